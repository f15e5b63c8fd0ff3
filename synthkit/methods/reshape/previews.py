"""Previews of a reshape, as ``(H, W, 3)`` images.

- :func:`reshape_image` (Fig. 2): the mesh with its graph edges coloured by length change
  (:func:`edge_colours`: elongated blue, compressed red, unchanged dark grey) and handle nodes as
  green dots, ``(size, size, 3) float32`` in [0, 1], framed like :func:`synthkit.preview.rasterize_mesh`.
- Figs. 7-8 of the texture reshape: :func:`autosimilarity_image` (``T_x`` red, ``T_y`` green, each
  scaled so that ``4 tau`` is full intensity), :func:`grid_image` (grid edges over a texture) and
  :func:`segmentation_image` (rigid texels light, stochastic dark, each detail tile outlined in its
  own colour); :func:`source_window` is the part of a texture a surface uses.
"""

from __future__ import annotations

import cv2
import numpy as np

from synthkit.preview import rasterize_mesh, view_rotation

__all__ = ["edge_colours", "reshape_image", "autosimilarity_image", "grid_image", "segmentation_image",
           "source_window", "ELONGATED", "COMPRESSED", "HANDLE"]

ELONGATED = (0.1, 0.3, 0.95)
COMPRESSED = (0.9, 0.1, 0.1)
HANDLE = (0.1, 0.75, 0.2)
_UNCHANGED = (0.25, 0.25, 0.25)


def edge_colours(ratio, *, tol: float = 1e-3) -> np.ndarray:
    """RGB ``(E, 3)`` for length ratios ``ratio (E,)`` (new / rest): blue above ``1 + tol``, red below ``1 - tol``."""
    ratio = np.asarray(ratio, np.float64)
    out = np.tile(np.asarray(_UNCHANGED), (len(ratio), 1))
    out[ratio > 1 + tol] = ELONGATED
    out[ratio < 1 - tol] = COMPRESSED
    return out


def reshape_image(V, F, edge_points, colours, handle_points, *, view: str, size: int) -> np.ndarray:
    """Render ``V (#V, 3)``, ``F (#F, 3)`` and draw segments ``edge_points (E, 2, 3)`` in ``colours
    (E, 3)`` and dots at ``handle_points (k, 3)``."""
    img = np.ascontiguousarray(rasterize_mesh(V, F, view=view, size=size))
    R = view_rotation(view)
    P = np.asarray(V, np.float64) @ R.T
    lo, hi = P[:, :2].min(axis=0), P[:, :2].max(axis=0)
    extent = max(float((hi - lo).max()), 1e-12)
    margin = 0.06 * size
    scale = (size - 2 * margin) / extent
    offset = margin + 0.5 * ((size - 2 * margin) - (hi - lo) * scale)

    def px(points):
        xy = (np.asarray(points, np.float64).reshape(-1, 3) @ R.T)[:, :2]
        xy = (xy - lo) * scale + offset
        return np.round(np.stack([xy[:, 0], size - 1 - xy[:, 1]], axis=1)).astype(np.int64)

    seg = px(edge_points).reshape(-1, 2, 2)
    for (a, b), c in zip(seg, colours, strict=True):
        cv2.line(img, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), tuple(float(x) for x in c), 2, cv2.LINE_AA)
    for p in px(handle_points):
        cv2.circle(img, (int(p[0]), int(p[1])), max(3, size // 128), HANDLE, -1, cv2.LINE_AA)
    return img

def source_window(C, shape, toroidal: bool) -> tuple[slice, slice, np.ndarray]:
    """Rows, columns and offset ``(2,)`` of the texels a surface with corners ``C (c, 2)`` uses
    (the whole texture for a toroidal one)."""
    H, W = shape
    if toroidal:
        return slice(0, H), slice(0, W), np.zeros(2)
    lo = np.clip(np.floor(C.min(axis=0)), 0, [W - 1, H - 1]).astype(int)
    hi = np.clip(np.ceil(C.max(axis=0)), lo + 1, [W, H]).astype(int)
    return slice(lo[1], hi[1]), slice(lo[0], hi[0]), lo.astype(float)


def autosimilarity_image(T, tau: float) -> np.ndarray:
    """``(H, W, 3)``: ``T (2, H, W)`` x in red, y in green."""
    img = np.zeros(T.shape[1:] + (3,), np.float32)
    img[..., 0] = np.clip(T[0] / (4 * tau), 0, 1)
    img[..., 1] = np.clip(T[1] / (4 * tau), 0, 1)
    return img


def grid_image(img, X, edges, *, offset=(0.0, 0.0), min_side: int = 384) -> np.ndarray:
    """``img (H, W, 3)`` upscaled to at least ``min_side`` with the edges ``(E, 2)`` of nodes ``X
    (n, 2)`` (texels, minus ``offset``) drawn in yellow."""
    k = max(1, int(np.ceil(min_side / max(min(img.shape[:2]), 1))))
    out = cv2.resize(np.asarray(img, np.float32), None, fx=k, fy=k, interpolation=cv2.INTER_NEAREST)
    P = np.round((np.asarray(X) - np.asarray(offset)) * k).astype(np.int32)
    for a, b in edges:
        cv2.line(out, tuple(int(v) for v in P[a]), tuple(int(v) for v in P[b]), (1.0, 0.85, 0.0), 1, cv2.LINE_AA)
    return out


def segmentation_image(rigid, tiles) -> np.ndarray:
    """``(H, W, 3)``: rigid texels light grey, stochastic dark, tiles ``(k + 1, 4)`` outlined."""
    img = np.where(rigid[..., None], 0.85, 0.15).astype(np.float32).repeat(3, axis=2)
    rng = np.random.default_rng(7)  # fixed colours for the outlines only
    for y0, x0, y1, x1 in tiles[1:]:
        colour = tuple(float(c) for c in rng.uniform(0.3, 1.0, 3))
        cv2.rectangle(img, (int(x0), int(y0)), (int(x1) - 1, int(y1) - 1), colour, 2)
    return img
