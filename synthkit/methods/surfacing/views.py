"""Named orthographic views of ``V (#V, 3)``, ``F (#F, 3)`` with a face-ID buffer, and painted strokes.

The paper projects mouse strokes through an object-ID buffer. Here a user paints over a render of
a named view in any image editor; :func:`image_strokes` reads the painted pixels back through the
face-ID buffer of the same camera. Views: ``front`` looks along -Z with +Y up, ``back`` along +Z,
``right`` along -X (from +X), ``left`` along +X, ``top`` down -Y, ``bottom`` up +Y, ``iso`` is
turned 35 degrees about +Y and tilted 25 degrees down. The camera and the shading are the
previews' (:func:`synthkit.preview.camera`: the mesh's bounding box, 6% margin, in a square
image; :func:`synthkit.preview.shaded_colors`). The face-ID buffer is filled by a regular
barycentric grid of samples per triangle, nearest sample per pixel, and stays so rather than
using the previews' exact pixel-centre rasterizer: painted PNGs made by earlier versions are read
against the render they were painted on, and on the bundled figure the two rasterizers show
another face at 8,534 of 59,127 front-view pixels (face borders).
"""

from __future__ import annotations

import numpy as np

from synthkit.preview import VIEWS, Camera, camera, shaded_colors

__all__ = ["VIEWS", "Camera", "camera", "face_id_buffer", "render", "paint_regions", "image_strokes",
           "unnamed_colors", "STROKE_COLOR_TOLERANCE"]

STROKE_COLOR_TOLERANCE = 0.3
"""Largest channel residual (0-1) a painted pixel may have from every stroke colour blended over the
render, and from the render's own range around it, and still be paint of a stroke colour. Measured
2026-12-03 on the bundled painted PNG (data-samples/surfacing-figure-front.png): its stroke pixels
reach 0.001 blurred (Gaussian, sigma 1.2), 0.287 as a JPEG of quality 75, 0.291 at quality 50, 0.199
blurred then quality 50; pure cyan over that figure's render reaches 0.466. A pixel farther is a
colour that names no region (:func:`unnamed_colors`)."""

UNNAMED_COLORS_SHOWN = 5
"""Most colours that name no region :func:`unnamed_colors` tells apart (the rest only counted)."""


def face_id_buffer(V, F, cam: Camera) -> np.ndarray:
    """``(size, size) int64``: the nearest face at each pixel, -1 where no face is seen."""
    F = np.asarray(F, np.int64)
    pix, depth = cam.to_pixels(V)
    tri, z = pix[F], depth[F]
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    n_sub = np.clip(np.ceil(edge * 1.5).astype(np.int64), 1, None)
    size = cam.size
    best = np.full(size * size, -np.inf)
    face_at = np.full(size * size, -1, np.int64)
    for n in np.unique(n_sub):
        faces = np.flatnonzero(n_sub == n)
        i, j = np.nonzero(np.add.outer(np.arange(n + 1), np.arange(n + 1)) <= n)
        bary = np.stack([i, j, n - i - j], axis=1) / n
        for chunk in np.array_split(faces, max(1, len(faces) * len(bary) // 2_000_000 + 1)):
            pts = np.einsum("sk,fkd->fsd", bary, tri[chunk])
            zs = np.einsum("sk,fk->fs", bary, z[chunk]).ravel()
            px = np.clip(np.round(pts[..., 0]).astype(np.int64), 0, size - 1)
            py = np.clip(np.round(pts[..., 1]).astype(np.int64), 0, size - 1)
            flat = (py * size + px).ravel()
            fid = np.repeat(chunk, len(bary))
            order = np.lexsort((-zs, flat))
            flat, zs, fid = flat[order], zs[order], fid[order]
            first = np.r_[True, flat[1:] != flat[:-1]]
            flat, zs, fid = flat[first], zs[first], fid[first]
            closer = zs > best[flat]
            best[flat[closer]] = zs[closer]
            face_at[flat[closer]] = fid[closer]
    return face_at.reshape(size, size)


def render(V, F, face_at: np.ndarray, cam: Camera) -> np.ndarray:
    """Grey two-sided Lambert render ``(size, size, 3) float32`` of the faces in ``face_at``, shaded
    as every preview is (:func:`synthkit.preview.shaded_colors`)."""
    img = np.ones((cam.size, cam.size, 3), np.float32)
    seen = face_at >= 0
    img[seen] = shaded_colors(np.asarray(V, np.float64) @ cam.rotation.T, np.asarray(F, np.int64), None,
                              face_at[seen])
    return img


def paint_regions(img, rendered, colors, *, tolerance: float, opacity: float) -> np.ndarray:
    """Region ``(H, W) int64`` of each pixel of a painted ``img (H, W, 3)`` over ``rendered (H, W, 3)``
    (both in [0, 1]): -1 unpainted, -2 painted but near no stroke colour, else the index into
    ``colors (L, 3)`` (NaN rows: regions without a colour here).

    A pixel is painted when it differs from the render by more than ``tolerance`` in some channel.
    Paint programs blend: an antialiased edge, a soft brush or semi-transparent paint leaves
    ``render + alpha (colour - render)``, and JPEG adds noise. So each painted pixel is explained by
    every stroke colour in turn: alpha is its least-squares opacity along the line from the render
    to the colour (clipped to [0, 1]) and the residual the largest channel difference left; the pixel
    takes the colour with the smallest residual among those with ``alpha >= opacity`` and residual
    within ``tolerance`` (a hard brush: alpha 1, the nearest colour within the tolerance). Pixels
    that no colour explains (the blend of two paints, a faint brush edge, a colour not listed) are
    -2, for the caller to count."""
    img, rendered = np.asarray(img, np.float64), np.asarray(rendered, np.float64)
    out = np.full(img.shape[:2], -1, np.int64)
    painted = np.abs(img - rendered).max(axis=2) > tolerance
    delta = (img - rendered)[painted]
    base = rendered[painted]
    best = np.full(len(delta), np.inf)
    region = np.full(len(delta), -2, np.int64)
    for r, c in enumerate(np.asarray(colors, np.float64)):
        if np.isnan(c).any():
            continue
        alpha, resid = _blend(delta, base, c)
        take = (alpha >= opacity) & (resid <= tolerance) & (resid < best)
        best[take], region[take] = resid[take], r
    out[painted] = region
    return out


def _blend(delta: np.ndarray, base: np.ndarray, color: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares opacity ``(n,)`` in [0, 1] of paint ``color (3,)`` explaining each pixel's
    difference ``delta (n, 3)`` from its render ``base (n, 3)``, and the largest channel residual."""
    dc = color[None, :] - base
    alpha = np.clip((delta * dc).sum(axis=1) / np.maximum((dc * dc).sum(axis=1), 1e-12), 0.0, 1.0)
    return alpha, np.abs(delta - alpha[:, None] * dc).max(axis=1)


def unnamed_colors(img, rendered, colors, *, tolerance: float) -> list[tuple[list[int], int]]:
    """``(rgb 0-255, pixels)`` of each colour painted on ``img`` that names no region, most pixels
    first (at most :data:`UNNAMED_COLORS_SHOWN`): painted pixels (differing from ``rendered`` by more
    than ``tolerance``) farther than :data:`STROKE_COLOR_TOLERANCE` from every row of ``colors``
    blended over the render at any opacity, and from the render's range in the 5x5 pixels around
    them (blur and JPEG ringing at the model's outline). Each colour is the commonest of those
    pixels left, with the pixels it explains blended over the render (its soft edges)."""
    from scipy.ndimage import maximum_filter, minimum_filter

    img, rendered = np.asarray(img, np.float64), np.asarray(rendered, np.float64)
    outside = np.maximum(minimum_filter(rendered, size=(5, 5, 1)) - img,
                         img - maximum_filter(rendered, size=(5, 5, 1))).max(axis=2)
    far = (np.abs(img - rendered).max(axis=2) > tolerance) & (outside > STROKE_COLOR_TOLERANCE)
    delta, base = (img - rendered)[far], rendered[far]
    for c in np.asarray(colors, np.float64):
        if len(delta) and not np.isnan(c).any():
            keep = _blend(delta, base, c)[1] > STROKE_COLOR_TOLERANCE
            delta, base = delta[keep], base[keep]
    found = []
    while len(delta) and len(found) < UNNAMED_COLORS_SHOWN:
        rgb, counts = np.unique(np.round((base + delta) * 255).astype(np.int64), axis=0, return_counts=True)
        color = rgb[np.argmax(counts)]
        member = _blend(delta, base, color / 255.0)[1] <= STROKE_COLOR_TOLERANCE
        found.append((color.tolist(), int(member.sum())))
        delta, base = delta[~member], base[~member]
    return found


def image_strokes(img, rendered, face_at, V, F, cam: Camera, colors, *, tolerance: float,
                  opacity: float = 0.25) -> tuple[list[np.ndarray], dict]:
    """Stroked vertices per region from a painted image, and counts of its painted pixels.

    ``img (H, W, 3)`` and ``rendered (H, W, 3)`` in [0, 1], ``face_at (H, W)`` of the same camera,
    ``colors (L, 3)`` in [0, 1] (NaN rows for regions without a colour here); pixels are read by
    :func:`paint_regions`. A stroke pixel over a face strokes the face's corner nearest to the pixel
    centre (of corners on one line of sight, the nearer); over the background it is ignored. The
    counts: ``read`` (stroke pixels over the model), ``ignored`` (painted pixels near no stroke
    colour), ``ignored_rgb`` (the commonest such colour, 0-255, or None) and ``unnamed`` (the
    colours that name no region, :func:`unnamed_colors`, as ``{"rgb", "hex", "pixels"}``)."""
    img = np.asarray(img, np.float64)
    if img.shape[:2] != face_at.shape:
        raise ValueError(f"image is {img.shape[1]}x{img.shape[0]} pixels, the view renders "
                         f"{face_at.shape[1]}x{face_at.shape[0]}")
    colors = np.asarray(colors, np.float64)
    pixel_region = paint_regions(img, rendered, colors, tolerance=tolerance, opacity=opacity)
    ys, xs = np.nonzero((pixel_region >= 0) & (face_at >= 0))
    region = pixel_region[ys, xs]
    corners = np.asarray(F, np.int64)[face_at[ys, xs]]
    pix, depth = cam.to_pixels(V)
    centre = np.stack([xs, ys], axis=1).astype(np.float64)
    dist = np.linalg.norm(pix[corners] - centre[:, None, :], axis=2)
    span = max(float(np.ptp(depth)), 1e-12)
    dist += 1e-6 * (depth.max() - depth[corners]) / span  # corners in line of sight: the nearer one
    nearest = corners[np.arange(len(corners)), np.argmin(dist, axis=1)]
    odd = np.round(img[pixel_region == -2] * 255).astype(np.int64)
    common = None
    if len(odd):
        rgb, counts = np.unique(odd, axis=0, return_counts=True)
        common = rgb[np.argmax(counts)].tolist()
    unnamed = [{"rgb": rgb, "hex": "#{:02x}{:02x}{:02x}".format(*rgb), "pixels": n}
               for rgb, n in unnamed_colors(img, rendered, colors, tolerance=tolerance)]
    counts = {"read": int(len(region)), "ignored": int(len(odd)), "ignored_rgb": common, "unnamed": unnamed}
    return [np.unique(nearest[region == r]) for r in range(len(colors))], counts
