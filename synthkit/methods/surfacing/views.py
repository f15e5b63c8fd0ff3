"""Named orthographic views of ``V (#V, 3)``, ``F (#F, 3)`` with a face-ID buffer, and painted strokes.

The paper projects mouse strokes through an object-ID buffer. Here a user paints over a render of
a named view in any image editor; :func:`image_strokes` reads the painted pixels back through the
face-ID buffer of the same camera. Views: ``front`` looks along -Z with +Y up, ``back`` along +Z,
``right`` along -X (from +X), ``left`` along +X, ``top`` down -Y, ``bottom`` up +Y, ``iso`` is
turned 35 degrees about +Y and tilted 25 degrees down. The camera frames the mesh's bounding box
(6% margin) in a square image; the buffer is filled by a regular barycentric grid of samples per
triangle, nearest sample per pixel, as :func:`synthkit.preview.rasterize_mesh` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["VIEWS", "Camera", "camera", "face_id_buffer", "render", "paint_regions", "image_strokes"]

VIEWS = {"front": (0.0, 0.0), "back": (180.0, 0.0), "right": (90.0, 0.0), "left": (-90.0, 0.0),
         "top": (0.0, 90.0), "bottom": (0.0, -90.0), "iso": (35.0, 25.0)}
"""View name -> (azimuth about +Y, elevation) in degrees."""

_BASE = np.array([0.72, 0.76, 0.84])
_LIGHT = np.array([0.35, 0.55, 0.76])


@dataclass
class Camera:
    """Orthographic camera: world -> camera ``rotation (3, 3)``, then pixel
    ``x = (p_x - lo_x) * scale + offset_x``, ``y = size - 1 - ((p_y - lo_y) * scale + offset_y)``."""

    view: str
    size: int
    rotation: np.ndarray
    lo: np.ndarray
    scale: float
    offset: np.ndarray

    def to_pixels(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates ``(k, 2)`` (x, y) and depth ``(k,)`` (larger is nearer) of ``P (k, 3)``."""
        Q = np.asarray(P, np.float64) @ self.rotation.T
        xy = (Q[:, :2] - self.lo) * self.scale + self.offset
        return np.stack([xy[:, 0], self.size - 1 - xy[:, 1]], axis=1), Q[:, 2]

    def to_json(self) -> dict:
        return {"view": self.view, "size": self.size, "rotation": self.rotation.tolist(), "lo": self.lo.tolist(),
                "scale": self.scale, "offset": self.offset.tolist(),
                "convention": "x = (R p - lo)_x * scale + offset_x; y = size - 1 - ((R p - lo)_y * scale + offset_y)"}


def camera(V, view: str, size: int) -> Camera:
    """The camera of ``view`` framing ``V (#V, 3)`` in a ``size`` x ``size`` image."""
    if view not in VIEWS:
        raise ValueError(f"unknown view {view!r} (one of {', '.join(VIEWS)})")
    azim, elev = np.radians(VIEWS[view])
    ca, sa, ce, se = np.cos(azim), np.sin(azim), np.cos(-elev), np.sin(-elev)
    rot_y = np.array([[ca, 0.0, -sa], [0.0, 1.0, 0.0], [sa, 0.0, ca]])
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, ce, -se], [0.0, se, ce]])
    R = rot_x.T @ rot_y
    xy = (np.asarray(V, np.float64) @ R.T)[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    margin = 0.06 * size
    scale = (size - 2 * margin) / max(float((hi - lo).max()), 1e-12)
    return Camera(view, int(size), R, lo, float(scale), margin + 0.5 * ((size - 2 * margin) - (hi - lo) * scale))


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
    """Grey two-sided Lambert render ``(size, size, 3) float32`` of the faces in ``face_at``."""
    V = np.asarray(V, np.float64) @ cam.rotation.T
    F = np.asarray(F, np.int64)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    shade = 0.35 + 0.65 * np.abs(n @ _LIGHT)
    img = np.ones((cam.size, cam.size, 3), np.float32)
    seen = face_at >= 0
    img[seen] = (_BASE[None, :] * shade[face_at[seen], None]).astype(np.float32)
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
        dc = c[None, :] - base
        alpha = np.clip((delta * dc).sum(axis=1) / np.maximum((dc * dc).sum(axis=1), 1e-12), 0.0, 1.0)
        resid = np.abs(delta - alpha[:, None] * dc).max(axis=1)
        take = (alpha >= opacity) & (resid <= tolerance) & (resid < best)
        best[take], region[take] = resid[take], r
    out[painted] = region
    return out


def image_strokes(img, rendered, face_at, V, F, cam: Camera, colors, *, tolerance: float,
                  opacity: float = 0.25) -> tuple[list[np.ndarray], dict]:
    """Stroked vertices per region from a painted image, and counts of its painted pixels.

    ``img (H, W, 3)`` and ``rendered (H, W, 3)`` in [0, 1], ``face_at (H, W)`` of the same camera,
    ``colors (L, 3)`` in [0, 1] (NaN rows for regions without a colour here); pixels are read by
    :func:`paint_regions`. A stroke pixel over a face strokes the face's corner nearest to the pixel
    centre (of corners on one line of sight, the nearer); over the background it is ignored. The
    counts: ``read`` (stroke pixels over the model), ``ignored`` (painted pixels near no stroke
    colour) and ``ignored_rgb`` (the commonest such colour, 0-255, or None)."""
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
    counts = {"read": int(len(region)), "ignored": int(len(odd)), "ignored_rgb": common}
    return [np.unique(nearest[region == r]) for r in range(len(colors))], counts
