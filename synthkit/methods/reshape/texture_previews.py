"""PNG previews of the texture reshape (Cabral et al. 2009, Figs. 7 and 8), as ``(H, W, 3)`` images.

- :func:`autosimilarity_image`: ``T_x`` in red, ``T_y`` in green (Fig. 7(d)), each scaled so that
  ``4 tau`` is full intensity.
- :func:`grid_image`: grid edges drawn over a texture (Fig. 7(e) on the source, 7(f) on the bake).
- :func:`segmentation_image`: rigid texels light, stochastic dark, each detail tile outlined in
  its own colour (Fig. 8(b, c)).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["autosimilarity_image", "grid_image", "segmentation_image", "source_window"]


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
