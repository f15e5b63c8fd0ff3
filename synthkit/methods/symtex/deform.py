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

Tiling (mode ``tile``): the warp starts zoomed on the centre, leaving ``margin`` of each side that
the deformation may pull in; after optimizing E_symm of the toroidal S_T, the mismatch between
opposite borders is removed by mean-value-coordinate interpolation of the boundary correction.
"""

from __future__ import annotations

import cv2
import numpy as np

from synthkit.core import symmetry as sy
from synthkit.core.warp import ARAP2D, MeshSampler, mean_value_coordinates
from synthkit.io.images import save_image
from synthkit.preview import montage_png


def control_points(img: np.ndarray, n: int, rng) -> np.ndarray:
    """Control points ``(k, 2)`` as (x, y): Harris corners then dart throwing, up to ``n``."""
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
    backward map (identity or the tile zoom). Evaluations are counted in ``evaluations``.
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
    ):
        self.img = np.asarray(img, dtype=np.float32)
        self.loss = loss
        self.sampler = MeshSampler(rest, self.img.shape[:2])
        self.F = self.sampler.F
        self.rest = rest
        self.U = np.asarray(U0, dtype=np.float64).copy()
        self.n_control = n_control
        self.levels, self.step, self.min_step = levels, step, min_step
        self.max_cycles, self.max_evaluations = max_cycles, max_evaluations
        self.border = border
        self.progress = progress
        self.evaluations = 0
        self.history: list[float] = []

    def render(self, U=None) -> np.ndarray:
        return self.sampler.warp(self.img, self.U if U is None else U, border=self.border)

    def _eval(self, solver, handles, H):
        self.evaluations += 1
        U = solver.solve(H)
        return self.loss(self.render(U)), U

    def run(self) -> np.ndarray:
        order = farthest_order(self.rest[: self.n_control])
        current = self.loss(self.render())
        self.history.append(current)
        budget_left = lambda: self.evaluations < self.max_evaluations  # noqa: E731
        for level in range(self.levels):
            k = max(4, self.n_control // 2 ** (self.levels - 1 - level))
            handles = order[: min(k, self.n_control)]
            solver = ARAP2D(self.rest, self.F, handles)
            Hpos = self.U[handles].copy()
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
                        grad = np.zeros(2)
                        for axis in range(2):
                            vals = []
                            for sgn in (1.0, -1.0):
                                trial = Hpos.copy()
                                trial[h, axis] += sgn * step
                                vals.append(self._eval(solver, handles, trial)[0])
                            grad[axis] = (vals[0] - vals[1]) / (2 * step)
                        g = np.hypot(*grad)
                        if g <= 0:
                            continue
                        trial = Hpos.copy()
                        trial[h] -= step * grad / g
                        val, U = self._eval(solver, handles, trial)
                        if val < current:
                            current, Hpos, self.U = val, trial, U
                            moved += 1
                    self.history.append(current)
                    if moved == 0 or not budget_left():
                        break
                step /= 2.0
        return self.render()


def toroidal_blend(img: np.ndarray, *, spacing: int = 4) -> np.ndarray:
    """Make ``img (H, W[, C])`` seamless across its toroidal boundary by MVC interpolation.

    Each border pixel's target is the mean of itself and the pixel facing it across the wrap
    (left with right column, top with bottom row; corners take the mean of all four). The
    correction (target - value) on the border polygon (sampled every ``spacing`` pixels) is spread
    into the interior with mean value coordinates and added, so opposite borders then agree.
    """
    out = np.asarray(img, dtype=np.float64).copy()
    H, W = out.shape[:2]
    target = out.copy()
    target[:, 0] = target[:, -1] = 0.5 * (out[:, 0] + out[:, -1])
    target[0, :] = target[-1, :] = 0.5 * (target[0, :] + target[-1, :])
    corr = target - out
    # border polygon (x, y) in order around the rectangle
    xs = np.arange(0, W - 1, spacing)
    ys = np.arange(0, H - 1, spacing)
    poly = np.concatenate(
        [
            np.stack([xs, np.zeros_like(xs)], 1),
            np.stack([np.full_like(ys, W - 1), ys], 1),
            np.stack([W - 1 - xs, np.full_like(xs, H - 1)], 1),
            np.stack([np.zeros_like(ys), H - 1 - ys], 1),
        ]
    ).astype(np.int64)
    vals = corr[poly[:, 1], poly[:, 0]]
    yy, xx = np.mgrid[1 : H - 1, 1 : W - 1]
    pts = np.stack([xx.ravel(), yy.ravel()], 1).astype(np.float64)
    interior = np.empty((len(pts),) + out.shape[2:])
    for s in range(0, len(pts), 4096):
        w = mean_value_coordinates(pts[s : s + 4096], poly.astype(np.float64))
        interior[s : s + 4096] = w @ vals.reshape(len(poly), -1) if out.ndim == 3 else w @ vals
    out[1 : H - 1, 1 : W - 1] += interior.reshape((H - 2, W - 2) + out.shape[2:])
    out[0, :], out[-1, :] = target[0, :], target[-1, :]
    out[:, 0], out[:, -1] = target[:, 0], target[:, -1]
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def seam_ratio(img: np.ndarray) -> float:
    """Mean squared luminance step across the toroidal seams over the mean interior step."""
    lum = sy.f_lum(np.asarray(img, dtype=np.float32)).astype(np.float64)
    dx = np.diff(lum, axis=1) ** 2
    dy = np.diff(lum, axis=0) ** 2
    interior = 0.5 * (dx.mean() + dy.mean())
    seam = 0.5 * (((lum[:, 0] - lum[:, -1]) ** 2).mean() + ((lum[0, :] - lum[-1, :]) ** 2).mean())
    return float(seam / max(interior, 1e-12))


def run_deform(cfg, ctx, src, tgt, *, targets_fn, objective_fn) -> None:
    """Run ``perturbation: deform`` for transfer / filter / symmetrize / tile."""
    dc = cfg.deform
    shape = src.shape[:2]
    H, W = shape
    with ctx.stage("target"):
        targets = targets_fn(cfg, src, tgt, shape)
        objective = objective_fn(cfg, shape, targets)
    with ctx.stage("mesh"):
        ctrl = control_points(src, dc.points, ctx.rng)
        spacing = max(4.0, np.sqrt(H * W / dc.points))
        rest = np.vstack([ctrl, border_points(shape, spacing)])
        U0 = rest.copy()
        if cfg.mode == "tile":
            m = cfg.tile.margin
            c = np.array([(W - 1) / 2.0, (H - 1) / 2.0])
            U0 = c + (rest - c) * (1.0 - 2.0 * m)
    # f_lum and f_1-lum are linear in the colour channels and bilinear sampling commutes with
    # them, so the optimizer may warp the one-channel luminance instead of the colour image
    pointwise = set(cfg.symmetry.signals) <= {"lum", "1-lum"}
    opt = DeformOptimizer(
        sy.f_lum(src) if pointwise else src,
        objective.loss,
        rest=rest,
        U0=U0,
        n_control=len(ctrl),
        levels=dc.levels,
        step=dc.step,
        min_step=dc.min_step,
        max_cycles=dc.max_cycles,
        max_evaluations=dc.max_evaluations,
        progress=ctx.progress,
    )
    start_img = opt.sampler.warp(src, U0)
    with ctx.stage("optimize"):
        opt.run()
        image = opt.sampler.warp(src, opt.U)
    start = objective.value(start_img)
    end = objective.value(image)
    metrics = {
        "objective": "E_L2" if objective.kind == "l2" else "E_symm",
        "objective_start": start,
        "objective_end": end,
        "baseline_objective": objective.value(src),
        "iterations": opt.evaluations,
        "control_points": len(ctrl),
        "objective_history": [abs(v) for v in opt.history],
    }
    if cfg.mode == "tile":
        with ctx.stage("blend"):
            image = toroidal_blend(image, spacing=cfg.tile.mvc_spacing)
        metrics.update(
            objective_end=objective.value(image),
            seam_ratio=seam_ratio(image),
            seam_ratio_input=seam_ratio(src),
        )
    ctx.metrics.update(metrics)
    with ctx.stage("write"):
        from synthkit.methods.symtex.pipeline import _write_common

        _write_common(cfg, ctx, src, image, objective, targets)
        if cfg.mode == "tile":
            save_image(ctx.path("tiled", "tiled_3x3.png"), np.tile(image, (3, 3, 1)))
            save_image(ctx.path("tiled_input", "tiled_input_3x3.png"), np.tile(src, (3, 3, 1)))
        montage_png(ctx.path("comparison", "comparison.png"), [src, image], titles=["input", "result"])
