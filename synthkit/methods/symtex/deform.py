"""ARAP image deformation guided by a symmetry objective (theta_deform, paper Sec. 4 Example 2).

Control points: up to ``N`` Harris corners of the luminance, spaced at least ``d = sqrt(H W / N) / 2``
apart, then filled up to ``N`` by dart throwing (uniform darts from the run's generator, rejected
when closer than ``d``); the four image corners and border points every ``2 d`` are added as mesh
vertices so the Delaunay mesh covers the image. The warp is a backward map (each rest vertex
samples the input at ``U_i``; see :class:`synthkit.core.warp.MeshSampler`), kept as rigid as
possible by :class:`synthkit.core.warp.ARAP2D` with the control points as handles.

Hierarchy: control points ordered by farthest-point sampling; level ``l`` of ``L`` uses the first
``N / 2^(L-1-l)`` of them (at least 4). At each level, starting at step ``s`` (5 px at the coarsest,
halved per finer level), every handle in turn estimates the gradient of the loss by central
differences of size ``step`` and moves ``step`` along it when that lowers the loss; cycles repeat
until none moves (or ``max_cycles``), then the step halves until it falls below ``min_step``.

The tile candidates of mode ``tile`` are in :mod:`.tile`. What real photographs showed of this
objective (issue 14): docs/findings/symmetry-texture.md.
"""

from __future__ import annotations

import contextlib
import logging
import os
from dataclasses import dataclass

import cv2
import numpy as np

from synthkit.core import symmetry as sy
from synthkit.core.threads import thread_pool
from synthkit.core.warp import ARAP2D, MeshSampler, displacement_gradient, triangle_stretch
from synthkit.methods.symtex.options import DeformOptions, TileOptions
from synthkit.methods.symtex.tile import SHARPNESS_MIN, high_frequency_energy, tile_crop

PROBE_THREADS = min(2, os.cpu_count() or 1)
"""Threads shared by every optimizer's gradient probes (one on a one-core machine)."""

log = logging.getLogger("synthkit")


def control_points(img: np.ndarray, n: int, rng) -> np.ndarray:
    """Control points ``(k, 2)`` as (x, y): Harris corners then dart throwing, up to ``n``.

    Dart throwing stops after ``30 n`` darts; when the image is too small for ``n`` points spaced
    ``d`` apart, fewer are returned and a warning is logged (the pipeline records the count in
    ``metrics.control_points``).
    """
    lum = sy.f_lum(np.asarray(img, dtype=np.float32))
    H, W = lum.shape
    d = max(2.0, np.sqrt(H * W / n) / 2.0)
    corners = cv2.goodFeaturesToTrack(
        lum, maxCorners=n, qualityLevel=0.01, minDistance=d, useHarrisDetector=True, k=0.04
    )
    pts = [] if corners is None else [tuple(p) for p in corners.reshape(-1, 2).astype(np.float64)]
    pts = [p for p in pts if d <= p[0] <= W - 1 - d and d <= p[1] <= H - 1 - d]
    arr = np.array(pts, dtype=np.float64).reshape(-1, 2)
    attempts = 0
    while len(arr) < n and attempts < 30 * n:
        attempts += 1
        p = np.array([rng.uniform(d, W - 1 - d), rng.uniform(d, H - 1 - d)])
        if len(arr) == 0 or np.min(np.hypot(*(arr - p).T)) >= d:
            arr = np.vstack([arr, p])
    if len(arr) < n:
        log.warning(
            "only %d of %d control points fit a %dx%d image at spacing %.1f px after %d darts (deform.points)",
            len(arr),
            n,
            H,
            W,
            d,
            attempts,
        )
    return arr


def border_points(shape, spacing: float) -> np.ndarray:
    """Image corners and border points ``(k, 2)`` (x, y) about ``spacing`` apart."""
    H, W = shape
    xs = np.linspace(0, W - 1, max(2, int(round((W - 1) / spacing)) + 1))
    ys = np.linspace(0, H - 1, max(2, int(round((H - 1) / spacing)) + 1))
    pts = [(x, 0.0) for x in xs] + [(x, H - 1.0) for x in xs]
    pts += [(0.0, y) for y in ys[1:-1]] + [(W - 1.0, y) for y in ys[1:-1]]
    return np.array(pts, dtype=np.float64)


def farthest_order(P: np.ndarray) -> np.ndarray:
    """Farthest-point ordering ``(k,)`` of points ``P (k, 2)``, starting at the one nearest their mean."""
    order = [int(np.argmin(np.hypot(*(P - P.mean(axis=0)).T)))]
    dist = np.hypot(*(P - P[order[0]]).T)
    for _ in range(len(P) - 1):
        nxt = int(np.argmax(dist))
        order.append(nxt)
        dist = np.minimum(dist, np.hypot(*(P - P[nxt]).T))
    return np.array(order, dtype=np.int64)


class DeformOptimizer:
    """Coarse-to-fine per-handle descent of ``loss(warped image)`` over ARAP warps.

    ``loss`` maps an image ``(H, W[, C])`` to a float to minimize. ``U0 (n, 2)`` is the starting
    backward map (identity or the tile zoom) and the shape the warp is kept as rigid as possible
    against, so the zoom itself costs nothing: with the handles where ``U0`` puts them, the ARAP
    solve returns ``U0``. Each level starts from the ARAP solve of its own handles at their current
    positions (the state its probes perturb). Evaluations are counted in ``evaluations``.

    ``out_shape`` is the rendered image's ``(H, W)`` (default ``img``'s): a tile smaller than the
    input is read from inside it. A move is taken only when it lowers the loss by more than
    ``min_gain`` times its magnitude (a relative threshold: moves that buy a gain within the
    evaluation noise only add warp), and, with ``max_stretch``, only when no triangle of the warp
    is stretched by more than that against ``U0`` (:func:`synthkit.core.warp.triangle_stretch`);
    ``rejected_stretch`` counts the moves that bound refused. ``accept(U) -> bool``, when given, is
    a further condition on every move (mode ``tile``: the Lanczos render keeps
    ``SHARPNESS_MIN`` of the input's high-frequency energy); ``rejected_accept`` counts its
    refusals. With ``max_gradient``, a move is also refused when the displacement from ``U0`` has
    a larger gradient on some triangle (:func:`synthkit.core.warp.displacement_gradient`: pattern
    elements stay in their rows); ``rejected_gradient`` counts those refusals.
    """

    def __init__(
        self,
        img,
        loss,
        *,
        rest,
        U0,
        n_control,
        levels,
        step,
        min_step,
        max_cycles,
        max_evaluations,
        border="reflect",
        progress=None,
        out_shape=None,
        max_stretch=None,
        min_gain=0.0,
        accept=None,
        max_gradient=None,
    ):
        self.img = np.asarray(img, dtype=np.float32)
        self.loss = loss
        self.sampler = MeshSampler(rest, self.img.shape[:2] if out_shape is None else tuple(out_shape))
        self.F = self.sampler.F
        self.rest = rest
        self.U0 = np.asarray(U0, dtype=np.float64).copy()
        self.U = self.U0.copy()
        self.n_control = n_control
        self.levels, self.step, self.min_step = levels, step, min_step
        self.max_cycles, self.max_evaluations = max_cycles, max_evaluations
        self.border = border
        self.progress = progress
        self.max_stretch = max_stretch
        self.min_gain = float(min_gain)
        self.rejected_stretch = 0
        self.accept = accept
        self.rejected_accept = 0
        self.max_gradient = max_gradient
        self.rejected_gradient = 0
        self.evaluations = 0
        self.history: list[float] = []

    def _allowed(self, U) -> bool:
        if self.max_stretch is not None and self.stretch(U) > self.max_stretch:
            self.rejected_stretch += 1
            return False
        if self.max_gradient is not None and self.gradient(U) > self.max_gradient:
            self.rejected_gradient += 1
            return False
        if self.accept is not None and not self.accept(U):
            self.rejected_accept += 1
            return False
        return True

    def gradient(self, U=None) -> float:
        """Largest displacement gradient of ``U`` (default the current warp) from ``U0``."""
        return float(displacement_gradient(self.rest, self.U0, self.U if U is None else U, self.F).max())

    def stretch(self, U=None) -> float:
        """Largest triangle stretch of ``U`` (default the current warp) against ``U0``."""
        return float(triangle_stretch(self.U0, self.U if U is None else U, self.F).max())

    def render(self, U=None) -> np.ndarray:
        return self.sampler.warp(self.img, self.U if U is None else U, border=self.border)

    def _eval(self, solver, H):
        self.evaluations += 1
        U = solver.solve(H)
        return self.loss(self.render(U)), U

    def _gradient(self, solver, Hpos: np.ndarray, h: int, step: float) -> np.ndarray:
        """Central-difference gradient ``(2,)`` of the loss in handle ``h``'s position: its four
        probes (``+-step`` along x and y) are independent and run on two threads (the FFTs, the
        resampling and the compiled loops release the GIL); the values do not depend on it."""
        trials = []
        for axis in range(2):
            for sgn in (1.0, -1.0):
                trial = Hpos.copy()
                trial[h, axis] += sgn * step
                trials.append(trial)
        pool = thread_pool("symtex-probes", PROBE_THREADS)
        vals = list(pool.map(lambda t: self.loss(self.render(solver.solve(t))), trials))
        self.evaluations += len(trials)
        return np.array([vals[0] - vals[1], vals[2] - vals[3]]) / (2 * step)

    def run(self) -> np.ndarray:
        order = farthest_order(self.rest[: self.n_control])
        current = self.loss(self.render())
        self.history.append(current)
        budget_left = lambda: self.evaluations < self.max_evaluations  # noqa: E731
        for level in range(self.levels):
            k = max(4, self.n_control // 2 ** (self.levels - 1 - level))
            handles = order[: min(k, self.n_control)]
            solver = ARAP2D(self.U0, self.F, handles)
            Hpos = self.U[handles].copy()
            if level > 0:
                # the finer level's parametrization: its handles where the coarser level left them
                val, U = self._eval(solver, Hpos)
                if self._allowed(U):
                    current, self.U = val, U
                # else keep the coarser warp: the finer solve of the same handles breaks a bound
                self.history.append(current)
            step = self.step / 2**level
            while step >= self.min_step and budget_left():
                for _ in range(self.max_cycles):
                    moved = 0
                    it = range(len(handles))
                    if self.progress is not None:
                        it = self.progress(it, total=len(handles), desc=f"ARAP level {level} step {step:g}")
                    for h in it:
                        if not budget_left():
                            break
                        grad = self._gradient(solver, Hpos, h, step)
                        g = np.hypot(*grad)
                        if g <= 0:
                            continue
                        trial = Hpos.copy()
                        trial[h] -= step * grad / g
                        val, U = self._eval(solver, trial)
                        if val < current - self.min_gain * abs(current):
                            if not self._allowed(U):
                                continue
                            current, Hpos, self.U = val, trial, U
                            moved += 1
                    self.history.append(current)
                    if moved == 0 or not budget_left():
                        break
                step /= 2.0
        return self.render()


@dataclass
class Warp:
    """What :func:`warp_image` gives: the rendered ``image (h, w, C)``, its backward map
    ``sample_map (h, w, 2) float32`` (x, y) and that of the start ``start_map``, the figures
    ``metrics`` and the sharpness reference ``hf_view`` of a tile (else None)."""

    image: np.ndarray
    sample_map: np.ndarray
    start_map: np.ndarray
    metrics: dict
    hf_view: float | None = None


def warp_mesh(view: np.ndarray, src_shape, out_shape, offset: np.ndarray, points: int, rng,
              zoom_margin: float | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """The rest vertices ``(n, 2)`` (control points of ``view`` then border points), the start
    backward map ``U0 (n, 2)`` (shifted by ``offset`` (x, y), or zoomed toward the centre of
    an input of ``src_shape`` by ``1 - 2 zoom_margin``) and the number of control points."""
    h, w = out_shape
    ctrl = control_points(view, points, rng)
    spacing = max(4.0, np.sqrt(h * w / points))
    rest = np.vstack([ctrl, border_points(out_shape, spacing)])
    U0 = rest + offset
    if zoom_margin is not None:
        H, W = src_shape[:2]
        c = np.array([(W - 1) / 2.0, (H - 1) / 2.0])
        U0 = c + (rest - c) * (1.0 - 2.0 * zoom_margin)
    return rest, U0, len(ctrl)


def warp_image(src: np.ndarray, objective, opts: DeformOptions, *, rng, tile: TileOptions | None = None,
               progress=None, stage=None) -> Warp:
    """Optimize ``objective`` over ARAP warps of ``src (H, W, C)`` (:class:`DeformOptimizer`).

    With ``tile`` (mode tile), the warp renders the tile: a native-resolution crop of the centre
    (``zoom: crop``, :func:`~synthkit.methods.symtex.tile.tile_crop`) or the centre zoomed to the
    input's size (``upsample``), and every move must keep ``SHARPNESS_MIN`` of the high
    frequencies. ``rng`` places the control points; ``stage(name)`` times a step (a context
    manager), ``progress`` wraps the handle loops. ``ValueError`` for a ``tile.margin`` that
    leaves no tile.
    """
    stage = stage or (lambda name: contextlib.nullcontext())
    out_shape, offset = src.shape[:2], np.zeros(2)
    crop = tile is not None and tile.zoom == "crop"
    if crop:
        out_shape, (oy, ox) = tile_crop(src.shape, tile.margin)
        offset = np.array([ox, oy], dtype=np.float64)
    h, w = out_shape
    with stage("mesh"):
        view = src[int(offset[1]) : int(offset[1]) + h, int(offset[0]) : int(offset[0]) + w]
        zoom = tile.margin if tile is not None and not crop else None
        rest, U0, n_ctrl = warp_mesh(view, src.shape, out_shape, offset, opts.points, rng, zoom)
    # f_lum and f_1-lum are linear in the colour channels and bilinear sampling commutes with
    # them, so the optimizer may warp the one-channel luminance instead of the colour image
    pointwise = set(objective.signals) <= {"lum", "1-lum"}
    opt = DeformOptimizer(
        sy.f_lum(src) if pointwise else src, objective.loss, rest=rest, U0=U0, n_control=n_ctrl,
        levels=opts.levels, step=opts.step, min_step=opts.min_step, max_cycles=opts.max_cycles,
        max_evaluations=opts.max_evaluations, progress=progress, out_shape=out_shape,
        max_stretch=opts.max_stretch, min_gain=opts.min_gain, max_gradient=opts.max_gradient,
    )
    interp = opts.interpolation
    start_img = opt.sampler.warp(src, U0, interpolation=interp)
    hf_view = None
    if tile is not None:
        # sharpness reference of the optimized tile: the part of the input it is cut from (the
        # whole input when upsampled); upsampled, moves may not lose more than 10 % of what the
        # zoomed start has (such a tile is never returned: see choose_tile)
        hf_view = high_frequency_energy(view if crop else src)
        lum = sy.f_lum(src)
        floor = SHARPNESS_MIN * (hf_view if crop else high_frequency_energy(start_img))
        opt.accept = lambda U: high_frequency_energy(opt.sampler.warp(lum, U, interpolation=interp)) >= floor
    with stage("optimize"):
        opt.run()
        image = opt.sampler.warp(src, opt.U, interpolation=interp)
    maps = [np.stack(opt.sampler.coords(U), axis=2) for U in (opt.U, U0)]
    metrics = _warp_metrics(opt, objective, src, start_img, image, maps, opts.points, n_ctrl)
    return Warp(image, maps[0].astype(np.float32), maps[1].astype(np.float32), metrics, hf_view)


def _warp_metrics(opt: DeformOptimizer, objective, src, start_img, image, maps, requested: int, n_ctrl: int) -> dict:
    """The figures of an optimized warp (``maps``: the backward maps of the result and the start)."""
    moved = np.hypot(*(maps[0] - maps[1]).transpose(2, 0, 1))
    return {
        "objective": "E_L2" if objective.kind == "l2" else "E_symm",
        "objective_start": objective.value(start_img),
        "objective_end": objective.value(image),
        "baseline_objective": objective.value(src),
        "iterations": opt.evaluations,
        "control_points": n_ctrl,
        "control_points_requested": requested,
        "objective_history": [abs(v) for v in opt.history],
        "mean_displacement": float(moved.mean()),
        "max_displacement": float(moved.max()),
        "max_stretch": opt.stretch(),
        "max_stretch_bound": opt.max_stretch,
        "moves_rejected_by_stretch": opt.rejected_stretch,
        "moves_rejected_by_sharpness": opt.rejected_accept,
        "moves_rejected_by_gradient": opt.rejected_gradient,
        "max_displacement_gradient": opt.gradient(),
        "symmetry_crop": None if objective.crop is None else list(objective.crop),
        "min_gain": opt.min_gain,
    }


def symmetrize_refusal(metrics: dict, max_gradient: float | None) -> str | None:
    """Why mode ``symmetrize`` returns the input instead of the deformed image, or None (issue 24).

    The deformed image is kept only when its E_symm (``metrics.objective_end``, the rendered
    colour result) is above the input's (``baseline_objective``) by more than ``min_gain`` of it
    (the share each move must buy) and, with ``max_gradient``, its displacement's gradient
    (``max_displacement_gradient``) is within it. The optimizer refuses moves that break either,
    but its probes are bilinear renders of the luminance, while the result is a Lanczos render of
    the colour image: E_symm of the two differ by about a percent (the unwarped grid lattice-p4:
    the probes +3%, the result -1.2%).
    """
    end, start = metrics["objective_end"], metrics["baseline_objective"]
    floor = start * (1.0 + metrics["min_gain"])
    if not end > floor:
        gain = (end / start - 1.0) * 100.0 if start > 0 else 0.0
        return (
            f"E_symm {end:.4g} of the deformed image is {gain:+.2f}% of the input's {start:.4g}, "
            f"not above it by deform.min_gain {metrics['min_gain']:g}"
        )
    grad = metrics["max_displacement_gradient"]
    if max_gradient is not None and grad > max_gradient:
        return f"the displacement's gradient {grad:.3g} exceeds deform.max_gradient {max_gradient:g}"
    return None
