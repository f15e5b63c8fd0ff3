"""Directional texture autosimilarity (Cabral et al. 2009, eq. 9) over ``(H, W)`` float32 maps.

``T_dir(p) = 1 / (2 Delta) * sum_{s = -Delta..Delta, s != 0} ||N(p + s dir) - N(p)||^2`` with
``N(p)`` the ``n x n`` neighbourhood of ``p``. Writing ``d_s(x) = (L(x + s dir) - L(x))^2``, the
neighbourhood distance is the box sum of ``d_s`` at ``p``, and ``d_{-s}(x) = d_s(x - s dir)``, so

    T_dir = Box_n( sum_{s=1..Delta} d_s + shift(d_s, s dir) ) / (2 Delta)

costs ``2 Delta`` shifted differences and one box filter per direction, not a loop over pixels.
The box is normalised (a mean over the ``n^2`` texels, not the paper's sum), so ``T`` is a squared
luminance difference per texel whatever ``n``, and the stiffness ``s_min`` of eq. 13 and the
segmentation threshold keep their meaning when ``n`` changes. Borders are reflected, or wrapped for
toroidal textures.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["DIRECTIONS", "equalize_luminance", "directional_autosimilarity"]

DIRECTIONS = {"horizontal": (1, 0), "vertical": (0, 1)}
"""Texture axes as ``(dx, dy)`` texel steps (x along columns, y along rows)."""


def equalize_luminance(img: np.ndarray) -> np.ndarray:
    """Luminance ``(H, W) float32`` of ``img (H, W[, C])`` in [0, 1], standardised to zero mean and
    unit standard deviation.

    The paper equalizes luminance so that one set of parameters serves every texture. A global
    standardisation does that without the histogram equalization's side effect of stretching the
    low-contrast noise of a plaster wall to the full range (which would make it look rigid).
    """
    img = np.asarray(img, np.float32)
    lum = img @ np.array([0.299, 0.587, 0.114], np.float32) if img.ndim == 3 else img
    if img.ndim == 3 and img.shape[2] != 3:
        raise ValueError(f"img must have 1 or 3 channels, got shape {img.shape}")
    std = float(lum.std())
    return ((lum - lum.mean()) / max(std, 1e-6)).astype(np.float32)


def directional_autosimilarity(
    lum: np.ndarray, *, delta: int = 10, size: int = 5, directions=("horizontal", "vertical"), wrap: bool = False
) -> np.ndarray:
    """Autosimilarity error maps ``(D, H, W) float32`` of ``lum (H, W)``, one per direction (eq. 9).

    ``delta`` is the paper's Delta (10), ``size`` the neighbourhood side (5), ``directions`` names of
    :data:`DIRECTIONS`; ``wrap`` treats the texture as toroidal. Raises ValueError when ``delta`` or
    ``size`` is below 1 or a direction is unknown.
    """
    lum = np.asarray(lum, np.float32)
    if lum.ndim != 2 or lum.size == 0:
        raise ValueError(f"lum must be a non-empty (H, W) array, got shape {lum.shape}")
    if int(delta) < 1:
        raise ValueError(f"delta must be at least 1, got {delta}")
    if int(size) < 1:
        raise ValueError(f"neighbourhood size must be at least 1, got {size}")
    unknown = [d for d in directions if d not in DIRECTIONS]
    if unknown:
        raise ValueError(f"unknown direction {unknown[0]!r} (use {', '.join(DIRECTIONS)})")
    delta, h = int(delta), int(size) // 2
    pad = delta + h
    P = np.pad(lum, pad, mode="wrap" if wrap else "reflect")
    out = np.empty((len(directions),) + lum.shape, np.float32)
    for k, name in enumerate(directions):
        dx, dy = DIRECTIONS[name]
        acc = np.zeros_like(P)
        for s in range(1, delta + 1):
            ox, oy = s * dx, s * dy
            d = np.zeros_like(P)
            d[: P.shape[0] - oy, : P.shape[1] - ox] = P[oy:, ox:] - P[: P.shape[0] - oy, : P.shape[1] - ox]
            np.square(d, out=d)
            acc += d
            acc[oy:, ox:] += d[: P.shape[0] - oy, : P.shape[1] - ox]
        box = cv2.boxFilter(acc, -1, (2 * h + 1, 2 * h + 1), normalize=True, borderType=cv2.BORDER_REFLECT)
        out[k] = box[pad:pad + lum.shape[0], pad:pad + lum.shape[1]] / (2 * delta)
    return out
