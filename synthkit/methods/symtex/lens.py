"""Radial lens undistortion searched for the most symmetric image (theta_lens, paper Sec. 6 Ex. 2).

Tsai's one-parameter model: ``p_u = p_d (1 + k1 |p_d|^2)`` with ``p_d`` a distorted and ``p_u`` an
undistorted position, both relative to the distortion centre and divided by half the image's
larger side (normalized coordinates). :func:`undistort` resamples an image at the distorted
position of every output pixel (the cubic ``r_u = r_d (1 + k1 r_d^2)`` solved by Newton steps);
:func:`distort` applies the forward model. :func:`search_k1` maximizes E_symm over ``k1``: a
coarse grid over ``[k1_min, k1_max]``, then golden-section search in the bracket around the best
grid value (the paper's search method is not stated; this is a derivative-free 1-D search).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import cv2
import numpy as np

TABLE = 4096


def _grid(shape, center):
    H, W = shape[:2]
    key = None if center is None else (float(center[0]), float(center[1]))
    return _grid_cached(int(H), int(W), key)


@functools.lru_cache(maxsize=4)
def _grid_cached(H: int, W: int, center):
    """Normalized coordinates ``v, u`` (read-only), their radius, the centre and the scale."""
    cy, cx = ((H - 1) / 2.0, (W - 1) / 2.0) if center is None else center
    s = max(H, W) / 2.0
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    v, u = (yy - np.float32(cy)) / np.float32(s), (xx - np.float32(cx)) / np.float32(s)
    ru = np.hypot(u, v)
    # lookup of ru in a table of TABLE + 1 radii over [0, max ru]: index and linear weight
    pos = ru * np.float32(TABLE / max(float(ru.max()), 1e-9))
    idx = np.minimum(pos.astype(np.int32), TABLE - 1)
    frac = pos - idx
    for arr in (v, u, ru, idx, frac):
        arr.setflags(write=False)
    return v, u, ru, cy, cx, s, idx, frac


def _remap(img: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    src = np.asarray(img, dtype=np.float32)
    return cv2.remap(src, xs.astype(np.float32), ys.astype(np.float32), cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def distort(img: np.ndarray, k1: float, *, center=None) -> np.ndarray:
    """Apply radial distortion ``k1`` to ``img (H, W[, C])``: output ``p_d`` shows input ``p_u``."""
    v, u, ru, cy, cx, s, _, _ = _grid(img.shape, center)
    g = 1.0 + k1 * ru * ru
    return _remap(img, cy + v * g * s, cx + u * g * s)


def undistort(img: np.ndarray, k1: float, *, center=None, iterations: int = 8) -> np.ndarray:
    """Remove radial distortion ``k1`` from ``img (H, W[, C])`` (inverse of :func:`distort`).

    For negative ``k1`` the model is monotonic only up to ``r* = sqrt(-1 / (3 k1))``; distorted
    radii are clamped there (pixels beyond the model's valid range show the edge of that disc).
    The cubic is solved by Newton steps on a table of ``TABLE + 1`` radii, interpolated per pixel.
    """
    v, u, ru, cy, cx, s, idx, frac = _grid(img.shape, center)
    # the radial map is 1-D: solve the cubic on a fine table of radii, interpolate per pixel
    table = np.linspace(0.0, float(ru.max()), TABLE + 1)
    r_cap = np.sqrt(-1.0 / (3.0 * k1)) if k1 < 0 else np.inf
    rd = np.minimum(table, r_cap)
    for _ in range(iterations):
        g = rd + k1 * rd**3 - table
        dg = np.maximum(1.0 + 3.0 * k1 * rd * rd, 1e-3)
        rd = np.clip(rd - g / dg, 0.0, r_cap)
    ratio_table = (np.divide(rd, table, out=np.ones_like(table), where=table > 0) * s).astype(np.float32)
    ratio = ratio_table[idx] * (1.0 - frac) + ratio_table[idx + 1] * frac
    return _remap(img, cy + v * ratio, cx + u * ratio)


def search_k1(
    score: Callable[[float], float],
    *,
    k1_min: float,
    k1_max: float,
    samples: int = 41,
    tol: float = 1e-4,
) -> tuple[float, list[tuple[float, float]]]:
    """Maximize ``score(k1)`` over ``[k1_min, k1_max]``: grid of ``samples`` then golden section.

    Returns the best ``k1`` and every evaluated ``(k1, score)`` in order.
    """
    history: list[tuple[float, float]] = []

    def f(k):
        val = float(score(float(k)))
        history.append((float(k), val))
        return val

    ks = np.linspace(k1_min, k1_max, samples)
    vals = np.array([f(k) for k in ks])
    b = int(np.argmax(vals))
    lo, hi = ks[max(b - 1, 0)], ks[min(b + 1, samples - 1)]
    invphi = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - invphi * (hi - lo), lo + invphi * (hi - lo)
    fc, fd = f(c), f(d)
    while hi - lo > tol:
        if fc >= fd:
            hi, d, fd = d, c, fc
            c = hi - invphi * (hi - lo)
            fc = f(c)
        else:
            lo, c, fc = c, d, fd
            d = lo + invphi * (hi - lo)
            fd = f(d)
    best_k, best_v = max(history, key=lambda kv: kv[1])
    return best_k, history
