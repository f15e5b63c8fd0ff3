"""Symmetry-guided image quilting (theta_synth, paper Sec. 4 Example 1).

The output is a toroidal grid of tiles (see :mod:`synthkit.core.quilting`). It starts from random
patches (or from unguided quilting); then the walk visits every tile in raster order, sweep after
sweep. At a tile, the ``k`` source patches with the lowest overlap error against the four
neighbouring bands are the overlap-consistent candidates; each is cut into place with
minimum-error boundary cuts, and the tile takes the candidate whose result has the translational
symmetry representation closest (E_L2) to the target, or keeps its current content when no
candidate is closer (so the objective never rises: a steepest-descent walk). Among the candidates
that gain at least 85% of the best one's (:data:`SEAM_SHARE`), it takes the one whose patch border
shows least (:func:`choose_candidate`, :func:`border_energy`).

Candidates are evaluated incrementally: the change of the windowed autocorrelation caused by
replacing one block is computed from the block and its surroundings only
(:class:`synthkit.core.autocorrelation.IncrementalAutocorrelation`), batched over all candidates of the
tile (in chunks shared by two threads), and E_L2 of the standardized result follows from four
sums of that change over the window, exactly (the same values as a full recompute, up to
rounding). With every displacement in the window (``symmetry.window: 0.5``, the default) those
sums come from fields of the current image computed once per tile and one small FFT per
candidate, with no full-size transform per candidate. ``evaluation="full"`` recomputes S_T of
the whole image for every candidate instead (the paper's way; for benchmarks and as the
reference in tests).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field

import numba
import numpy as np

from synthkit.core import quilting as q
from synthkit.core import symmetry as sy
from synthkit.core.autocorrelation import IncrementalAutocorrelation, one_blas_thread
from synthkit.core.flow import NUMBA_CACHE

_PREPARE = ThreadPoolExecutor(max_workers=1, thread_name_prefix="symtex-prepare")
"""The thread that prepares a tile's evaluation while the walk builds its candidates."""


@dataclass
class WalkResult:
    """Result of :func:`guided_walk`: ``image (H, W, C)``, per-tile source ``origins (ny, nx, 2)``,
    per-pixel source ``sources (H, W, 2)`` (see :class:`synthkit.core.quilting.QuiltResult`),
    objective ``history`` (start, then after each sweep), tile visits ``iterations``, tiles
    ``changed`` in total, evaluated ``candidates_evaluated``."""

    image: np.ndarray
    origins: np.ndarray
    sources: np.ndarray | None = None
    history: list[float] = field(default_factory=list)
    iterations: int = 0
    changed: int = 0
    candidates_evaluated: int = 0


def random_init(
    source: np.ndarray, shape, *, patch: int, overlap: int, rng, seams: str = "dp", progress=None
) -> q.QuiltResult:
    """Toroidal tiling with uniformly random source patches, each cut into its filled neighbours
    (``progress``: optional wrapper of the tiles, as in :func:`synthkit.core.quilting.quilt`)."""
    src = np.asarray(source, dtype=np.float32)
    q.check_sizes(src.shape, shape, patch, overlap)
    H, W = int(shape[0]), int(shape[1])
    ys, xs = q.tile_grid(H, patch, overlap), q.tile_grid(W, patch, overlap)
    canvas = np.zeros((H, W) + src.shape[2:], dtype=np.float32)
    filled = np.zeros((H, W), dtype=bool)
    origins = np.zeros((len(ys), len(xs), 2), dtype=np.int64)
    sources = np.zeros((H, W, 2), dtype=np.int64)
    tiles = [(i, j) for i in range(len(ys)) for j in range(len(xs))]
    for i, j in progress(tiles, total=len(tiles), desc="random start") if progress else tiles:
        y0, x0 = ys[i], xs[j]
        pos = np.array([rng.integers(src.shape[0] - patch + 1), rng.integers(src.shape[1] - patch + 1)])
        ry, rx = q.region_indices(y0, x0, patch, (H, W))
        p = q.source_patches(src, pos[None], patch)
        region = canvas[np.ix_(ry, rx)]
        weight = filled[np.ix_(ry, rx)]
        ov = q.tile_overlaps(ys, xs, i, j, patch, (H, W))
        keep = q.seam_masks(p, region, weight, overlaps=ov, method=seams)[0]
        q.paste(canvas, p[0], keep, y0, x0)
        q.paste(sources, q.patch_sources(pos[None], patch)[0], keep, y0, x0)
        filled[np.ix_(ry, rx)] = True
        origins[i, j] = pos
    return q.QuiltResult(canvas, origins, ys, xs, sources)


def l2_of_autocorrelations(acs: np.ndarray, target: np.ndarray) -> np.ndarray:
    """E_L2 ``(K,)`` of standardized windowed autocorrelations ``acs (K, a, b)`` against ``target (a, b)``."""
    flat = acs.reshape(acs.shape[0], -1)
    mu = flat.mean(axis=1, keepdims=True)
    sd = flat.std(axis=1, keepdims=True)
    sd = np.where(sd > 0, sd, np.inf)
    z = (flat - mu) / sd
    return ((z - target.reshape(1, -1)) ** 2).mean(axis=1)


def _band(patch: int, overlaps: tuple[int, int, int, int]) -> np.ndarray:
    top, left, bottom, right = overlaps
    w = np.zeros((patch, patch), dtype=bool)
    w[:top, :] = True
    w[:, :left] = True
    if bottom:
        w[patch - bottom :, :] = True
    if right:
        w[:, patch - right :] = True
    return w


def guided_walk(
    source: np.ndarray,
    init: q.QuiltResult,
    *,
    signals: Sequence[str],
    targets: Sequence[np.ndarray],
    window: tuple[int, int],
    patch: int,
    candidates: int,
    sweeps: int,
    evaluation: str = "incremental",
    seams: str = "dp",
    progress: Callable | None = None,
    workers: int | None = None,
) -> WalkResult:
    """Improve ``init`` by the paper's walk over tiles toward standardized S_T ``targets``.

    Parameters
    ----------
    source : (Hs, Ws, C) float32 source texture.
    init : starting toroidal tiling (its ``image`` is copied).
    signals : per-signal names ("lum", "1-lum"); ``targets`` the matching standardized S_T windows
        ``(2 wy + 1, 2 wx + 1)``; the objective is the sum of their E_L2.
    candidates : k overlap-consistent candidates tried per tile.
    sweeps : passes over the tiles; the walk stops early after a pass that changes no tile.
    evaluation : "incremental" (block update of S_T) or "full" (S_T of the whole image per candidate).
        Blocks larger than half the output force "full".
    seams : "dp" (minimum-error boundary cuts) or "graphcut" (graph-cut seams) for every candidate.
    progress : optional wrapper ``progress(iterable, total=, desc=)`` for a progress bar.
    workers : threads sharing the incremental evaluation of a tile's candidates (default
        ``min(2, os.cpu_count())``); with two or more, a tile's fixed evaluation work runs in a
        second thread while the candidates are built. The same result for a given ``workers``
        (across them, candidate values may differ by an ulp).
    """
    src = np.asarray(source, dtype=np.float32)
    canvas, origins, sources = init.image.copy(), init.origins.copy(), init.sources.copy()
    ys, xs = init.ys, init.xs
    H, W = canvas.shape[:2]
    if 2 * patch > min(H, W):
        evaluation = "full"
    targets = [np.asarray(t, dtype=np.float64) for t in targets]
    workers = min(2, os.cpu_count() or 1) if workers is None else workers

    def sig(img):
        return [sy.signal(img, s).astype(np.float64) for s in signals]

    def full_value(img):
        pairs = zip(sig(img), targets, strict=True)
        return float(sum(sy.e_l2(sy.translational(f, window=window), T) for f, T in pairs))

    states = [] if evaluation != "incremental" else [
        IncrementalAutocorrelation(f, window=window, offset=float(f.mean()), fft_dtype=np.float32) for f in sig(canvas)]

    def current_value():
        if states:
            return float(sum(l2_of_autocorrelations(st.ac[None], T)[0] for st, T in zip(states, targets, strict=True)))
        return full_value(canvas)

    result = WalkResult(canvas, origins, sources)
    value = current_value()
    result.history.append(value)
    matcher = q.PatchMatcher(src, patch)
    with one_blas_thread() if states else nullcontext():
        _walk(result, value, src, matcher, (ys, xs), states, targets, full_value, current_value, signals=signals,
              patch=patch, candidates=candidates, sweeps=sweeps, seams=seams, progress=progress, workers=workers)
    return result


def _walk(result, value, src, matcher, grid, states, targets, full_value, current_value, *, signals, patch,
          candidates, sweeps, seams, progress, workers) -> None:
    """The sweeps of :func:`guided_walk` over the tiles of ``grid`` (ys, xs), updating ``result`` in place.

    The candidates' fixed work of each tile (:meth:`IncrementalAutocorrelation.prepare`: fields
    of the current image, which a change of the previous tile invalidates) runs in a second thread
    while this one builds the tile's candidates; then the candidates are scored."""
    canvas, origins, sources = result.image, result.origins, result.sources
    H, W = canvas.shape[:2]
    ys, xs = grid
    tiles = [(i, j) for i in range(len(ys)) for j in range(len(xs))]
    for _ in range(sweeps):
        changed = 0
        for i, j in progress(tiles, total=len(tiles), desc="guided walk") if progress else tiles:
            y0, x0 = int(ys[i]), int(xs[j])
            ry, rx = q.region_indices(y0, x0, patch, (H, W))
            pending = [_PREPARE.submit(st.prepare, y0, x0, patch, patch, T, workers=workers)
                       for st, T in zip(states, targets, strict=True)] if states and workers > 1 else []
            try:
                pos, keep, news, border = _candidate_blocks(src, canvas, sources, matcher, ys, xs, (i, j),
                                                            patch, candidates, seams)
            finally:
                for job in pending:
                    job.result()
            result.iterations += 1
            result.candidates_evaluated += len(pos)
            if states:
                values, grids = _incremental_values(states, targets, signals, canvas[np.ix_(ry, rx)], news,
                                                    (y0, x0), workers)
            else:
                values = np.empty(len(pos))
                for c in range(len(pos)):
                    trial = canvas.copy()
                    trial[np.ix_(ry, rx)] = news[c]
                    values[c] = full_value(trial)
            best = choose_candidate(values, value, border)
            if values[best] < value - 1e-12 * max(1.0, abs(value)):
                canvas[np.ix_(ry, rx)] = news[best]
                q.paste(sources, q.patch_sources(pos[best][None], patch)[0], keep[best], y0, x0)
                origins[i, j] = pos[best]
                for st, (halves, deltas) in zip(states, grids if states else [], strict=False):
                    # the spectral evaluation (window = the whole torus) keeps no windows: apply computes it
                    dac = None if halves is None else st.window_from_half(halves[best])
                    st.apply(y0, x0, deltas[best], dac=dac)
                value = float(values[best])
                changed += 1
        for st in states:
            st.refresh()
        value = current_value()
        result.history.append(value)
        result.changed += changed
        if changed == 0:
            break


def _candidate_blocks(src, canvas, sources, matcher, ys, xs, tile, patch: int, candidates: int, seams: str):
    """The ``k`` overlap-consistent candidates of tile ``(i, j)`` of the toroidal grid, each cut
    into place: source positions ``(k, 2)``, cut masks ``(k, B, B) bool``, the blocks they give
    ``(k, B, B[, C])`` and their :func:`border_energy` ``(k,)`` (``sources (H, W, 2)``: the
    canvas's per-pixel source map)."""
    H, W = canvas.shape[:2]
    i, j = tile
    ry, rx = q.region_indices(int(ys[i]), int(xs[j]), patch, (H, W))
    region = canvas[np.ix_(ry, rx)]
    overlaps = q.tile_overlaps(ys, xs, i, j, patch, (H, W))
    pos = q.candidates(matcher.costs(region, _band(patch, overlaps)), tol=None, k=candidates)
    patches = q.source_patches(src, pos, patch)
    keep = q.seam_masks(patches, region, np.ones((patch, patch), bool), overlaps=overlaps, method=seams)
    k = keep[..., None] if patches.ndim == 4 else keep
    ring = q.region_indices(int(ys[i]) - 1, int(xs[j]) - 1, patch + 2, (H, W))
    border = border_energy(canvas[np.ix_(*ring)], sources[np.ix_(*ring)], patches, keep, pos)
    return pos, keep, np.where(k, patches, region[None]), border


def _lum(stack: np.ndarray) -> np.ndarray:
    """Luminance ``(K, h, w) float64`` of images ``(K, h, w[, C])`` (seen as one ``(K h, w)`` image)."""
    K, h, w = stack.shape[:3]
    return sy.f_lum(stack.reshape(K * h, w, *stack.shape[3:])).astype(np.float64).reshape(K, h, w)


def border_energy(ring: np.ndarray, ring_sources: np.ndarray, patches: np.ndarray, keep: np.ndarray,
                  positions: np.ndarray) -> np.ndarray:
    """Excess gradient energy ``(K,)`` across the patch borders of each candidate cut into place.

    ``ring (B + 2, B + 2[, C])`` and ``ring_sources (B + 2, B + 2, 2)``: the canvas and its source
    map around the tile (one pixel beyond each side); ``patches (K, B, B[, C])`` the candidates
    at source ``positions (K, 2)``, each kept where ``keep (K, B, B)``. Over every step that
    touches the block and joins pixels that are not source neighbours (a patch border) once the
    candidate is in place, the squared luminance step less the mean squared step inside the
    candidates (the texture's own) is summed: a border the eye cannot tell from the texture costs
    about 0, a visible one its contrast times its length (:func:`_border_energy_kernel`).
    """
    K, B = keep.shape[:2]
    lum_p = _lum(patches)
    grid = np.stack(np.mgrid[-1 : B + 1, -1 : B + 1], axis=2)
    implied = np.ascontiguousarray(ring_sources - grid, dtype=np.int64)  # origin each pixel continues
    return _border_energy_kernel(_lum(ring[None])[0], implied, lum_p, np.ascontiguousarray(keep),
                                 np.ascontiguousarray(positions, dtype=np.int64))


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _border_energy_kernel(ring, implied, lum_p, keep, pos):  # pragma: no cover - compiled
    K, B = keep.shape[0], keep.shape[1]
    inside, n_inside = 0.0, 0
    for k in range(K):
        for y in range(B):
            for x in range(B):
                if x + 1 < B:
                    inside += (lum_p[k, y, x + 1] - lum_p[k, y, x]) ** 2
                    n_inside += 1
                if y + 1 < B:
                    inside += (lum_p[k, y + 1, x] - lum_p[k, y, x]) ** 2
                    n_inside += 1
    inside /= max(n_inside, 1)
    out = np.zeros(K)
    n = B + 2
    new = np.zeros((n, n), dtype=np.bool_)
    val = np.empty((n, n))
    for k in range(K):
        for y in range(n):
            for x in range(n):
                kept = 0 < y <= B and 0 < x <= B and keep[k, y - 1, x - 1]
                new[y, x] = kept or (implied[y, x, 0] == pos[k, 0] and implied[y, x, 1] == pos[k, 1])
                val[y, x] = lum_p[k, y - 1, x - 1] if kept else ring[y, x]
        total = 0.0
        for y in range(n):
            for x in range(n):
                for dy, dx in ((0, 1), (1, 0)):
                    y2, x2 = y + dy, x + dx
                    if y2 >= n or x2 >= n:
                        continue
                    inner1 = 0 < y <= B and 0 < x <= B
                    inner2 = 0 < y2 <= B and 0 < x2 <= B
                    if not (inner1 or inner2):
                        continue
                    if new[y, x] and new[y2, x2]:
                        continue
                    if not new[y, x] and not new[y2, x2]:
                        same = implied[y, x, 0] == implied[y2, x2, 0] and implied[y, x, 1] == implied[y2, x2, 1]
                        if same:
                            continue
                    total += (val[y2, x2] - val[y, x]) ** 2 - inside
        out[k] = total
    return out


SEAM_SHARE = 0.15
"""Share of a tile's best E_L2 gain the walk may give up for a less visible patch border (see
:func:`choose_candidate`; docs/findings/symmetry-texture.md, "Patch edges, third round")."""


def choose_candidate(values: np.ndarray, value: float, border: np.ndarray, share: float | None = None) -> int:
    """Index of the candidate the walk takes: among those whose objective ``values (k,)`` gains at
    least ``1 - share`` of the best gain over the current ``value``, the one with the least
    :func:`border_energy` ``border (k,)``; the best by ``values`` when no candidate gains (the walk
    then keeps the tile; ``share`` defaults to :data:`SEAM_SHARE`; 0: the paper's choice, the best
    by ``values``)."""
    share = SEAM_SHARE if share is None else share
    best = int(np.argmin(values))
    gain = value - float(values[best])
    if gain <= 0 or share <= 0 or border[best] <= 0:
        return best
    near = np.flatnonzero(value - values >= (1.0 - share) * gain)
    return int(near[np.argmin(border[near])])


def _incremental_values(states, targets, signals, region, news, corner, workers: int):
    """E_L2 ``(k,)`` of every candidate block ``news`` replacing ``region`` at ``corner`` (y0, x0),
    summed over the signals, and per signal the halves and signal changes that apply the best."""
    y0, x0 = corner
    patch = region.shape[0]
    values = np.zeros(len(news))
    grids = []
    for st, T, s_name in zip(states, targets, signals, strict=True):
        f_old = sy.signal(region, s_name).astype(np.float64)
        # all candidates' signals at once: the stack seen as one (K B, B[, C]) image
        stacked = sy.signal(news.reshape(len(news) * patch, *news.shape[2:]), s_name)
        deltas = stacked.reshape(len(news), patch, patch).astype(np.float64) - f_old[None]
        vals, halves = st.l2_of_changes(y0, x0, deltas, T, workers=workers)
        values += vals
        grids.append((halves, deltas))
    return values, grids


def seam_visibility(image: np.ndarray, sources: np.ndarray) -> float:
    """Seam visibility of a quilted ``image (H, W[, C])``: the mean squared luminance step across
    patch borders over that inside patches (each direction averaged on its own, then the two).

    Patch borders are the toroidal steps between pixels that do not show neighbouring source
    pixels (``sources (H, W, 2)``, :func:`synthkit.core.tiling.seam_masks`); about 1 when the
    borders cannot be told from the patches' insides, above 1 when edges show."""
    from synthkit.core.tiling import seam_masks
    from synthkit.methods.symtex.tile import seam_ratio

    return seam_ratio(image, seams=seam_masks(sources))


def seam_energy(image: np.ndarray, sources: np.ndarray) -> float:
    """Visible patch border of a quilted ``image (H, W[, C])`` per step of the image: the gradient
    energy across patch borders in excess of what the same steps carry inside patches,
    ``(sum_border d^2 - n_border m) / (n_steps m)`` with ``d`` the luminance step and ``m`` the
    mean squared step inside patches (both directions, toroidal; borders from ``sources (H, W,
    2)`` as in :func:`seam_visibility`).

    Unlike :func:`seam_visibility` (a mean over border steps) it grows with the length of visible
    border: an image cut into many small blocks whose edges show scores high even when most of its
    borders are invisible; 0 when the borders carry no more than the inside (clipped there: borders
    smoother than the texture are not seen either)."""
    from synthkit.core.tiling import seam_masks

    lum = sy.f_lum(np.asarray(image, dtype=np.float32)).astype(np.float64)
    dx = (np.roll(lum, -1, axis=1) - lum) ** 2
    dy = (np.roll(lum, -1, axis=0) - lum) ** 2
    mx, my = seam_masks(sources)
    inside = 0.5 * (dx[~mx].mean() + dy[~my].mean()) if (~mx).any() and (~my).any() else 0.0
    excess = float(dx[mx].sum() + dy[my].sum()) - inside * float(mx.sum() + my.sum())
    return max(excess, 0.0) / max(2 * lum.size * inside, 1e-20)
