"""Materials continue instead of stretching (beyond the paper's section 4; docs/findings/reshape.md).

A surface of a house (a brick wall, a roof slope) maps its atlas patch with one affine map from
world to texels. When the wall widens, :func:`extend_surface` keeps that map, anchored at the
corner that moved least (a wall widened from its left end keeps its left texels; a wall carried
up by a raise keeps all of them) and with the new surface turned back into the input's plane (a
roof slope whose pitch changes): the new corners get the texels the input's map gives their new
positions, so every world length keeps its texel length (texel scale 1), and the texels the
patch does not hold are filled by continuing its content: each is read one or more whole periods
back into the patch (:func:`periods`), so brick courses, siding boards and roof tiles repeat
whole. Stochastic content (plaster, concrete) is continued the same way, by its strongest
repetition shift, not synthesized by quilting. Copies are by whole texels: nothing is
resampled; texels more than two texels outside the new triangles are black (they are never
sampled, and compress). A surface whose map is not affine (bent over an angle edge, mirrored) returns None and
goes through the paper's reshape instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import distance_transform_edt

__all__ = ["Extended", "affine_map", "patch_mask", "periods", "lattice", "extend_surface", "extend_tiled"]

EDGE = 8
"""Texels along a patch's border that continued texels are read from only when its interior has no
texel at a whole period: the border often holds a strip that is not the material."""

SHIFTS = 12
"""Whole periods tried each way when continuing a texel."""

PERIODIC = 0.05
"""Lattice strength (:func:`lattice`) under which content counts as stochastic and is quilted
(plaster against brick and roof tiles: docs/findings/reshape.md)."""

QUILT_PATCH = 32
"""Side (texels) of the quilting patches of stochastic content (overlap a quarter of it)."""

AFFINE_TOL = 0.75
"""Largest misfit (texels) of the world-to-texel affine map of a surface that still counts as affine."""


@dataclass
class Extended:
    """An extended surface: new ``UV (c, 2)`` of its corners in the patch, the patch ``(h, w, 3)``,
    its metrics (``texel_scale_error``: mean |new texel length / world length over the input's - 1|
    over the surface's edges, ``periods`` in texels, ``continued`` share of copied texels)."""

    UV: np.ndarray
    texture: np.ndarray
    metrics: dict


def affine_map(P: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares ``M (4, 2)`` with ``[P, 1] @ M ~ C`` for corners ``P (c, 3)`` and texels
    ``C (c, 2)``, and its largest misfit (texels)."""
    A = np.column_stack([P, np.ones(len(P))])
    M = np.linalg.lstsq(A, C, rcond=None)[0]
    return M, float(np.abs(A @ M - C).max()) if len(C) else 0.0


def patch_mask(C: np.ndarray, F: np.ndarray, shape, *, erode: bool = True) -> np.ndarray:
    """``(H, W) bool``: the texels inside the triangles ``F`` over texel corners ``C (c, 2)``,
    shrunk by one texel with ``erode`` (their border may hold a neighbour patch's texels)."""
    mask = np.zeros(shape[:2], np.uint8)
    for tri in F:
        cv2.fillPoly(mask, [np.round(C[tri] * 16).astype(np.int32)], 1, shift=4)
    return (cv2.erode(mask, np.ones((3, 3), np.uint8)) if erode else mask).astype(bool)


def periods(img: np.ndarray, mask: np.ndarray, *, min_period: int = 4) -> tuple[int, int, int]:
    """The repetition lattice ``(px, qx, py)`` of :func:`lattice`."""
    return lattice(img, mask, min_period=min_period)[:3]


def lattice(img: np.ndarray, mask: np.ndarray, *, min_period: int = 4) -> tuple[int, int, int, float]:
    """The repetition lattice ``(px, qx, py)`` (texels) of ``img (H, W, 3)`` inside ``mask``: the
    content repeats by ``(px, 0)`` along a row and by ``(qx, py)`` to the next course (``qx`` half a
    brick in a running bond, 0 in a stack). From the masked, normalised autocorrelation of the
    luminance over the mask's box (shifts whose overlap is under a quarter of the mask left out):
    along each axis its largest value past its first negative value (a whole course, not the
    smoothness of neighbouring texels) and ``min_period``, up to half the box (half the box when
    it never turns negative); ``py`` and ``qx`` maximise it over the horizontal offsets too, ``qx``
    reduced modulo ``px``; and its strength, the smaller normalised autocorrelation at ``(px, 0)``
    and ``(qx, py)`` (1: the content repeats exactly, or never decorrelates along that axis, as
    siding boards along their length; plaster: under :data:`PERIODIC`)."""
    ys, xs = np.nonzero(mask)
    if not len(ys):
        return 1, 0, 1, 0.0
    box = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
    lum = img[box].mean(axis=2) if img.ndim == 3 else img[box]
    m = mask[box].astype(np.float64)
    lum = np.where(m > 0, lum - lum[m > 0].mean(), 0.0)
    shape = [2 * s for s in lum.shape]
    corr = np.fft.irfft2(np.abs(np.fft.rfft2(lum, shape)) ** 2, shape)
    norm = np.fft.irfft2(np.abs(np.fft.rfft2(m, shape)) ** 2, shape)
    r = corr / np.maximum(norm, 1.0) / max(float((lum ** 2).sum() / m.sum()), 1e-12)
    r[norm < 0.25 * m.sum()] = -np.inf
    h, w = lum.shape
    px = _first_peak(r[0, :w], min_period, w)
    dx = np.r_[0:w // 2, shape[1] - w // 2 + 1:shape[1]]
    best = r[:h][:, dx].max(axis=1)
    py = _first_peak(np.where(np.isfinite(best), best, -np.inf), min_period, h, line=r[:h, 0])
    j = int(dx[np.argmax(r[py, dx])])
    qx = j - shape[1] if j >= shape[1] // 2 else j
    sx = r[0, px] if (r[0, :max(w // 2, 1)] < 0).any() else 1.0
    sy = r[py, j] if (r[:max(h // 2, 1), 0] < 0).any() else 1.0
    strength = float(min(sx, sy))
    return px, (qx + px // 2) % px - px // 2, py, strength if np.isfinite(strength) else 0.0


def _first_peak(values, min_period: int, n: int, line=None) -> int:
    """Shift of the largest of ``values`` past the first negative value of ``line`` (default
    ``values``) and ``min_period``, below ``n // 2`` (``n // 2`` when there is none)."""
    hi = max(n // 2, min_period + 1)
    line = values if line is None else line
    dips = np.flatnonzero(line[:hi] < 0)
    start = max(min_period, int(dips[0]) if len(dips) else hi)
    seg = values[start:hi]
    if not len(seg) or not np.isfinite(seg).any():
        return max(n // 2, 1)
    return int(start + np.argmax(seg))


def _fill(img, mask, box_new, period) -> tuple[np.ndarray, float]:
    """Patch ``(h, w, 3)`` over the texel box ``box_new = (x0, y0, w, h)`` (source texel frame):
    texels inside ``mask`` copied, each other one read at the shortest lattice offset
    ``i (px, 0) + j (qx, py)`` (``period``, :func:`periods`) that lands inside it, at least
    ``EDGE`` texels from its border when one does (the nearest
    texel of the mask when none of up to ``SHIFTS`` periods each way does); returns it and the
    share of texels continued."""
    x0, y0, w, h = box_new
    H, W = mask.shape
    X, Y = np.meshgrid(np.arange(x0, x0 + w), np.arange(y0, y0 + h))
    sx, sy = X.ravel(), Y.ravel()
    inside = _inside(mask, sx, sy)
    continued = float(1 - inside.mean())
    px, qx, py = max(period[0], 1), period[1], max(period[2], 1)
    k = np.arange(-SHIFTS, SHIFTS + 1)
    offsets = np.array([(i * px + j * qx, j * py) for i in k for j in k])
    offsets = offsets[np.argsort(np.hypot(offsets[:, 0], offsets[:, 1]), kind="stable")][1:]
    todo = np.flatnonzero(~inside)
    core = cv2.erode(mask.astype(np.uint8), np.ones((2 * EDGE + 1, 2 * EDGE + 1), np.uint8)).astype(bool)
    for source in (core, mask):
        for dx, dy in offsets:
            if not len(todo):
                break
            hit = _inside(source, sx[todo] + dx, sy[todo] + dy)
            sx[todo[hit]] += dx
            sy[todo[hit]] += dy
            todo = todo[~hit]
    sx, sy = np.clip(sx, 0, W - 1), np.clip(sy, 0, H - 1)
    if len(todo):
        near = distance_transform_edt(~mask, return_distances=False, return_indices=True)
        sy[todo], sx[todo] = near[0][sy[todo], sx[todo]], near[1][sy[todo], sx[todo]]
    return img[sy, sx].reshape(h, w, -1), continued


def _source_positions(mask: np.ndarray, B: int) -> np.ndarray:
    """``(H - B + 1, W - B + 1) bool``: top-left corners of the ``B x B`` windows inside ``mask``."""
    inside = cv2.erode(mask.astype(np.uint8), np.ones((B, B), np.uint8), anchor=(0, 0),
                       borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return inside[:mask.shape[0] - B + 1, :mask.shape[1] - B + 1].astype(bool)


def _quilt_fill(img, mask, box_new, rng) -> tuple[np.ndarray, float] | None:
    """Patch ``(h, w, 3)`` over ``box_new = (x0, y0, w, h)`` for stochastic content: texels inside
    ``mask`` copied, the others quilted (Efros and Freeman, :mod:`synthkit.core.quilting`) from
    ``QUILT_PATCH``-texel windows of the surface's own texels, each tile matching the texels already
    there and cut along its minimum-error boundary; tiles go most-covered first so each joins what is
    known. The original texels deeper than the overlap stay. None when no window fits the mask."""
    from synthkit.core.quilting import boundary_masks, candidates, overlap_costs, source_patches

    x0, y0, w, h = box_new
    B = min(QUILT_PATCH, w, h)
    ov = max(B // 4, 1)
    ys, xs = np.nonzero(mask)
    crop = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
    src = img[crop]
    valid = _source_positions(mask[crop], B) if B >= 4 and min(src.shape[:2]) >= B else np.zeros((0, 0), bool)
    if not valid.any():
        return None
    X, Y = np.meshgrid(np.arange(x0, x0 + w), np.arange(y0, y0 + h))
    known = _inside(mask, X, Y)
    canvas = np.zeros((h, w, img.shape[2]), np.float32)
    canvas[known] = img[Y[known], X[known]]
    locked = distance_transform_edt(known) > ov
    filled = known.copy()
    rows = np.unique(np.r_[np.arange(0, h - B, B - ov), h - B])
    cols = np.unique(np.r_[np.arange(0, w - B, B - ov), w - B])
    tiles = [(ty, tx) for ty in rows for tx in cols if not filled[ty:ty + B, tx:tx + B].all()]
    while tiles:
        k = int(np.argmax([filled[ty:ty + B, tx:tx + B].sum() for ty, tx in tiles]))
        ty, tx = tiles.pop(k)
        region, weight = canvas[ty:ty + B, tx:tx + B], filled[ty:ty + B, tx:tx + B]
        cost = np.where(valid, overlap_costs(src, region, weight.astype(np.float32)), np.inf)
        cands = candidates(cost, tol=0.1)
        patch = source_patches(src, cands[rng.integers(len(cands))][None], B)
        keep = boundary_masks(patch, region, weight, overlaps=(ov, ov, ov, ov))[0] & ~locked[ty:ty + B, tx:tx + B]
        region[keep] = patch[0][keep]
        filled[ty:ty + B, tx:tx + B] = True
    return canvas, float(1 - known.mean())


def _normal(P: np.ndarray) -> np.ndarray:
    """Unit normal ``(3,)`` of the plane nearest the points ``P (c, 3)``."""
    return np.linalg.svd(P - P.mean(axis=0))[2][-1]


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation ``(3, 3)`` taking unit vector ``a`` to ``b`` (or to ``-b``, whichever
    is nearer: a plane's normal has no sign)."""
    if a @ b < 0:
        a = -a
    v, c = np.cross(a, b), float(a @ b)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def _inside(mask, x, y) -> np.ndarray:
    H, W = mask.shape
    ok = (x >= 0) & (x < W) & (y >= 0) & (y < H)
    out = np.zeros(x.shape, bool)
    out[ok] = mask[y[ok], x[ok]]
    return out


def extend_surface(img: np.ndarray, C: np.ndarray, F: np.ndarray, P0: np.ndarray, P1: np.ndarray,
                   rng=None) -> Extended | None:
    """The continued patch of a surface with texel corners ``C (c, 2)`` (x right, y down, in
    ``img (H, W, 3)``), triangles ``F (k, 3)``, corner positions before ``P0 (c, 3)`` and after
    ``P1 (c, 3)``; None when its world-to-texel map is not affine within :data:`AFFINE_TOL`.
    Content with a lattice strength under :data:`PERIODIC` is quilted (:func:`_quilt_fill`, random
    choices from ``rng``), other content repeated by whole periods (:func:`_fill`)."""
    C1 = _kept_map(C, P0, P1)
    if C1 is None:
        return None
    lo = np.floor(C1.min(axis=0) + 1e-6).astype(int)
    hi = np.ceil(C1.max(axis=0) - 1e-6).astype(int)
    w, h = (np.maximum(hi - lo, 1)).tolist()
    mask = patch_mask(C, F, img.shape)
    if not mask.any():
        return None
    *period, strength = lattice(img, mask)
    box = (int(lo[0]), int(lo[1]), w, h)
    quilted = _quilt_fill(img, mask, box, np.random.default_rng(rng)) if strength < PERIODIC else None
    patch, continued = quilted if quilted is not None else _fill(img, mask, box, period)
    used = cv2.dilate(patch_mask(C1 - lo, F, (h + 2, w + 2), erode=False).astype(np.uint8), np.ones((5, 5), np.uint8))
    patch[~used[:h, :w].astype(bool)] = 0.0
    UV = np.column_stack([(C1[:, 0] - lo[0]) / w, 1.0 - (C1[:, 1] - lo[1]) / h])
    return Extended(UV, patch, {**_scale_error(C, C1, F, P0, P1), "periods": list(period), "continued": continued,
                                "lattice_strength": strength, "quilted": quilted is not None})


def _kept_map(C, P0, P1) -> np.ndarray | None:
    """Texel corners ``(c, 2)`` the input's world-to-texel map gives the new corners ``P1``
    (anchored at the least moved corner, turned back into the input's plane), or None."""
    M, misfit = affine_map(P0, C)
    if misfit > AFFINE_TOL:
        return None
    a = int(np.argmin(np.linalg.norm(P1 - P0, axis=1)))
    Q1 = (P1 - P1[a]) @ _turn(_normal(P1), _normal(P0)).T + P0[a]
    return np.column_stack([Q1, np.ones(len(Q1))]) @ M


def extend_tiled(C: np.ndarray, F: np.ndarray, P0: np.ndarray, P1: np.ndarray, shape) -> Extended | None:
    """A toroidal surface continued by its UVs alone: the new corners' UVs ``(c, 2)`` from the
    kept map (texels of a texture of ``shape (H, W, ...)``), so the tile repeats more often and
    keeps its size; no new texels (``texture`` None). None when the map is not affine."""
    C1 = _kept_map(C, P0, P1)
    if C1 is None:
        return None
    H, W = shape[:2]
    UV = np.column_stack([C1[:, 0] / W, 1.0 - C1[:, 1] / H])
    return Extended(UV, None, {**_scale_error(C, C1, F, P0, P1), "periods": None, "continued": None})


def _scale_error(C, C1, F, P0, P1) -> dict:
    """``texel_scale_error``: mean |texel length / world length after over before - 1| over the
    edges of ``F`` (edges under half a texel left out)."""
    e = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    world0, world1 = (np.linalg.norm(P[e[:, 1]] - P[e[:, 0]], axis=1) for P in (P0, P1))
    tex0, tex1 = (np.linalg.norm(Q[e[:, 1]] - Q[e[:, 0]], axis=1) for Q in (C, C1))
    ok = (world0 > 1e-12) & (world1 > 1e-12) & (tex0 > 0.5)
    scale = (tex1[ok] / world1[ok]) / (tex0[ok] / world0[ok])
    return {"texel_scale_error": float(np.abs(scale - 1).mean()) if ok.any() else 0.0}
