"""Previews of a reshape (Fig. 2): the mesh with its graph edges coloured by length change.

Elongated edges are blue, compressed edges red, unchanged ones dark grey; handle nodes are green
dots. Images are ``(size, size, 3) float32`` in [0, 1], framed like
:func:`synthkit.preview.rasterize_mesh` frames the same vertices.
"""

from __future__ import annotations

import cv2
import numpy as np

from synthkit.preview import rasterize_mesh, view_rotation

__all__ = ["edge_colours", "reshape_image", "ELONGATED", "COMPRESSED", "HANDLE"]

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
