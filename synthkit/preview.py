"""PNG previews of what a run made: meshes, scalar fields, images, curves.

Meshes are drawn by a small software rasterizer (orthographic view, z-buffer, two-sided Lambert
shading), so previews need no display and no OpenGL. Views: ``front`` looks along -Z with +Y up,
``top`` looks down -Y with -Z up, ``side`` looks along -X with +Y up, ``iso`` is turned 35 degrees
about +Y and tilted 25 degrees down.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from synthkit.io.images import save_image

_VIEWS = {
    "front": (0.0, 0.0),
    "top": (0.0, 90.0),
    "side": (90.0, 0.0),
    "iso": (35.0, 25.0),
}
_BASE_COLOR = np.array([0.72, 0.76, 0.84])


def view_rotation(view: str) -> np.ndarray:
    """(3, 3) rotation taking world coordinates to camera coordinates (x right, y up, z to viewer)."""
    if view not in _VIEWS:
        raise ValueError(f"unknown view {view!r} (one of {', '.join(_VIEWS)})")
    azim, elev = np.radians(_VIEWS[view])
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
    max_samples: int | None = None,
) -> np.ndarray:
    """Render ``V (#V, 3)``, ``F (#F, 3)`` to an ``(size, size, 3) float32`` image in [0, 1].

    ``face_colors (#F, 3)`` in [0, 1] tint faces; ``lines (k, 2, 3)`` are segments drawn on top in
    red. Triangles are covered by a regular barycentric grid of samples fine enough for their
    pixel size; the nearest sample wins per pixel. Samples are processed in chunks, so memory stays
    bounded; ``max_samples`` optionally caps their total for speed, at the price of holes in faces
    larger than the coarsened sampling.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    img = np.ones((size, size, 3), dtype=np.float32)
    if len(F) == 0:
        return img
    R = view_rotation(view)
    P = V @ R.T
    framed = P if lines is None or not len(lines) else np.vstack([P, np.asarray(lines).reshape(-1, 3) @ R.T])
    lo, hi = framed[:, :2].min(axis=0), framed[:, :2].max(axis=0)
    extent = max(float((hi - lo).max()), 1e-12)
    margin = 0.06 * size
    scale = (size - 2 * margin) / extent
    offset = margin + 0.5 * ((size - 2 * margin) - (hi - lo) * scale)

    def to_pixels(points: np.ndarray) -> np.ndarray:
        xy = (points[:, :2] - lo) * scale + offset
        return np.stack([xy[:, 0], size - 1 - xy[:, 1]], axis=1)

    tri = P[F]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, norm, out=np.zeros_like(normals), where=norm > 0)
    light = np.array([0.35, 0.55, 0.76])
    shade = 0.35 + 0.65 * np.abs(normals @ light)
    colors = _BASE_COLOR[None, :] if face_colors is None else np.asarray(face_colors, dtype=np.float64)
    colors = np.broadcast_to(colors, (len(F), 3)) * shade[:, None]

    pix = to_pixels(P)[F]
    edge = np.linalg.norm(pix - np.roll(pix, 1, axis=1), axis=2).max(axis=1)
    n_sub = np.clip(np.ceil(edge * 1.5).astype(np.int64), 1, None)
    cost = (n_sub + 1) * (n_sub + 2) // 2
    if max_samples is not None and cost.sum() > max_samples:
        n_sub = np.clip((n_sub * np.sqrt(max_samples / cost.sum())).astype(np.int64), 1, None)
    depth = np.full(size * size, -np.inf)
    face_at = np.full(size * size, -1, dtype=np.int64)
    for n in np.unique(n_sub):
        faces = np.nonzero(n_sub == n)[0]
        i, j = np.nonzero(np.add.outer(np.arange(n + 1), np.arange(n + 1)) <= n)
        bary = np.stack([i, j, n - i - j], axis=1) / n
        for chunk in np.array_split(faces, max(1, len(faces) * len(bary) // 2_000_000 + 1)):
            _splat(bary, pix[chunk], tri[chunk, :, 2], chunk, size, depth, face_at)
    covered = face_at >= 0
    img.reshape(-1, 3)[covered] = colors[face_at[covered]]
    if lines is not None and len(lines):
        segs = np.asarray(lines, dtype=np.float64).reshape(-1, 3) @ R.T
        seg_pix = to_pixels(segs).reshape(-1, 2, 2)
        canvas = np.ascontiguousarray(img)
        for a, b in np.round(seg_pix).astype(np.int64):
            cv2.line(canvas, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), (0.85, 0.1, 0.1), 2, cv2.LINE_AA)
        img = canvas
    return img


def _splat(bary: np.ndarray, pix: np.ndarray, z: np.ndarray, faces: np.ndarray, size: int,
           depth: np.ndarray, face_at: np.ndarray) -> None:
    """Splat the samples ``bary (S, 3)`` of triangles ``pix (f, 3, 2)`` (pixels) with depths
    ``z (f, 3)`` into the z-buffer ``depth (size*size,)`` / ``face_at`` (face index ``faces[i]``).

    Per pixel the deepest sample wins, the first one (face order, then sample order) among equal
    depths, and it replaces the buffer only when strictly nearer: the result of a stable sort by
    pixel and depth, without the sort (one ``maximum.at`` and one ``minimum.at`` over the samples).
    """
    pts = np.einsum("sk,fkd->fsd", bary, pix)  # einsum's sums: written out, they differ in the last bit
    zs = np.einsum("sk,fk->fs", bary, z).ravel()
    px = np.clip(np.round(pts[..., 0]).astype(np.int64), 0, size - 1)
    py = np.clip(np.round(pts[..., 1]).astype(np.int64), 0, size - 1)
    flat = (py * size + px).ravel()
    best = np.full(size * size, -np.inf)
    np.maximum.at(best, flat, zs)
    level = np.nonzero(zs == best[flat])[0]
    first = np.full(size * size, len(zs), dtype=np.int64)
    np.minimum.at(first, flat[level], level)
    pixels = np.nonzero(first < len(zs))[0]
    sample = first[pixels]
    closer = zs[sample] > depth[pixels]
    depth[pixels[closer]] = zs[sample[closer]]
    face_at[pixels[closer]] = faces[sample[closer] // len(bary)]


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
