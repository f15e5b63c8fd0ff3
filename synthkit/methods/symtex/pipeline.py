"""``synthkit symmetry-texture``: load, build the target, optimize, write the result and previews.

Stages: ``load`` (images, blank/size checks), ``target`` (S(g) or FLT(S(f))), ``baseline``
(unguided quilting from the same seed, synthesis modes), ``optimize`` (guided walk, ARAP or lens
search), ``write``. Metrics: ``objective_start``, ``objective_end``, ``baseline_objective``,
``iterations`` plus mode-specific values; the synthesis modes report ``seam_visibility`` (of the
result) and ``baseline_seam_visibility`` (of unguided quilting), see
:func:`synthkit.methods.symtex.synth.seam_visibility`. Randomness: ``ctx.rng`` is split once into a baseline
generator and a walk generator, so ``mode: quilt`` with a seed gives exactly the baseline of a
guided run with that seed.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from synthkit.core import quilting as q
from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError, InputError
from synthkit.io.images import load_image, save_image
from synthkit.methods.symtex import lens as lens_mod
from synthkit.methods.symtex import synth as synth_mod
from synthkit.methods.symtex.common import build_objective, build_targets, write_common
from synthkit.methods.symtex.config import SymtexConfig
from synthkit.preview import montage_png, plot_curve_png

MIN_SIZE = 8

log = logging.getLogger("synthkit")


def _load(path: Path, what: str) -> np.ndarray:
    img = load_image(path, mode="rgb")
    if min(img.shape[:2]) < MIN_SIZE:
        raise InputError(f"{path}: {what} is {img.shape[0]}x{img.shape[1]}, smaller than {MIN_SIZE}x{MIN_SIZE}")
    if float(np.ptp(img)) <= 1e-6:
        raise InputError(f"{path}: {what} is blank (constant): its symmetry representation is undefined")
    return img


def _check_signals(img: np.ndarray, signals, path: Path, what: str) -> None:
    for s in signals:
        if float(np.ptp(sy.signal(img, s))) <= 1e-6:
            raise InputError(f"{path}: {what} has a constant {s} signal: its symmetry representation is undefined")


def resolve_auto_signals(cfg: SymtexConfig, src: np.ndarray, metrics: dict) -> SymtexConfig:
    """``cfg`` with ``symmetry.signals: auto`` replaced by one signal chosen on ``src``.

    E_symm (tile, symmetrize): of ``lum`` and ``1-lum``, the one whose raw representation has the
    larger variance; both variances go to ``metrics.signal_variances``. With ``f = mu + g`` on a
    torus, raw S_T is ``(N mu^2 + AC_g) / (N mu^2 + AC_g(0))``, and ``1 - f`` has ``(1 - mu)`` in
    place of ``mu``: the same pattern, divided by a larger constant for the signal whose mean is
    farther from 0. On dark line art on white (``mu`` near 1) E_symm of lum is 1e-5 to 1e-8 of a
    flat S near 1; 1-lum carries the same pattern at 40-1200x that size (a synthetic grid, the
    negative of lattice-p4). With ``symmetry.mode: overlap`` (mean-free) both are equal: ``lum``.
    E_L2 compares standardized representations, which are the same for lum and 1-lum: ``lum``.
    """
    if cfg.objective_kind() == "symm":
        from synthkit.methods.symtex.common import build_objective

        objective = build_objective(cfg, src.shape[:2])
        variances = {}
        for s in ("lum", "1-lum"):
            f = sy.signal(src.astype(np.float64), s)
            variances[s] = sy.e_symm(objective.represent(f, standardize=False)) if np.ptp(f) > 1e-6 else 0.0
        chosen = max(variances, key=lambda k: (variances[k], k == "lum"))
        metrics["signal_variances"] = variances
    else:
        chosen = "lum"
    sym = cfg.symmetry.model_copy(update={"signals": [chosen]})
    return cfg.model_copy(update={"symmetry": sym})


PIXEL_BYTES = 512
"""Bytes per pixel of the working image: signals, their padded transforms, S fields and candidate
buffers (estimate)."""


def check_image_budget(budget, cfg: SymtexConfig, src: np.ndarray) -> None:
    """Refuse a source or output size whose working fields exceed the memory budget."""
    H, W = src.shape[:2]
    budget.require("source", f"{cfg.source} ({H}x{W})", H * W, "pixels", bytes_each=PIXEL_BYTES)
    if cfg.output_size is not None:
        h, w = cfg.output_size
        budget.require("output_size", f"{h}x{w}", float(h) * float(w), "pixels", bytes_each=PIXEL_BYTES)


def run(cfg: SymtexConfig, ctx) -> None:
    """Run one symmetry-texture config (see the module docstring)."""
    pert = cfg.resolved_perturbation()
    with ctx.stage("load"):
        src = _load(cfg.source, "source image")
        if cfg.symmetry.signals == "auto":
            cfg = resolve_auto_signals(cfg, src, ctx.metrics)
        _check_signals(src, cfg.symmetry.signals, cfg.source, "source image")
        tgt = None
        if cfg.target is not None and cfg.mode == "transfer":
            tgt = _load(cfg.target, "target image")
            _check_signals(tgt, cfg.symmetry.signals, cfg.target, "target image")
    ctx.metrics["signals"] = list(cfg.symmetry.signals)
    check_image_budget(ctx.budget, cfg, src)
    if pert == "synth":
        _run_synth(cfg, ctx, src, tgt)
    elif pert == "lens":
        _run_lens(cfg, ctx, src)
    else:
        from synthkit.methods.symtex import deform as deform_mod

        deform_mod.run_deform(cfg, ctx, src, tgt)


def _run_synth(cfg: SymtexConfig, ctx, src: np.ndarray, tgt: np.ndarray | None) -> None:
    sc = cfg.synth
    out_shape = tuple(cfg.output_size) if cfg.output_size is not None else src.shape[:2]
    if sc.patch > min(src.shape[:2]):
        raise ConfigError(
            f"synth.patch {sc.patch} is larger than the {src.shape[0]}x{src.shape[1]} source image {cfg.source}"
        )
    if sc.patch > min(out_shape):
        raise ConfigError(f"output_size {out_shape[0]}x{out_shape[1]} is smaller than one patch ({sc.patch})")
    with ctx.stage("target"):
        targets = build_targets(cfg, src, tgt, out_shape)
        objective = build_objective(cfg, out_shape, targets)
    base_rng, walk_rng = ctx.rng.spawn(2)
    baseline = baseline_value = baseline_seams = None
    if cfg.mode == "quilt" or cfg.baseline or sc.init == "quilt":
        with ctx.stage("baseline"):
            baseline = q.quilt(src, out_shape, patch=sc.patch, overlap=sc.overlap, tol=sc.tol, seams=sc.seams,
                               rng=base_rng, progress=ctx.progress)
            baseline_value = objective.value(baseline.image)
        baseline_seams = synth_mod.seam_visibility(baseline.image, baseline.sources)
    if cfg.mode == "quilt":
        image = baseline.image
        start = end = baseline_value
        iterations = len(baseline.ys) * len(baseline.xs)
        ctx.metrics.update(tiles=iterations, seam_visibility=baseline_seams)
    else:
        with ctx.stage("optimize"):
            if sc.init == "quilt":
                init = baseline
            else:
                init = synth_mod.random_init(
                    src,
                    out_shape,
                    patch=sc.patch,
                    overlap=sc.overlap,
                    rng=walk_rng,
                    seams=sc.seams,
                    progress=ctx.progress,
                )
            walk = synth_mod.guided_walk(
                src,
                init,
                signals=cfg.symmetry.signals,
                targets=targets,
                window=objective.window,
                patch=sc.patch,
                candidates=sc.candidates,
                sweeps=sc.sweeps,
                evaluation=sc.evaluation,
                seams=sc.seams,
                progress=ctx.progress,
            )
        image = walk.image
        start, end = walk.history[0], objective.value(image)
        iterations = walk.iterations
        ctx.metrics.update(
            seam_visibility=synth_mod.seam_visibility(image, walk.sources),
            **({"baseline_seam_visibility": baseline_seams} if cfg.baseline else {}),
            sweeps=len(walk.history) - 1,
            tiles_changed=walk.changed,
            candidates_evaluated=walk.candidates_evaluated,
            objective_history=walk.history,
        )
    ctx.metrics.update(
        objective="E_L2",
        objective_start=start,
        objective_end=end,
        **({"baseline_objective": baseline_value} if cfg.mode == "quilt" or cfg.baseline else {}),
        iterations=iterations,
        output_size=list(out_shape),
        window=list(objective.window),
    )
    with ctx.stage("write"):
        write_common(cfg, ctx, src, image, objective, targets)
        if cfg.mode != "quilt":
            shown = [src, image] if not cfg.baseline else [src, baseline.image, image]
            if cfg.baseline:
                save_image(ctx.path("baseline", "baseline.png"), baseline.image)
            if ctx.wants_preview("summary"):
                titles = ["source", "guided"] if not cfg.baseline else ["source", "unguided", "guided"]
                montage_png(ctx.path("comparison", "comparison.png"), shown, titles=titles)


def _run_lens(cfg: SymtexConfig, ctx, src: np.ndarray) -> None:
    lc = cfg.lens
    objective = build_objective(cfg, src.shape[:2], source=src)
    with ctx.stage("optimize"):

        def score(k1: float) -> float:
            return objective.value(lens_mod.undistort(src, k1, center=lc.center))

        start = score(0.0)
        k1, history = lens_mod.search_k1(score, k1_min=lc.k1_min, k1_max=lc.k1_max, samples=lc.samples, tol=lc.tol)
        image = lens_mod.undistort(src, k1, center=lc.center)
        end = objective.value(image)
    # issue 24: symmetrize never returns a worse image (E_symm of the search's k1 may be the
    # grid's best and still not above k1 = 0 once the colour image is resampled)
    reason = None if end > start else f"E_symm {end:.4g} at k1 {k1:.4g} is not above the input's {start:.4g}"
    if reason:
        log.warning("symmetrize: %s: returned the input unchanged (%s)", cfg.source, reason)
        image, end = src, start
    ctx.metrics.update(
        objective="E_symm",
        objective_start=start,
        objective_end=end,
        baseline_objective=start,
        iterations=len(history),
        k1=k1 if reason is None else 0.0,
        k1_searched=k1,
        status="input returned" if reason else "symmetrized",
        status_reason=reason,
    )
    with ctx.stage("write"):
        write_common(cfg, ctx, src, image, objective, None)
        ks, vals = np.array(sorted(history)).T
        plot_curve_png(
            ctx.preview_path("k1_search", "k1_search.png"), ks, vals, xlabel="k1", ylabel="E_symm", title="lens search"
        )
