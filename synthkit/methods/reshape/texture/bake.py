"""Distortion map, stretch and the offline shader bake (Cabral et al. 2009, 4.4 and 4.5).

Arrays: textures ``(H, W, C) float32`` in [0, 1]; node positions ``X (n, 2)`` in original texel
coordinates and ``Y (n, 2)`` in output texel coordinates (``x`` columns, ``y`` rows, pixel centres
at ``+0.5``); ``triangles (t, 3)``.

- :func:`distortion_map` rasterizes the deformed triangles ``Y`` with the original coordinates
  ``X`` as attribute: the paper's distortion map, ``(Ho, Wo, 2)`` original texel coordinates per
  output texel. Texels no triangle covers take their nearest covered texel's value, so bilinear
  reads along the contour do not pull in the background.
- :func:`triangle_stretch` gives each triangle's singular values of the map ``X -> Y``.
- :func:`bake` evaluates the paper's fragment shader texel by texel::

      UV = distortionMap(p); tile = tilemap(UV)
      color = base(UV) + lerp(detail(UV), detail(tile origin + p mod tile size), stretch)  (tile != 0)
      color = base(UV) + detail(UV)                                                        (rigid)

  with ``stretch = clip((s_max - 1) / ramp, 0, 1)`` from the deformation grid, so an unstretched
  texel keeps its own detail and a texel stretched by ``1 + ramp`` or more takes the tile's.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np
from scipy import ndimage

from synthkit.core.numba_cache import NUMBA_CACHE

__all__ = ["DistortionMap", "distortion_map", "triangle_jacobians", "triangle_stretch", "bake", "remap",
           "laplacian_energy"]


@dataclass
class DistortionMap:
    """``uv (Ho, Wo, 2) float32`` original texel coordinates per output texel, ``covered (Ho, Wo)
    bool`` and ``triangle (Ho, Wo) int32`` (the covering triangle, nearest one outside)."""

    uv: np.ndarray
    covered: np.ndarray
    triangle: np.ndarray


@numba.njit(cache=NUMBA_CACHE)
def _raster(X, Y, tri, uv, owner):  # pragma: no cover - compiled
    """Scan-convert each triangle of ``Y`` (texel centres at +0.5) writing barycentric ``X``."""
    Ho, Wo = owner.shape
    for t in range(tri.shape[0]):
        i, j, k = tri[t, 0], tri[t, 1], tri[t, 2]
        ax, ay, bx, by, cx, cy = Y[i, 0], Y[i, 1], Y[j, 0], Y[j, 1], Y[k, 0], Y[k, 1]
        det = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if det == 0.0:
            continue
        x0 = max(int(np.floor(min(ax, bx, cx) - 0.5)) + 1, 0)
        x1 = min(int(np.floor(max(ax, bx, cx) - 0.5)), Wo - 1)
        y0 = max(int(np.floor(min(ay, by, cy) - 0.5)) + 1, 0)
        y1 = min(int(np.floor(max(ay, by, cy) - 0.5)), Ho - 1)
        for py in range(y0, y1 + 1):
            qy = py + 0.5
            for px in range(x0, x1 + 1):
                qx = px + 0.5
                l1 = ((qx - ax) * (cy - ay) - (qy - ay) * (cx - ax)) / det
                l2 = ((bx - ax) * (qy - ay) - (by - ay) * (qx - ax)) / det
                l0 = 1.0 - l1 - l2
                if l0 >= -1e-9 and l1 >= -1e-9 and l2 >= -1e-9:
                    uv[py, px, 0] = l0 * X[i, 0] + l1 * X[j, 0] + l2 * X[k, 0]
                    uv[py, px, 1] = l0 * X[i, 1] + l1 * X[j, 1] + l2 * X[k, 1]
                    owner[py, px] = t


def distortion_map(X, Y, triangles, shape) -> DistortionMap:
    """Rasterize the triangles at ``Y (n, 2)`` into an output of ``shape (Ho, Wo)`` with the
    coordinates ``X (n, 2)`` interpolated (barycentric). Raises ValueError on an empty output."""
    X, Y = np.ascontiguousarray(X, np.float64), np.ascontiguousarray(Y, np.float64)
    tri = np.ascontiguousarray(triangles, np.int64)
    if min(shape) < 1:
        raise ValueError(f"output shape must be positive, got {shape}")
    uv = np.zeros(tuple(shape) + (2,), np.float32)
    owner = np.full(shape, -1, np.int32)
    _raster(X, Y, tri, uv, owner)
    covered = owner >= 0
    if not covered.any():
        raise ValueError("no output texel is covered by the deformed grid")
    if not covered.all():
        _, (iy, ix) = ndimage.distance_transform_edt(~covered, return_indices=True)
        uv, owner = uv[iy, ix], owner[iy, ix]
    return DistortionMap(uv, covered, owner)


def triangle_jacobians(X, Y, triangles) -> np.ndarray:
    """Jacobian ``(t, 2, 2)`` of each triangle's linear map ``X -> Y`` (column ``d``: the image of
    the unit step along axis ``d``)."""
    P, Q = X[triangles], Y[triangles]
    A = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)  # (t, 2, 2) columns: edges
    B = np.stack([Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0]], axis=2)
    return B @ np.linalg.inv(A)


def triangle_stretch(X, Y, triangles) -> np.ndarray:
    """Singular values ``(t, 2)`` (largest first) of each triangle's linear map ``X -> Y``."""
    return np.linalg.svd(triangle_jacobians(X, Y, triangles), compute_uv=False)


def remap(img, uv, wrap: bool) -> np.ndarray:
    """Bilinear read of ``img (H, W[, C])`` at ``uv (Ho, Wo, 2)`` texel coordinates (wrapped or
    clamped at the border)."""
    border = cv2.BORDER_WRAP if wrap else cv2.BORDER_REPLICATE
    out = cv2.remap(img, uv[..., 0] - 0.5, uv[..., 1] - 0.5, cv2.INTER_LINEAR, borderMode=border)
    return out.reshape(uv.shape[:2] + img.shape[2:])


def bake(base, detail, tile_ids, tiles, dmap: DistortionMap, stretch, *, wrap: bool = False) -> np.ndarray:
    """The shader of 4.5 evaluated per output texel: ``(Ho, Wo, C) float32`` in [0, 1].

    ``base``, ``detail`` ``(H, W, C)``; ``tile_ids (H, W) int32`` and ``tiles (k + 1, 4)`` from
    :func:`detail.tile_map`; ``stretch (Ho, Wo)`` in [0, 1]; ``wrap`` for toroidal textures.
    """
    uv = dmap.uv
    H, W = tile_ids.shape
    b = remap(base, uv, wrap)
    d = remap(detail, uv, wrap)
    ix = np.floor(uv[..., 0]).astype(np.int64)
    iy = np.floor(uv[..., 1]).astype(np.int64)
    ix, iy = (ix % W, iy % H) if wrap else (np.clip(ix, 0, W - 1), np.clip(iy, 0, H - 1))
    tid = tile_ids[iy, ix]
    sel = np.flatnonzero(tid.ravel() != 0)
    if len(sel):
        py, px = np.divmod(sel, uv.shape[1])
        y0, x0, y1, x1 = (tiles[tid.ravel()[sel], k] for k in range(4))
        dt = detail[y0 + py % (y1 - y0), x0 + px % (x1 - x0)]
        s = np.asarray(stretch, np.float32).ravel()[sel][:, None]
        flat = d.reshape(len(tid.ravel()), -1)
        flat[sel] = (1 - s) * flat[sel] + s * dt.reshape(len(sel), -1)
        d = flat.reshape(d.shape)
    return np.clip(b + d, 0.0, 1.0)


def laplacian_energy(img, mask=None) -> float:
    """High-frequency energy: the variance of the Laplacian (3x3) of the luminance of ``img (H, W[,
    C])``, over ``mask (H, W) bool`` (eroded by one texel, so the mask's border is not counted)."""
    img = np.asarray(img, np.float32)
    lum = img @ np.array([0.299, 0.587, 0.114], np.float32) if img.ndim == 3 else img
    lap = cv2.Laplacian(lum, cv2.CV_32F, ksize=1)
    if mask is None:
        return float(lap[1:-1, 1:-1].var())
    m = ndimage.binary_erosion(mask, iterations=1)
    return float(lap[m].var()) if m.sum() > 1 else float("nan")
