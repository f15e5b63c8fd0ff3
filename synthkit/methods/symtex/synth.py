"""Symmetry-guided image quilting (theta_synth, paper Sec. 4 Example 1).

The output is a toroidal grid of tiles (see :mod:`synthkit.core.quilting`). It starts from random
patches (or from unguided quilting); then the walk visits every tile, row of tiles after row,
sweep after sweep. At a tile, the ``k`` source patches with the lowest overlap error against the
four neighbouring bands are the overlap-consistent candidates; each is cut into place with
minimum-error boundary cuts, and the tile takes the candidate whose result has the translational
symmetry representation closest (E_L2) to the target, or keeps its current content when no
candidate is closer (so the objective never rises: a steepest-descent walk). The tiles of a row
are visited in batches whose blocks do not meet (every other tile, :func:`tile_batches`): each
tile of a batch is scored against the same image, and the batch's improving tiles are accepted
together when the exact objective of the result is lower, else one by one (:func:`_accept`).
Among the candidates of a tile that gain at least 85% of the best one's (:data:`SEAM_SHARE`), it
proposes the one whose patch border shows least (:func:`choose_candidate`, :func:`border_energy`).

Candidates are evaluated incrementally: the change of the windowed autocorrelation caused by
replacing one block is computed from the block and its surroundings only
(:class:`synthkit.core.autocorrelation.IncrementalAutocorrelation`), batched over all candidates of the
tile (the tiles of a batch shared by two threads), and E_L2 of the standardized result follows from four
sums of that change over the window, exactly (the same values as a full recompute, up to
rounding). With every displacement in the window (``symmetry.window: 0.5``, the default) those
sums come from fields of the current image computed once per batch and one small FFT per
candidate, with no full-size transform per candidate. ``evaluation="full"`` recomputes S_T of
the whole image for every candidate instead (the paper's way; for benchmarks and as the
reference in tests).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field

import numba
import numpy as np

from synthkit.core import quilting as q
from synthkit.core import symmetry as sy
from synthkit.core.autocorrelation import IncrementalAutocorrelation
from synthkit.core.numba_cache import NUMBA_CACHE
from synthkit.core.threads import one_blas_thread, thread_pool


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
    seam_share: float | None = None,
    polish_sweeps: int = 0,
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
    seam_share : share of a tile's best gain the walk may give up for a quieter patch border
        (:func:`choose_candidate`; default :data:`SEAM_SHARE`, 0: the paper's choice).
    polish_sweeps : passes after ``sweeps`` in which a tile takes, among the candidates that lower
        the objective at all, the one whose border shows least (``seam_share`` 1).
    progress : optional wrapper ``progress(iterable, total=, desc=)`` for a progress bar.
    workers : threads sharing the tiles of a batch (default ``min(2, os.cpu_count())``); each
        tile is built and scored in one thread, so the result is the same for any ``workers``.
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
            return float(sum(st.value(T, (patch, patch)) for st, T in zip(states, targets, strict=True)))
        return full_value(canvas)

    result = WalkResult(canvas, origins, sources)
    value = current_value()
    result.history.append(value)
    matcher = q.PatchMatcher(src, patch)
    with one_blas_thread() if states else nullcontext():
        _walk(result, value, src, matcher, (ys, xs), states, targets, full_value, current_value, signals=signals,
              patch=patch, candidates=candidates, seams=seams, progress=progress, workers=workers,
              shares=[seam_share] * sweeps + [1.0] * polish_sweeps)
    return result


def _walk(result, value, src, matcher, grid, states, targets, full_value, current_value, *, signals, patch,
          candidates, seams, progress, workers, shares) -> None:
    """The sweeps of :func:`guided_walk` over the batches of ``grid`` (ys, xs) (:func:`tile_batches`),
    updating ``result`` in place.

    Every tile of a batch is evaluated against the same image (the spectrum and fields of the
    current image serve the whole batch, computed in this thread while ``workers`` threads build
    and score its tiles); the tiles whose chosen candidate lowers the objective are then accepted
    together when the exact objective of the result is lower (:func:`_accept`). ``shares``: per
    sweep, the share of :func:`choose_candidate`."""
    canvas = result.image
    H, W = canvas.shape[:2]
    ys, xs = grid
    batches = tile_batches(ys, xs, patch, (H, W))
    pool = thread_pool("symtex-walk", workers) if workers > 1 else None

    def evaluate(tile, value, share):
        i, j = tile
        y0, x0 = int(ys[i]), int(xs[j])
        pos, keep, news, border = _candidate_blocks(src, canvas, result.sources, matcher, ys, xs, (i, j), patch,
                                                    candidates, seams)
        if states:
            ry, rx = q.region_indices(y0, x0, patch, (H, W))
            values = _incremental_values(states, targets, signals, canvas[np.ix_(ry, rx)], news, (y0, x0))
        else:
            ry, rx = q.region_indices(y0, x0, patch, (H, W))
            values = np.empty(len(pos))
            for c in range(len(pos)):
                trial = canvas.copy()
                trial[np.ix_(ry, rx)] = news[c]
                values[c] = full_value(trial)
        best = choose_candidate(values, value, border, share)
        return tile, float(values[best]), pos[best], keep[best], news[best], len(pos)

    for share in shares:
        changed = 0
        for batch in progress(batches, total=len(batches), desc="guided walk") if progress else batches:
            jobs = [pool.submit(evaluate, t, value, share) for t in batch] if pool is not None else []
            for st, T in zip(states, targets, strict=False):  # while the pool builds the candidates
                st.prepare_image(T, (patch, patch))
            found = [job.result() for job in jobs] if jobs else [evaluate(t, value, share) for t in batch]
            result.iterations += len(batch)
            result.candidates_evaluated += sum(f[-1] for f in found)
            value, n = _accept(result, found, value, states, signals, current_value, grid, patch)
            changed += n
        value = current_value()
        result.history.append(value)
        result.changed += changed
        if changed == 0:
            break


def _accept(result, found, value, states, signals, current_value, grid, patch) -> tuple[float, int]:
    """Accept the proposals ``found`` (per tile: ``(tile, predicted value, position, cut mask, block,
    number of candidates)``, each evaluated alone against the current image) whose predicted value
    is below ``value``: all together when the exact objective of the result is lower; otherwise one
    by one in order of predicted value, each kept only when the exact objective falls. The
    objective never rises. Returns the new value and the number of tiles changed."""
    tol = 1e-12 * max(1.0, abs(value))
    better = sorted((f for f in found if f[1] < value - tol), key=lambda f: f[1])
    if not better:
        return value, 0
    before = [_place(result, states, signals, f, grid, patch) for f in better]
    trial = current_value()
    if trial < value - tol:
        return trial, len(better)
    for f, old in zip(better[::-1], before[::-1], strict=True):
        _restore(result, states, signals, f[0], old, grid, patch)
    n = 0
    for f in better:
        old = _place(result, states, signals, f, grid, patch)
        trial = current_value()
        if trial < value - tol:
            value, n = trial, n + 1
        else:
            _restore(result, states, signals, f[0], old, grid, patch)
    return value, n


def _place(result, states, signals, proposal, grid, patch):
    """Put a proposal's block into ``result`` and ``states``; returns what it replaced."""
    (i, j), _, pos, keep, block = proposal[:5]
    ys, xs = grid
    canvas, sources = result.image, result.sources
    y0, x0 = int(ys[i]), int(xs[j])
    ry, rx = q.region_indices(y0, x0, patch, canvas.shape[:2])
    old = (canvas[np.ix_(ry, rx)].copy(), sources[np.ix_(ry, rx)].copy(), result.origins[i, j].copy())
    canvas[np.ix_(ry, rx)] = block
    q.paste(sources, q.patch_sources(pos[None], patch)[0], keep, y0, x0)
    result.origins[i, j] = pos
    for st, name in zip(states, signals, strict=False):
        st.assign(y0, x0, sy.signal(block, name))
    return old


def _restore(result, states, signals, tile, old, grid, patch) -> None:
    """Undo :func:`_place` of tile ``(i, j)`` with what it returned."""
    i, j = tile
    ys, xs = grid
    y0, x0 = int(ys[i]), int(xs[j])
    ry, rx = q.region_indices(y0, x0, patch, result.image.shape[:2])
    result.image[np.ix_(ry, rx)], result.sources[np.ix_(ry, rx)], result.origins[i, j] = old
    for st, name in zip(states, signals, strict=False):
        st.assign(y0, x0, sy.signal(old[0], name))


BATCH_SHARE = 1 / 16
"""The largest share of the image the blocks of one batch cover (:func:`tile_batches`). The tiles
of a batch are scored against the same image, each blind to the others' changes; measured on the
transfer benchmark's pair (noise source, dot lattice target), batches covering 4.7% (256^2) and
5% (512^2) of the image end on average over seeds within a few percent of the E_L2 of the
tile-by-tile walk, 9.4% (256^2) 5-10% above it (docs/findings/symmetry-texture.md, "Speed,
third round")."""


def tile_batches(ys: np.ndarray, xs: np.ndarray, patch: int, shape: tuple[int, int]) -> list[list[tuple[int, int]]]:
    """The guided walk's batches: per row of tiles (in order), its tiles ``(i, j)`` in as few
    groups as the first fit gives whose blocks (``patch`` wide, toroidal in ``shape``) do not meet
    (every other tile), each group cut into equal runs covering at most :data:`BATCH_SHARE` of the
    image. A tile's candidates depend on its block only, so those of one batch can be built and
    scored against the same image."""
    H, W = shape
    most = max(1, int(BATCH_SHARE * H * W) // (patch * patch))
    batches = []
    for i in range(len(ys)):
        groups: list[list[int]] = []
        for j in range(len(xs)):
            for g in groups:
                if all(min((xs[j] - xs[k]) % W, (xs[k] - xs[j]) % W) >= patch for k in g):
                    g.append(j)
                    break
            else:
                groups.append([j])
        for g in groups:
            runs = -(-len(g) // most)
            bounds = [round(r * len(g) / runs) for r in range(runs + 1)]
            batches.extend([(i, j) for j in g[lo:hi]] for lo, hi in zip(bounds[:-1], bounds[1:], strict=True))
    return batches


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


def _incremental_values(states, targets, signals, region, news, corner) -> np.ndarray:
    """E_L2 ``(k,)`` of every candidate block ``news`` replacing ``region`` at ``corner`` (y0, x0),
    summed over the signals (one thread: the walk's threads share the tiles of a batch)."""
    y0, x0 = corner
    patch = region.shape[0]
    values = np.zeros(len(news))
    for st, T, s_name in zip(states, targets, signals, strict=True):
        f_old = sy.signal(region, s_name).astype(np.float64)
        # all candidates' signals at once: the stack seen as one (K B, B[, C]) image
        stacked = sy.signal(news.reshape(len(news) * patch, *news.shape[2:]), s_name)
        deltas = stacked.reshape(len(news), patch, patch).astype(np.float64) - f_old[None]
        values += st.l2_of_changes(y0, x0, deltas, T, workers=1)[0]
    return values


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
