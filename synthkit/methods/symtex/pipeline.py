"""``synthkit symmetry-texture``: load, build the target, optimize; the result in memory.

:func:`compute` runs the stages on an :class:`~synthkit.io.inputs.Inputs` and returns a
:class:`~synthkit.methods.symtex.outputs.SymmetryTextureResult` (``synthkit.symmetry_texture``);
:func:`run` (the command line) writes it. Stages: ``load`` (images, blank/size checks),
``target`` (S(g) or FLT(S(f))), ``baseline`` (unguided quilting from the same seed, synthesis
modes), ``optimize`` (guided walk, ARAP or lens search), then ``write`` (:mod:`.outputs`).

Metrics: ``objective_start``, ``objective_end``, ``baseline_objective``, ``iterations`` plus
mode-specific values; the synthesis modes report ``seam_visibility`` and ``seam_energy`` (of the
result) and ``baseline_seam_visibility``, ``baseline_seam_energy`` (of unguided quilting), see
:func:`synthkit.methods.symtex.synth.seam_visibility` and
:func:`~synthkit.methods.symtex.synth.seam_energy`. Randomness: ``ctx.rng`` is split once into a
baseline generator and a walk generator, so ``mode: quilt`` with a seed gives exactly the
baseline of a guided run with that seed.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from synthkit.core import quilting as q
from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError, InputError
from synthkit.io.inputs import Inputs
from synthkit.methods.symtex import deform as deform_mod
from synthkit.methods.symtex import lens as lens_mod
from synthkit.methods.symtex import synth as synth_mod
from synthkit.methods.symtex import tile as tile_mod
from synthkit.methods.symtex.common import build_objective, build_targets, representations, result_peak, similarity
from synthkit.methods.symtex.config import SymtexConfig
from synthkit.methods.symtex.options import SymtexOptions, options_of
from synthkit.methods.symtex.outputs import SymmetryTextureResult
from synthkit.result import result_fields

MIN_SIZE = 8

log = logging.getLogger("synthkit")


def _name(inputs: Inputs, path: Path, key: str):
    """What messages call an input: its file, or its config key when it was given in memory."""
    return key if inputs.is_memory(path) else path


def _load(inputs: Inputs, path: Path, key: str, what: str) -> np.ndarray:
    """The image at config key ``key`` (a file or an array given in memory), checked."""
    img = inputs.image(path, mode="rgb")
    where = _name(inputs, path, key)
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
    larger variance (both go to ``metrics.signal_variances``; why: docs/findings/symmetry-texture.md).
    With ``symmetry.mode: overlap`` (mean-free) both are equal: ``lum``. E_L2 compares
    standardized representations, which are the same for lum and 1-lum: ``lum``.
    """
    if cfg.objective_kind() == "symm":
        objective = build_objective(options_of(cfg).objective, src.shape[:2])
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


def check_image_budget(budget, cfg: SymtexConfig, src: np.ndarray, source=None) -> None:
    """Refuse a source or output size whose working fields exceed the memory budget (``source``:
    what the message calls the source image, default its file)."""
    H, W = src.shape[:2]
    budget.require("source", f"{source or cfg.source} ({H}x{W})", H * W, "pixels", bytes_each=PIXEL_BYTES)
    if cfg.output_size is not None:
        h, w = cfg.output_size
        budget.require("output_size", f"{h}x{w}", float(h) * float(w), "pixels", bytes_each=PIXEL_BYTES)


def compute(cfg: SymtexConfig, inputs: Inputs, ctx) -> SymmetryTextureResult:
    """Run one symmetry-texture config on ``inputs`` (see the module docstring); write nothing."""
    given = cfg
    source = _name(inputs, cfg.source, "source")
    with ctx.stage("load"):
        src = _load(inputs, cfg.source, "source", "source image")
        if cfg.symmetry.signals == "auto":
            cfg = resolve_auto_signals(cfg, src, ctx.metrics)
        _check_signals(src, cfg.symmetry.signals, source, "source image")
        tgt = None
        if cfg.target is not None and cfg.mode == "transfer":
            tgt = _load(inputs, cfg.target, "target", "target image")
            _check_signals(tgt, cfg.symmetry.signals, _name(inputs, cfg.target, "target"), "target image")
    ctx.metrics["signals"] = list(cfg.symmetry.signals)
    check_image_budget(ctx.budget, cfg, src, source)
    opts = options_of(cfg)
    if opts.perturbation == "synth":
        _check_patch(opts, src, source)
    try:
        if opts.perturbation == "synth":
            out = _run_synth(opts, ctx, src, tgt)
        elif opts.perturbation == "lens":
            out = _run_lens(opts, ctx, src, source)
        else:
            out = _run_deform(opts, ctx, src, tgt, source)
    except ValueError as exc:
        if str(exc).split(" ", 1)[0] in CONFIG_KEYS:  # a stage's refusal naming a config key
            raise ConfigError(str(exc)) from None
        raise
    objective, targets = out.pop("objective"), out.pop("targets")
    s_input, s_target, s_result = representations(src, out["image"], objective, targets)
    if s_result.ndim == 2:
        ctx.metrics["result_peak"] = result_peak(s_result)
    return SymmetryTextureResult(source=src, s_input=s_input, s_target=s_target, s_result=s_result, **out,
                                 **result_fields(given, ctx, inputs))


CONFIG_KEYS = ("tile.margin", "filter.kind")
"""The keys the stage modules name in a ``ValueError`` that the pipeline reports as a config error."""


def _check_patch(opts: SymtexOptions, src: np.ndarray, source) -> None:
    patch, out_shape = opts.synth.patch, opts.output_size or src.shape[:2]
    if patch > min(src.shape[:2]):
        raise ConfigError(f"synth.patch {patch} is larger than the {src.shape[0]}x{src.shape[1]} source image {source}")
    if patch > min(out_shape):
        raise ConfigError(f"output_size {out_shape[0]}x{out_shape[1]} is smaller than one patch ({patch})")


def _targets(opts: SymtexOptions, src: np.ndarray, tgt: np.ndarray | None, out_shape) -> list[np.ndarray] | None:
    """S(g) of transfer's target, FLT(S(f)) of filter, S(f) of quilt (E_L2); None for E_symm."""
    image = tgt if opts.mode == "transfer" else src
    return build_targets(opts.objective, image, out_shape, opts.filter if opts.mode == "filter" else None)


def _run_synth(opts: SymtexOptions, ctx, src: np.ndarray, tgt: np.ndarray | None) -> dict:
    sc = opts.synth
    out_shape = opts.output_size or src.shape[:2]
    with ctx.stage("target"):
        targets = _targets(opts, src, tgt, out_shape)
        objective = build_objective(opts.objective, out_shape, targets)
    base_rng, walk_rng = ctx.rng.spawn(2)
    baseline = baseline_value = baseline_seams = None
    if opts.mode == "quilt" or opts.baseline or sc.init == "quilt":
        with ctx.stage("baseline"):
            baseline = q.quilt(src, out_shape, patch=sc.patch, overlap=sc.overlap, tol=sc.tol, seams=sc.seams,
                               rng=base_rng, progress=ctx.progress)
            baseline_value = objective.value(baseline.image)
        baseline_seams = seam_figures(baseline.image, baseline.sources)
    if opts.mode == "quilt":
        image = baseline.image
        start = end = baseline_value
        iterations = len(baseline.ys) * len(baseline.xs)
        ctx.metrics.update(tiles=iterations, **baseline_seams)
    else:
        with ctx.stage("optimize"):
            init = baseline if sc.init == "quilt" else synth_mod.random_init(
                src, out_shape, patch=sc.patch, overlap=sc.overlap, rng=walk_rng, seams=sc.seams,
                progress=ctx.progress)
            walk = synth_mod.guided_walk(
                src, init, signals=objective.signals, targets=targets, window=objective.window, patch=sc.patch,
                candidates=sc.candidates, sweeps=sc.sweeps, evaluation=sc.evaluation, seams=sc.seams,
                seam_share=sc.seam_share, polish_sweeps=sc.polish_sweeps, progress=ctx.progress)
        image = walk.image
        start, end = walk.history[0], objective.value(image)
        iterations = walk.iterations
        ctx.metrics.update(
            **seam_figures(image, walk.sources),
            **({f"baseline_{k}": v for k, v in baseline_seams.items()} if opts.baseline else {}),
            sweeps=len(walk.history) - 1,
            tiles_changed=walk.changed,
            candidates_evaluated=walk.candidates_evaluated,
            objective_history=walk.history,
        )
    ctx.metrics.update(
        objective="E_L2",
        objective_start=start,
        objective_end=end,
        **({"baseline_objective": baseline_value} if opts.mode == "quilt" or opts.baseline else {}),
        iterations=iterations,
        output_size=list(out_shape),
        window=list(objective.window),
    )
    return {"image": image, "baseline": baseline.image if opts.mode != "quilt" and opts.baseline else None,
            "objective": objective, "targets": targets}


def seam_figures(image: np.ndarray, sources: np.ndarray) -> dict:
    """``seam_visibility`` (mean over border steps) and ``seam_energy`` (visible border per step) of
    a quilted image, see :func:`synthkit.methods.symtex.synth.seam_energy`."""
    return {"seam_visibility": synth_mod.seam_visibility(image, sources),
            "seam_energy": synth_mod.seam_energy(image, sources)}


def _run_lens(opts: SymtexOptions, ctx, src: np.ndarray, source) -> dict:
    lc = opts.lens
    objective = build_objective(opts.objective, src.shape[:2], source=src)
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
        log.warning("symmetrize: %s: returned the input unchanged (%s)", source, reason)
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
        ssim_to_input=similarity(image, src),
    )
    return {"image": image, "k1_search": np.array(history, dtype=np.float64), "objective": objective, "targets": None}


def _run_deform(opts: SymtexOptions, ctx, src: np.ndarray, tgt: np.ndarray | None, source) -> dict:
    """Perturbation ``deform`` (transfer, filter, symmetrize, tile): the ARAP warp
    (:func:`synthkit.methods.symtex.deform.warp_image`), then the tile candidates (mode tile) or
    the refusal of a symmetrization that is not better (mode symmetrize)."""
    tile = opts.mode == "tile"
    if tile and not opts.tile.optimize:
        return _run_tile_unoptimized(opts, ctx, src)
    out_shape = tile_mod.tile_crop(src.shape, opts.tile.margin)[0] if tile and opts.tile.zoom == "crop" \
        else src.shape[:2]
    with ctx.stage("target"):
        targets = _targets(opts, src, tgt, out_shape)
        objective = build_objective(opts.objective, out_shape, targets, source=src)
    warp = deform_mod.warp_image(src, objective, opts.deform, rng=ctx.rng, tile=opts.tile if tile else None,
                                 progress=ctx.progress, stage=ctx.stage)
    image, sample_map, metrics, tiles = warp.image, warp.sample_map, warp.metrics, {}
    if tile:
        image, tiles = tile_mod.tile_result(src, image, objective, opts.tile, warp.hf_view, metrics,
                                            progress=ctx.progress, stage=ctx.stage)
    if opts.mode == "symmetrize":
        reason = deform_mod.symmetrize_refusal(metrics, opts.deform.max_gradient)
        metrics["status"] = "input returned" if reason else "symmetrized"
        metrics["status_reason"] = reason
        if reason:
            log.warning("symmetrize: %s: returned the input unchanged (%s)", source, reason)
            image, sample_map = src, warp.start_map
            for key in ("objective_end", "mean_displacement", "max_displacement", "max_displacement_gradient"):
                metrics[f"refused_{key}"] = metrics[key]
            metrics.update(objective_end=metrics["baseline_objective"], mean_displacement=0.0,
                           max_displacement=0.0, max_displacement_gradient=0.0)
        metrics["ssim_to_input"] = similarity(image, src)
    ctx.metrics.update(metrics)
    return {"image": image, "sample_map": sample_map, "tiles": tiles, "objective": objective, "targets": targets}


def _run_tile_unoptimized(opts: SymtexOptions, ctx, src: np.ndarray) -> dict:
    """Mode ``tile`` without the paper's optimization (``tile.optimize: false``, the default): the
    blended input and the cut tiles are compared with the input as
    :func:`~synthkit.methods.symtex.tile.choose_tile` does, in seconds. E_symm is that of the same
    objective as with the optimization (window of the tile crop)."""
    out_shape, _ = tile_mod.tile_crop(src.shape, opts.tile.margin)
    with ctx.stage("target"):
        objective = build_objective(opts.objective, out_shape, None, source=src)
    start = objective.value(src)
    metrics = {"objective": "E_symm", "objective_start": start, "objective_end": start, "iterations": 0,
               "tile_optimized": False}
    image, tiles = tile_mod.tile_result(src, None, objective, opts.tile, None, metrics, progress=ctx.progress,
                                        stage=ctx.stage)
    ctx.metrics.update(metrics)
    return {"image": image, "sample_map": None, "tiles": tiles, "objective": objective, "targets": None}
