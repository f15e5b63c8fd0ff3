"""Detail reintroduction, offline part (Cabral et al. 2009, 4.5), over ``(H, W)`` texel maps.

1. :func:`segment_rigid`: the per-texel maximum of the directional maps, segmented into rigid and
   stochastic texels by a binary graph cut [BJ01] (:func:`synthkit.core.graphcut.grid_mincut`):
   region costs ``max(tau - T, 0) / tau`` for rigid and ``min(max(T - tau, 0) / tau, 1)`` for
   stochastic, and BJ01's boundary cost ``smoothness * exp(-(L_p - L_q)^2 / (2 edge_sigma^2))``
   between 4-neighbours on the equalized luminance ``L``. ``tau`` is in the units of
   :func:`autosim.equalize_luminance` (texture variance), so one value serves every texture, as
   the paper found with its equalized textures.

   Why the boundary term: eq. 9 spreads a feature's error over ``Delta + n / 2`` texels around it
   (a pixel 8 texels from a door jamb still sees it within its +-10 line), so a threshold alone
   makes every rigid region 12 texels too wide: on the generated 512^2 wall the thresholded mask
   (Potts cost only) had IoU 0.76 with the known mask (20k false rigid texels). Capping the
   stochastic cost at 1 and making cuts cheap across luminance edges moves the boundary back onto
   the feature's edge: IoU 1.0 there with ``smoothness`` 20 and ``edge_sigma`` 0.5.
2. :func:`grow_tile`: in one stochastic region, a rectangle grown from a random seed, spiral-like
   (right, down, left, up in turn, each side as far as one step keeps the rectangle inside); the
   largest over ``tries`` seeds is the region's detail tile (the paper's naive search).
   :func:`largest_rectangle` is the exact search beyond the paper (the paper points to [DMR97]
   for polygons; on a texel mask the "largest rectangle in a histogram" pass over the rows is
   exact in O(H W)): ``tile_map(..., search="exact")``.
3. :func:`tile_map`: tile id per texel (0 rigid or no tile) and the ``(k, 4)`` tile table.
4. :func:`base_detail`: a bilateral filter [TM98] splits the texture into base and detail.

Beyond the paper (its section 6 names the limitation): :func:`split_regions` cuts the stochastic
texels into several labels by k-means on local statistics (mean and log standard deviation of
the equalized luminance over 15 x 15 texels, labels median-filtered over 7 x 7), so two
materials that touch get a tile each; an option (``regions: split``), off by default (measured
on a real house: docs/findings/reshape.md).
"""

from __future__ import annotations

import cv2
import numba
import numpy as np
from scipy import ndimage

from synthkit.core.graphcut import grid_mincut
from synthkit.core.numba_cache import NUMBA_CACHE

__all__ = ["segment_rigid", "split_regions", "grow_tile", "largest_rectangle", "tile_map", "base_detail"]


def segment_rigid(T, lum, *, tau: float, smoothness: float, edge_sigma: float) -> np.ndarray:
    """Rigid mask ``(H, W) bool`` from the directional maps ``T (D, H, W)`` (max over directions)
    and the equalized luminance ``lum (H, W)`` by the binary cut above. Raises ValueError for a
    non-positive ``tau`` or ``edge_sigma``, or a negative smoothness."""
    if tau <= 0 or edge_sigma <= 0:
        raise ValueError(f"tau and edge_sigma must be positive, got {tau}, {edge_sigma}")
    if smoothness < 0:
        raise ValueError(f"smoothness must be non-negative, got {smoothness}")
    Tm = np.asarray(T, np.float64).max(axis=0)
    L = np.asarray(lum, np.float64)
    cost_rigid = np.maximum(tau - Tm, 0.0) / tau
    cost_stoch = np.minimum(np.maximum(Tm - tau, 0.0) / tau, 1.0)
    right = np.zeros_like(L)
    down = np.zeros_like(L)
    right[:, :-1] = smoothness * np.exp(-((L[:, 1:] - L[:, :-1]) ** 2) / (2 * edge_sigma**2))
    down[:-1] = smoothness * np.exp(-((L[1:] - L[:-1]) ** 2) / (2 * edge_sigma**2))
    side, _ = grid_mincut(cost_rigid, cost_stoch, {(0, 1): right, (1, 0): down})
    return side  # sink side pays the source capacity: cost_rigid


def split_regions(stochastic, lum, *, clusters: int, rng) -> np.ndarray:
    """Labels ``(H, W) int32`` (0: not stochastic) of the connected components of each k-means
    cluster (``clusters`` of them, seeded by ``rng``) of the ``stochastic (H, W) bool`` texels, on
    the local mean and log standard deviation of ``lum (H, W)``."""
    from scipy.cluster.vq import kmeans2

    lum = np.asarray(lum, np.float32)
    mean = cv2.boxFilter(lum, -1, (15, 15))
    std = np.sqrt(np.maximum(cv2.boxFilter(lum * lum, -1, (15, 15)) - mean * mean, 0)) + 1e-3
    idx = np.flatnonzero(stochastic.ravel())
    labels = np.zeros(stochastic.shape, np.int32)
    if len(idx) < clusters:
        return ndimage.label(stochastic)[0].astype(np.int32)
    feat = np.column_stack([mean.ravel()[idx], np.log(std.ravel()[idx])]).astype(np.float64)
    feat = (feat - feat.mean(axis=0)) / np.maximum(feat.std(axis=0), 1e-9)
    _, cl = kmeans2(feat, clusters, minit="++", seed=rng)
    part = np.full(stochastic.size, -1)
    part[idx] = cl
    part = ndimage.median_filter(part.reshape(stochastic.shape), size=7)  # k-means labels are speckled
    part[~stochastic] = -1
    base = 0
    for c in range(clusters):
        lab, n = ndimage.label(part == c)
        labels[lab > 0] = lab[lab > 0] + base
        base += n
    return labels


def _integral(mask: np.ndarray) -> np.ndarray:
    S = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), np.int64)
    S[1:, 1:] = np.cumsum(np.cumsum(mask, axis=0), axis=1)
    return S


def _full(S, y0, y1, x0, x1) -> bool:
    """Whether every texel of rows ``[y0, y1)`` and columns ``[x0, x1)`` is in the region."""
    if y0 < 0 or x0 < 0 or y1 >= S.shape[0] or x1 >= S.shape[1]:
        return False
    return S[y1, x1] - S[y0, x1] - S[y1, x0] + S[y0, x0] == (y1 - y0) * (x1 - x0)


def _grow(S, y, x) -> tuple[int, int, int, int]:
    """Spiral growth from seed ``(y, x)``: ``(y0, x0, y1, x1)`` (end exclusive)."""
    r = [y, x, y + 1, x + 1]
    steps = [8, 8, 8, 8]
    while any(steps):
        for side in range(4):  # right, down, left, up
            if not steps[side]:
                continue
            y0, x0, y1, x1 = r
            k = steps[side]
            cand = [(y0, x0, y1, x1 + k), (y0, x0, y1 + k, x1), (y0, x0 - k, y1, x1), (y0 - k, x0, y1, x1)][side]
            if _full(S, cand[0], cand[2], cand[1], cand[3]):
                r = list(cand)
            else:
                steps[side] = k // 2
    return tuple(r)


def grow_tile(region: np.ndarray, *, rng, tries: int = 8) -> tuple[int, int, int, int] | None:
    """Largest rectangle ``(y0, x0, y1, x1)`` (end exclusive) over ``tries`` spiral growths from
    seeds drawn by ``rng`` in ``region (H, W) bool``; None for an empty region."""
    ys, xs = np.nonzero(region)
    if not len(ys):
        return None
    S = _integral(region)
    best, area = None, -1
    for k in rng.choice(len(ys), size=min(tries, len(ys)), replace=False):
        y0, x0, y1, x1 = _grow(S, int(ys[k]), int(xs[k]))
        if (y1 - y0) * (x1 - x0) > area:
            best, area = (y0, x0, y1, x1), (y1 - y0) * (x1 - x0)
    return best


@numba.njit(cache=NUMBA_CACHE)
def _histogram_rectangle(region):  # pragma: no cover - compiled
    H, W = region.shape
    height = np.zeros(W + 1, np.int64)
    stack = np.zeros(W + 2, np.int64)
    best = np.zeros(5, np.int64)  # area, y0, x0, y1, x1
    for y in range(H):
        for x in range(W):
            height[x] = height[x] + 1 if region[y, x] else 0
        top = 0
        for x in range(W + 1):
            h = height[x] if x < W else 0
            while top > 0 and height[stack[top - 1]] >= h:
                hh = height[stack[top - 1]]
                top -= 1
                left = stack[top - 1] + 1 if top > 0 else 0
                if hh * (x - left) > best[0]:
                    best[0], best[1], best[2], best[3], best[4] = hh * (x - left), y - hh + 1, left, y + 1, x
            stack[top] = x
            top += 1
    return best


def largest_rectangle(region: np.ndarray) -> tuple[int, int, int, int] | None:
    """The largest all-true axis-parallel rectangle ``(y0, x0, y1, x1)`` (end exclusive) of
    ``region (H, W) bool``, exactly; None for an empty region."""
    best = _histogram_rectangle(np.ascontiguousarray(region, np.bool_))
    return None if best[0] == 0 else tuple(int(v) for v in best[1:])


def tile_map(rigid: np.ndarray, *, rng, tries: int = 8, min_side: int = 4,
             search: str = "spiral", labels=None) -> tuple[np.ndarray, np.ndarray]:
    """Tile id ``(H, W) int32`` per texel and the tile table ``(k + 1, 4) int64`` of ``(y0, x0, y1,
    x1)`` rows (row 0 unused: id 0 means rigid, or a region whose tile is thinner than
    ``min_side``). One tile per connected stochastic region (4-connected), by ``search``
    ``"spiral"`` (the paper; seeds come from ``rng`` region by region in label order, so the result
    is deterministic for a seed) or ``"exact"`` (:func:`largest_rectangle`). ``labels (H, W)``
    (from :func:`split_regions`) replaces the connected components when given."""
    if search not in ("spiral", "exact"):
        raise ValueError(f"unknown tile search {search!r}")
    if labels is None:
        labels, _ = ndimage.label(~rigid)
    ids = np.zeros(rigid.shape, np.int32)
    table = [(0, 0, 0, 0)]
    objects = ndimage.find_objects(labels)
    for lab, sl in enumerate(objects, start=1):
        region = labels[sl] == lab
        r = grow_tile(region, rng=rng, tries=tries) if search == "spiral" else largest_rectangle(region)
        if r is None or min(r[2] - r[0], r[3] - r[1]) < min_side:
            continue
        oy, ox = sl[0].start, sl[1].start
        table.append((r[0] + oy, r[1] + ox, r[2] + oy, r[3] + ox))
        ids[sl][region] = len(table) - 1
    return ids, np.asarray(table, np.int64).reshape(-1, 4)


def base_detail(img: np.ndarray, *, sigma_s: float, sigma_r: float) -> tuple[np.ndarray, np.ndarray]:
    """Base ``bilateral(img)`` and detail ``img - base``, both ``(H, W, C) float32`` for ``img
    (H, W, C)`` in [0, 1]; ``sigma_s`` in texels, ``sigma_r`` in intensity."""
    img = np.asarray(img, np.float32)
    base = cv2.bilateralFilter(img, d=-1, sigmaColor=float(sigma_r), sigmaSpace=float(sigma_s))
    base = base.reshape(img.shape)
    return base, img - base
