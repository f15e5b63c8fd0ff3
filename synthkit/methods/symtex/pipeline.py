"""``synthkit symmetry-texture``: load, build the target, optimize; the result in memory.

:func:`compute` runs the stages on an :class:`~synthkit.io.inputs.Inputs` and returns a
:class:`~synthkit.methods.symtex.outputs.SymmetryTextureResult` (``synthkit.symmetry_texture``);
:func:`run` (the command line) writes it. Stages: ``load`` (images, blank/size checks),
``target`` (S(g) or FLT(S(f))), ``baseline`` (unguided quilting from the same seed, synthesis
modes), ``optimize`` (guided walk, ARAP or lens search), then ``write`` (:mod:`.outputs`).

Metrics: ``objective_start``, ``objective_end``, ``baseline_objective``, ``iterations`` plus
mode-specific values; the synthesis modes report ``seam_visibility`` (of the result) and
``baseline_seam_visibility`` (of unguided quilting), see
:func:`synthkit.methods.symtex.synth.seam_visibility`. Randomness: ``ctx.rng`` is split once into
a baseline generator and a walk generator, so ``mode: quilt`` with a seed gives exactly the
baseline of a guided run with that seed.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from synthkit.api import result_fields
from synthkit.core import quilting as q
from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError, InputError
from synthkit.io.inputs import Inputs
from synthkit.methods.symtex import lens as lens_mod
from synthkit.methods.symtex import synth as synth_mod
from synthkit.methods.symtex.common import build_objective, build_targets, representations, result_peak
from synthkit.methods.symtex.config import SymtexConfig
from synthkit.methods.symtex.outputs import SymmetryTextureResult

MIN_SIZE = 8

log = logging.getLogger("synthkit")


def _load(inputs: Inputs, path: Path, key: str, what: str) -> np.ndarray:
    """The image at config key ``key`` (a file or an array given in memory), checked."""
    img = inputs.image(path, mode="rgb")
    where = key if inputs.is_memory(path) else path
    if min(img.shape[:2]) < MIN_SIZE:
        raise InputError(f"{where}: {what} is {img.shape[0]}x{img.shape[1]}, smaller than {MIN_SIZE}x{MIN_SIZE}")
    if float(np.ptp(img)) <= 1e-6:
        raise InputError(f"{where}: {what} is blank (constant): its symmetry representation is undefined")
    return img


def _check_signals(img: np.ndarray, signals, where, what: str) -> None:
    for s in signals:
        if float(np.ptp(sy.signal(img, s))) <= 1e-6:
            raise InputError(f"{where}: {what} has a constant {s} signal: its symmetry representation is undefined")


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


def compute(cfg: SymtexConfig, inputs: Inputs, ctx) -> SymmetryTextureResult:
    """Run one symmetry-texture config on ``inputs`` (see the module docstring); write nothing."""
    given = cfg
    pert = cfg.resolved_perturbation()
    with ctx.stage("load"):
        src = _load(inputs, cfg.source, "source", "source image")
        if cfg.symmetry.signals == "auto":
            cfg = resolve_auto_signals(cfg, src, ctx.metrics)
        where = "source" if inputs.is_memory(cfg.source) else cfg.source
        _check_signals(src, cfg.symmetry.signals, where, "source image")
        tgt = None
        if cfg.target is not None and cfg.mode == "transfer":
            tgt = _load(inputs, cfg.target, "target", "target image")
            where = "target" if inputs.is_memory(cfg.target) else cfg.target
            _check_signals(tgt, cfg.symmetry.signals, where, "target image")
    ctx.metrics["signals"] = list(cfg.symmetry.signals)
    check_image_budget(ctx.budget, cfg, src)
    if pert == "synth":
        out = _run_synth(cfg, ctx, src, tgt)
    elif pert == "lens":
        out = _run_lens(cfg, ctx, src)
    else:
        out = _run_deform(cfg, ctx, src, tgt)
    objective, targets = out.pop("objective"), out.pop("targets")
    s_input, s_target, s_result = representations(cfg, src, out["image"], objective, targets)
    if s_result.ndim == 2:
        ctx.metrics["result_peak"] = result_peak(s_result)
    return SymmetryTextureResult(source=src, s_input=s_input, s_target=s_target, s_result=s_result, **out,
                                 **result_fields(given, ctx, inputs))


def run(cfg: SymtexConfig, ctx) -> None:
    """The command line's run: :func:`compute` on the config's files, then write the outputs."""
    compute(cfg, Inputs(), ctx).write(ctx)


def _run_deform(cfg: SymtexConfig, ctx, src: np.ndarray, tgt: np.ndarray | None) -> dict:
    from synthkit.methods.symtex import deform as deform_mod

    try:
        image, sample_map, tiles, objective, targets = deform_mod.run_deform(cfg, ctx, src, tgt)
    except ValueError as exc:
        if str(exc).startswith("tile.margin"):
            raise ConfigError(str(exc)) from None
        raise
    return {"image": image, "sample_map": sample_map, "tiles": tiles, "objective": objective, "targets": targets}


def _run_synth(cfg: SymtexConfig, ctx, src: np.ndarray, tgt: np.ndarray | None) -> dict:
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
    return {"image": image, "baseline": baseline.image if cfg.mode != "quilt" and cfg.baseline else None,
            "objective": objective, "targets": targets}


def _run_lens(cfg: SymtexConfig, ctx, src: np.ndarray) -> dict:
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
    return {"image": image, "k1_search": np.array(history, dtype=np.float64), "objective": objective, "targets": None}
