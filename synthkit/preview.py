"""PNG previews of what a run made: meshes, scalar fields, images, curves.

Meshes are drawn by a small software rasterizer (orthographic view, z-buffer, two-sided Lambert
shading), so previews need no display and no OpenGL. A mesh with an :class:`Appearance` is drawn
as it will look in a DCC: each pixel's texture coordinates are interpolated in its face
(barycentric in screen space: exact for an orthographic view) and its material's texture is
sampled there (nearest texel, repeating outside [0, 1]), times the material's colour and any
vertex colours. Views: ``front`` looks along -Z with +Y up,
``top`` looks down -Y with -Z up, ``side`` looks along -X with +Y up, ``iso`` is turned 35 degrees
about +Y and tilted 25 degrees down.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from synthkit.io.images import save_image

VIEWS = {"front": (0.0, 0.0), "back": (180.0, 0.0), "right": (90.0, 0.0), "side": (90.0, 0.0),
         "left": (-90.0, 0.0), "top": (0.0, 90.0), "bottom": (0.0, -90.0), "iso": (35.0, 25.0)}
"""View name -> (azimuth about +Y, elevation) in degrees, of every render: previews and the views
strokes are painted on (``side`` is ``right``)."""

FRAME_MARGIN = 0.06
"""Share of the image size left free on each side of a framed view."""


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


def camera(points, view: str, size: int) -> Camera:
    """The camera of ``view`` framing ``points (k, 3)`` (their bounding box, :data:`FRAME_MARGIN`
    free on each side, centred) in a ``size`` x ``size`` image."""
    R = view_rotation(view)
    xy = (np.asarray(points, np.float64).reshape(-1, 3) @ R.T)[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    margin = FRAME_MARGIN * size
    scale = (size - 2 * margin) / max(float((hi - lo).max()), 1e-12)
    return Camera(view, int(size), R, lo, float(scale), margin + 0.5 * ((size - 2 * margin) - (hi - lo) * scale))
_BASE_COLOR = np.array([0.72, 0.76, 0.84])

SET1 = np.array(
    [[228, 26, 28], [55, 126, 184], [77, 175, 74], [152, 78, 163], [255, 127, 0], [255, 255, 51],
     [166, 86, 40], [247, 129, 191], [153, 153, 153], [102, 194, 165]], dtype=np.uint8
)
"""``(10, 3) uint8`` the qualitative palette of region colours (ColorBrewer Set1, then Set2's first)."""


def golden_hues(n: int, *, start: float = 0.0, saturation: float = 0.55, value: float = 0.92) -> np.ndarray:
    """``(n, 3)`` float64 RGB in [0, 1] of ``n`` distinct colours: hues ``start + i * 0.618...``
    (golden-ratio steps, so any prefix is spread out) at one saturation and value."""
    h = (start + np.arange(n) * 0.618033988749895) % 1.0
    sector = np.floor(h * 6).astype(int) % 6
    f = h * 6 - np.floor(h * 6)
    v = np.full(n, float(value))
    p, q, t = v * (1 - saturation), v * (1 - f * saturation), v * (1 - (1 - f) * saturation)
    table = np.stack([np.stack(rgb, 1) for rgb in
                      ((v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q))])
    return table[sector, np.arange(n)]


@dataclass
class Appearance:
    """How a mesh's faces look (all arrays over its ``#F`` faces).

    Attributes
    ----------
    corner_uv : (#F, 3, 2) texture coordinates per face corner, or None
    face_image : (#F,) int64 index into ``images`` (-1: untextured)
    images : base-colour textures, each (H, W, 3) float in [0, 1] or uint8 (row 0 = top, v = 1)
    face_tint : (#F, 3) material colour in [0, 1]
    corner_color : (#F, 3, 3) vertex colours in [0, 1] per corner, or None
    """

    corner_uv: np.ndarray | None
    face_image: np.ndarray
    images: list
    face_tint: np.ndarray
    corner_color: np.ndarray | None = None

    @classmethod
    def of(cls, asset, corner_uv=None, face_material=None, corner_color=None, *, like_input: bool = False):
        """The appearance of faces that use ``asset``'s materials (an :class:`~synthkit.asset.Asset`):
        with ``like_input`` the asset's own faces, else faces given by ``corner_uv (#F, 3, 2)``,
        ``face_material (#F,)`` and ``corner_color (#F, 3, 4) uint8``."""
        if like_input:
            corner_uv, face_material, corner_color = asset.corner_uv, asset.face_material, asset.corner_color
        n = len(face_material) if face_material is not None else (len(corner_uv) if corner_uv is not None else 0)
        fm = np.zeros(n, np.int64) if face_material is None else np.asarray(face_material, np.int64)
        mats = asset.materials
        images = [None if m.image is None else m.image[..., :3] for m in mats]  # uint8: texels converted as sampled
        tints = np.array([m.color[:3] for m in mats] + [[1.0, 1.0, 1.0]], np.float64)
        face_image = np.where(fm >= 0, fm, -1)
        if corner_uv is None:
            face_image = np.full(n, -1, np.int64)
        else:
            has = np.array([img is not None for img in images] + [False])
            face_image = np.where(has[np.where(fm >= 0, fm, len(mats))], face_image, -1)
        colors = None if corner_color is None else np.asarray(corner_color, np.float64)[..., :3] / 255.0
        return cls(corner_uv=corner_uv, face_image=face_image, images=images,
                   face_tint=tints[np.where(fm >= 0, fm, len(mats))], corner_color=colors)


def view_rotation(view: str) -> np.ndarray:
    """(3, 3) rotation taking world coordinates to camera coordinates (x right, y up, z to viewer)."""
    if view not in VIEWS:
        raise ValueError(f"unknown view {view!r} (one of {', '.join(VIEWS)})")
    azim, elev = np.radians(VIEWS[view])
    elev = -elev
    ca, sa, ce, se = np.cos(azim), np.sin(azim), np.cos(elev), np.sin(elev)
    rot_y = np.array([[ca, 0.0, -sa], [0.0, 1.0, 0.0], [sa, 0.0, ca]])
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, ce, -se], [0.0, se, ce]])
    return rot_x.T @ rot_y


def rasterize_mesh(
    V: np.ndarray,
    F: np.ndarray,
    *,
    face_colors: np.ndarray | None = None,
    view: str = "iso",
    size: int = 512,
    lines: np.ndarray | None = None,
    appearance: Appearance | None = None,
    frame: np.ndarray | None = None,
) -> np.ndarray:
    """Render ``V (#V, 3)``, ``F (#F, 3)`` to an ``(size, size, 3) float32`` image in [0, 1].

    ``face_colors (#F, 3)`` in [0, 1] tint faces; ``appearance`` draws them textured (module
    docstring) instead; ``lines (k, 2, 3)`` are segments drawn on top in red. ``frame (k, 3)``:
    world points the view is framed to instead of the mesh (so that several renders share one
    scale). Each pixel shows the nearest face that holds its centre (:func:`_rasterize`).
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    img = np.ones((size, size, 3), dtype=np.float32)
    if len(F) == 0:
        return img
    framed = V if frame is None else np.asarray(frame, np.float64).reshape(-1, 3)
    if lines is not None and len(lines):
        framed = np.vstack([framed, np.asarray(lines, np.float64).reshape(-1, 3)])
    cam = camera(framed, view, size)
    R = cam.rotation
    P = V @ R.T
    pix = cam.to_pixels(V)[0]
    depth = np.full(size * size, -np.inf)
    face_at = np.full(size * size, -1, dtype=np.int64)
    _rasterize(pix[F], P[F, 2], size, depth, face_at)
    covered = face_at >= 0
    img.reshape(-1, 3)[covered] = shaded_colors(P, F, None if appearance is not None else face_colors,
                                                 face_at[covered])
    if appearance is not None:
        pixels = np.flatnonzero(covered)
        img.reshape(-1, 3)[pixels] *= _surface_colors(appearance, pix[F], pixels, face_at[pixels], size, face_colors)
    if lines is not None and len(lines):
        seg_pix = cam.to_pixels(np.asarray(lines, dtype=np.float64).reshape(-1, 3))[0].reshape(-1, 2, 2)
        canvas = np.ascontiguousarray(img)
        ends = np.round(seg_pix).astype(np.int32).reshape(-1, 2, 1, 2)
        cv2.polylines(canvas, list(ends), False, (0.85, 0.1, 0.1), 2, cv2.LINE_AA)
        img = canvas
    return img


_INSIDE_TOL = 1e-9
"""Barycentric tolerance of the inside test: a pixel centre on a shared edge belongs to both faces."""

_PAIRS_PER_CHUNK = 1 << 21
"""Bounding-box pixels of the faces rasterized at once by :func:`_rasterize` (bounds its memory)."""

_LIGHT = np.array([0.35, 0.55, 0.76])
_NO_FACE = np.iinfo(np.int64).max


def shaded_colors(P: np.ndarray, F: np.ndarray, face_colors, faces: np.ndarray) -> np.ndarray:
    """Two-sided Lambert colours ``(k, 3)`` of the faces ``faces (k,)`` of ``P (#V, 3)`` (camera
    coordinates), ``F (#F, 3)``; only the faces that cover a pixel are shaded."""
    used = np.zeros(len(F), bool)
    used[faces] = True
    uniq = np.flatnonzero(used)
    inv = np.cumsum(used)[faces] - 1
    tri = P[F[uniq]]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, norm, out=np.zeros_like(normals), where=norm > 0)
    shade = 0.35 + 0.65 * np.abs(normals @ _LIGHT)
    colors = _BASE_COLOR if face_colors is None else np.asarray(face_colors, np.float64)
    base = np.broadcast_to(colors, (len(F), 3))[uniq]
    return (base * shade[:, None])[inv]


def _surface_colors(app: Appearance, tri_pix: np.ndarray, pixels: np.ndarray, faces: np.ndarray,
                    size: int, face_colors=None) -> np.ndarray:
    """``(k, 3)`` unshaded colours (over :data:`_BASE_COLOR`, which the shading applied) of the
    pixels ``pixels (k,)`` showing faces ``faces (k,)``; ``tri_pix (#F, 3, 2)`` are the faces'
    pixel coordinates. Untextured faces take ``face_colors (#F, 3)`` when given, else their tint."""
    T = tri_pix[faces]
    px = np.stack([pixels % size, pixels // size], axis=1).astype(np.float64)
    e1, e2, d = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0], px - T[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        w1 = np.where(det != 0, (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det, 1 / 3)
        w2 = np.where(det != 0, (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det, 1 / 3)
    W = np.clip(np.stack([1 - w1 - w2, w1, w2], axis=1), 0, 1)
    W /= np.maximum(W.sum(axis=1, keepdims=True), 1e-12)
    color = app.face_tint[faces].astype(np.float64)
    if face_colors is not None:
        plain = app.face_image[faces] < 0
        color[plain] = np.broadcast_to(np.asarray(face_colors, np.float64), (len(app.face_image), 3))[faces[plain]]
    if app.corner_color is not None:
        color = color * np.einsum("kc,kcj->kj", W, app.corner_color[faces])
    if app.corner_uv is not None:
        corner_uv = app.corner_uv[faces]
        corner_uv[np.isnan(corner_uv)] = 0.0  # a copy: faces without UVs sample texel (0, 0)
        uv = np.einsum("kc,kcj->kj", W, corner_uv)
        for index in np.unique(app.face_image[faces]):
            if index < 0:
                continue
            at = np.flatnonzero(app.face_image[faces] == index)
            image = app.images[index]
            h, w = image.shape[:2]
            u, v = (np.where((c >= 0) & (c <= 1), c, np.mod(c, 1.0)) for c in (uv[at, 0], uv[at, 1]))
            col = np.minimum(np.floor(u * w), w - 1).astype(np.int64)
            row = np.minimum(np.floor((1.0 - v) * h), h - 1).astype(np.int64)
            texels = image[row, col]
            color[at] *= texels / 255.0 if texels.dtype == np.uint8 else texels
    return (color / _BASE_COLOR).astype(np.float32)


def _rasterize(pix, z, size, depth, face_at) -> None:
    """Z-buffer the triangles ``pix (f, 3, 2)`` (pixel coordinates, pixel centres at integers) with
    vertex depths ``z (f, 3)`` into ``depth (size*size,)`` / ``face_at`` (face index), nearer = larger z.

    A pixel takes the nearest face whose triangle holds its centre; among equal depths the first
    face, and a face replaces what the buffers already hold only when strictly nearer. A face that
    holds no pixel centre (smaller than a pixel, or degenerate) still marks the pixel of its
    centroid, so thin parts stay visible. Faces with a non-finite coordinate are skipped.

    Vectorised (:func:`_centre_candidates`): faces go in chunks whose bounding boxes hold at most
    :data:`_PAIRS_PER_CHUNK` pixels, and the nearest per pixel is taken by ``np.maximum.at``. Numpy
    only: a process that draws previews pays no compiler start-up (numba's costs 0.3-0.4 s).
    """
    pix = np.asarray(pix, np.float64)
    z = np.asarray(z, np.float64)
    cols = [np.ascontiguousarray(c) for c in (pix[:, 0, 0], pix[:, 1, 0], pix[:, 2, 0],
                                                pix[:, 0, 1], pix[:, 1, 1], pix[:, 2, 1],
                                                z[:, 0], z[:, 1], z[:, 2])]
    x0, x1, x2, y0, y1, y2, z0, z1, z2 = cols
    with np.errstate(invalid="ignore", over="ignore"):
        valid = np.isfinite(x0 + x1 + x2 + y0 + y1 + y2 + z0 + z1 + z2)
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        lo_x, lo_y = (np.clip(np.ceil(np.minimum(np.minimum(a, b), c)), 0, size) for a, b, c in
                      ((x0, x1, x2), (y0, y1, y2)))
        hi_x, hi_y = (np.clip(np.floor(np.maximum(np.maximum(a, b), c)), -1, size - 1) for a, b, c in
                      ((x0, x1, x2), (y0, y1, y2)))
    span_x = np.where(valid, np.maximum(hi_x - lo_x + 1, 0), 0).astype(np.int64)
    span_y = np.where(valid, np.maximum(hi_y - lo_y + 1, 0), 0).astype(np.int64)
    count = np.where(area != 0, span_x * span_y, 0)
    box = (lo_x.astype(np.int64), lo_y.astype(np.int64), span_x, span_y)
    best_d = np.full(size * size, -np.inf)
    best_f = np.full(size * size, _NO_FACE)
    hit = np.zeros(len(pix), bool)
    ends = np.cumsum(count)
    start = 0
    while start < len(pix):
        stop = max(int(np.searchsorted(ends, ends[start] - count[start] + _PAIRS_PER_CHUNK, "right")), start + 1)
        k, d, f = _centre_candidates(cols, area, box, count, start, stop, size)
        hit[f] = True
        _keep_nearest(best_d, best_f, k, d, f)
        start = stop
    miss = np.flatnonzero(valid & ~hit)
    cx = np.clip(np.round((x0[miss] + x1[miss] + x2[miss]) / 3.0), 0, size - 1).astype(np.int64)
    cy = np.clip(np.round((y0[miss] + y1[miss] + y2[miss]) / 3.0), 0, size - 1).astype(np.int64)
    _keep_nearest(best_d, best_f, cy * size + cx, (z0[miss] + z1[miss] + z2[miss]) / 3.0, miss)
    nearer = best_d > depth
    depth[nearer] = best_d[nearer]
    face_at[nearer] = best_f[nearer]


def _centre_candidates(cols, area, box, count, start, stop, size):
    """Pixel centres inside faces ``start..stop-1`` (``cols``: the nine ``(f,)`` columns x0..x2,
    y0..y2, z0..z2; ``box``: bounding-box corner and size): pixel index ``k``, depth ``d`` and face
    ``f``, each ``(m,)``.

    Row by row: on a row ``py`` each barycentric weight is affine in ``px``, ``w_i = a_i px + b_i``,
    so the centres with every ``w_i >= -tol`` form one span, found from the three bounds; the depth
    is affine along the span too. The work is one step per (face, row) and one per covered pixel.
    """
    x0, x1, x2, y0, y1, y2, z0, z1, z2 = cols
    lo_x, lo_y, span_x, span_y = box
    rows = np.where(count[start:stop] > 0, span_y[start:stop], 0)
    f = np.repeat(np.arange(start, stop), rows)
    if not len(f):
        return f, np.zeros(0), f
    py = (lo_y[f] + np.arange(len(f)) - np.repeat(np.cumsum(rows) - rows, rows)).astype(np.float64)
    inv = 1.0 / area[f]
    a0, a1 = (y1[f] - y2[f]) * inv, (y2[f] - y0[f]) * inv
    b0 = (x1[f] * (y2[f] - py) - x2[f] * (y1[f] - py)) * inv
    b1 = (x2[f] * (y0[f] - py) - x0[f] * (y2[f] - py)) * inv
    first = lo_x[f].astype(np.float64)
    last = first + span_x[f] - 1
    for a, b in ((a0, b0), (a1, b1), (-(a0 + a1), 1.0 - b0 - b1)):
        with np.errstate(divide="ignore", invalid="ignore"):
            edge = (-_INSIDE_TOL - b) / a
        first = np.where(a > 0, np.maximum(first, np.ceil(edge)), first)
        last = np.where(a < 0, np.minimum(last, np.floor(edge)), last)
        last = np.where((a == 0) & (b < -_INSIDE_TOL), first - 1, last)
    n_px = np.maximum(last - first + 1, 0).astype(np.int64)
    slope = a0 * z0[f] + a1 * z1[f] - (a0 + a1) * z2[f]
    offset = b0 * z0[f] + b1 * z1[f] + (1.0 - b0 - b1) * z2[f]
    runs = np.flatnonzero(n_px)
    f, n_px = f[runs], n_px[runs]
    px = np.repeat(first[runs], n_px) + (np.arange(int(n_px.sum())) - np.repeat(np.cumsum(n_px) - n_px, n_px))
    d = np.repeat(slope[runs], n_px) * px + np.repeat(offset[runs], n_px)
    k = np.repeat(py[runs].astype(np.int64) * size, n_px) + px.astype(np.int64)
    return k, d, np.repeat(f, n_px)


def _keep_nearest(best_d, best_f, k, d, f) -> None:
    """Merge candidates ``k, d, f (m,)`` into the per-pixel ``best_d``, ``best_f`` in place: the
    larger depth wins, and among equal depths the smaller face index (earlier merges hold smaller
    faces, so a tie with what is held keeps it)."""
    if not len(k):
        return
    before = best_d[k]
    np.maximum.at(best_d, k, d)
    best_f[k[d > before]] = _NO_FACE  # a nearer face arrived: forget the one held
    at_top = d == best_d[k]
    np.minimum.at(best_f, k[at_top], f[at_top])


def _save(path: Path | str | None, img: np.ndarray) -> None:
    """Write ``img`` to ``path``; a ``None`` path (a preview the run does not keep) writes nothing."""
    if path is not None:
        save_image(path, img)


def render_mesh_png(path: Path | str | None, V: np.ndarray, F: np.ndarray, **kwargs) -> np.ndarray:
    """Render a mesh with :func:`rasterize_mesh` and write it as PNG (``path`` None: only render);
    returns the image."""
    img = rasterize_mesh(V, F, **kwargs)
    _save(path, img)
    return img


MeshLook = tuple
"""``(V (#V, 3), F (#F, 3), Appearance or None)``: a mesh as :func:`before_after_png` draws it."""


def before_after_png(
    path: Path | str | None, before: MeshLook, after: MeshLook, *, views: Sequence[str] = ("front", "iso", "top"),
    size: int = 256, titles: tuple[str, str] = ("input", "result"),
) -> np.ndarray:
    """Two rows of textured views (``views``), the input above the result, both framed to the
    bounding boxes of both (one scale, so a change of size shows); write a PNG (``path`` None: only
    render) and return it."""
    corners = np.vstack([np.asarray(m[0], np.float64) for m in (before, after)])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    box = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    rows = []
    for (V, F, app), title in zip((before, after), titles, strict=True):
        tiles = [rasterize_mesh(V, F, view=v, size=size, appearance=app, frame=box) for v in views]
        rows.append(montage_png(None, tiles, titles=[f"{title}: {v}" for v in views], height=size))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=1.0) for r in rows]
    out = np.concatenate([rows[0], np.ones((6, width, 3), np.float32), rows[1]], axis=0)
    _save(path, out)
    return out


def colorize(field: np.ndarray, *, vmin: float | None = None, vmax: float | None = None) -> np.ndarray:
    """``(H, W)`` scalar field -> ``(H, W, 3) float32`` viridis colours (non-finite values grey)."""
    field = np.asarray(field, dtype=np.float64)
    finite = np.isfinite(field)
    lo = float(np.min(field[finite])) if vmin is None and finite.any() else (vmin or 0.0)
    hi = float(np.max(field[finite])) if vmax is None and finite.any() else (vmax or 1.0)
    span = hi - lo if hi > lo else 1.0
    norm = np.where(finite, (field - lo) / span, 0.0)
    lut = np.round(np.clip(norm, 0, 1) * 255).astype(np.uint8)
    rgb = cv2.applyColorMap(lut, cv2.COLORMAP_VIRIDIS)[..., ::-1].astype(np.float32) / 255.0
    rgb[~finite] = 0.5
    return rgb


def heatmap_png(
    path: Path | str | None, field: np.ndarray, *, title: str | None = None, min_size: int = 256
) -> np.ndarray:
    """Write a 2-D scalar field as a viridis heatmap PNG (upscaled to ``min_size``); returns it."""
    rgb = colorize(field)
    h, w = rgb.shape[:2]
    factor = max(1, int(np.ceil(min_size / max(h, w))))
    if factor > 1:
        rgb = cv2.resize(rgb, (w * factor, h * factor), interpolation=cv2.INTER_NEAREST)
    if title:
        rgb = _with_title(rgb, title)
    _save(path, rgb)
    return rgb


def image_png(path: Path | str | None, img: np.ndarray) -> None:
    """Write an image (grey or colour, float in [0, 1]) as PNG."""
    _save(path, img)


def _as_rgb(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img, dtype=np.float32)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    return img[..., :3]


def _with_title(img: np.ndarray, title: str) -> np.ndarray:
    band = np.full((24, img.shape[1], 3), 255, dtype=np.uint8)
    cv2.putText(band, title, (4, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([band.astype(np.float32) / 255.0, img], axis=0)


def montage_png(
    path: Path | str | None, images: Sequence[np.ndarray], *, titles: Sequence[str] | None = None, height: int = 256
) -> np.ndarray:
    """Place images side by side at a common ``height`` (with optional titles) and write a PNG."""
    tiles = []
    for k, img in enumerate(images):
        rgb = _as_rgb(img)
        h, w = rgb.shape[:2]
        if h != height:
            new_w = max(1, int(round(w * height / h)))
            rgb = cv2.resize(rgb, (new_w, height), interpolation=cv2.INTER_AREA if h > height else cv2.INTER_NEAREST)
        if titles is not None:
            rgb = _with_title(rgb, titles[k])
        tiles.append(rgb)
        tiles.append(np.ones((tiles[-1].shape[0], 6, 3), dtype=np.float32))
    out = np.concatenate(tiles[:-1], axis=1)
    _save(path, out)
    return out


def plot_curve_png(
    path: Path | str | None,
    xs: np.ndarray,
    ys: np.ndarray,
    *,
    xlabel: str = "",
    ylabel: str = "",
    title: str = "",
    size: tuple[int, int] = (480, 360),
) -> np.ndarray:
    """Draw the polyline (xs, ys) with axes, tick labels and titles; write a PNG; returns it."""
    xs = np.asarray(xs, dtype=np.float64)
    ys = np.asarray(ys, dtype=np.float64)
    w, h = size
    img = np.full((h, w, 3), 255, dtype=np.uint8)
    left, right, top, bottom = 56, 16, 44, 44
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = float(min(ys.min(), 0.0)), float(ys.max())
    x1 = x1 if x1 > x0 else x0 + 1.0
    y1 = y1 if y1 > y0 else y0 + 1.0

    def px(x, y):
        u = left + (np.asarray(x) - x0) / (x1 - x0) * (w - left - right)
        v = h - bottom - (np.asarray(y) - y0) / (y1 - y0) * (h - top - bottom)
        return u, v

    black = (0, 0, 0)
    cv2.line(img, (left, h - bottom), (w - right, h - bottom), black, 1)
    cv2.line(img, (left, top), (left, h - bottom), black, 1)
    for t in np.linspace(0, 1, 5):
        xv, yv = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
        u, _ = px(xv, y0)
        _, v = px(x0, yv)
        cv2.putText(img, f"{xv:.3g}", (int(u) - 12, h - bottom + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.35, black, 1)
        cv2.putText(img, f"{yv:.3g}", (4, int(v) + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, black, 1)
    u, v = px(xs, ys)
    pts = np.round(np.stack([u, v], axis=1)).astype(np.int32).reshape(-1, 1, 2)
    cv2.polylines(img, [pts], False, (25, 80, 200), 2, cv2.LINE_AA)
    cv2.putText(img, title, (left, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, black, 1, cv2.LINE_AA)
    cv2.putText(img, xlabel, (w // 2 - 40, h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.4, black, 1, cv2.LINE_AA)
    cv2.putText(img, ylabel, (4, top - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.4, black, 1, cv2.LINE_AA)
    _save(path, img)
    return img.astype(np.float32) / 255.0
