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
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field

import numpy as np

from synthkit.core import quilting as q
from synthkit.core import symmetry as sy
from synthkit.core.autocorrelation import IncrementalAutocorrelation, one_blas_thread

_POOLS: dict[int, ThreadPoolExecutor] = {}


def _executor(threads: int) -> ThreadPoolExecutor:
    """The walk's pool of ``threads`` workers, which share the tiles of a batch."""
    if threads not in _POOLS:
        _POOLS[threads] = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="symtex-walk")
    return _POOLS[threads]


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
              patch=patch, candidates=candidates, sweeps=sweeps, seams=seams, progress=progress, workers=workers)
    return result


def _walk(result, value, src, matcher, grid, states, targets, full_value, current_value, *, signals, patch,
          candidates, sweeps, seams, progress, workers) -> None:
    """The sweeps of :func:`guided_walk` over the batches of ``grid`` (ys, xs) (:func:`tile_batches`),
    updating ``result`` in place.

    Every tile of a batch is evaluated against the same image (the spectrum and fields of the
    current image serve the whole batch, computed in this thread while ``workers`` threads build
    and score its tiles); the tiles whose
    best candidate lowers the objective are then accepted together when the exact objective of
    the result is lower (:func:`_accept`)."""
    canvas = result.image
    H, W = canvas.shape[:2]
    ys, xs = grid
    batches = tile_batches(ys, xs, patch, (H, W))
    pool = _executor(workers) if workers > 1 else None

    def evaluate(tile):
        i, j = tile
        y0, x0 = int(ys[i]), int(xs[j])
        pos, keep, news = _candidate_blocks(src, canvas, matcher, ys, xs, (i, j), patch, candidates, seams)
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
        best = int(np.argmin(values))
        return tile, float(values[best]), pos[best], keep[best], news[best], len(pos)

    for _ in range(sweeps):
        changed = 0
        for batch in progress(batches, total=len(batches), desc="guided walk") if progress else batches:
            jobs = [pool.submit(evaluate, t) for t in batch] if pool is not None else []
            for st, T in zip(states, targets, strict=False):  # while the pool builds the candidates
                st.prepare_image(T, (patch, patch))
            found = [job.result() for job in jobs] if jobs else [evaluate(t) for t in batch]
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


def _candidate_blocks(src, canvas, matcher, ys, xs, tile, patch: int, candidates: int, seams: str):
    """The ``k`` overlap-consistent candidates of tile ``(i, j)`` of the toroidal grid, each cut
    into place: source positions ``(k, 2)``, cut masks ``(k, B, B) bool`` and the blocks they
    give ``(k, B, B[, C])``."""
    H, W = canvas.shape[:2]
    i, j = tile
    ry, rx = q.region_indices(int(ys[i]), int(xs[j]), patch, (H, W))
    region = canvas[np.ix_(ry, rx)]
    overlaps = q.tile_overlaps(ys, xs, i, j, patch, (H, W))
    pos = q.candidates(matcher.costs(region, _band(patch, overlaps)), tol=None, k=candidates)
    patches = q.source_patches(src, pos, patch)
    keep = q.seam_masks(patches, region, np.ones((patch, patch), bool), overlaps=overlaps, method=seams)
    k = keep[..., None] if patches.ndim == 4 else keep
    return pos, keep, np.where(k, patches, region[None])


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
