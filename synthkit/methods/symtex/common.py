"""What the symmetry-texture modes share: the objective, its targets, and the common outputs.

:func:`build_objective` and :func:`build_targets` turn a config into the :class:`Objective` and
its standardized target representations; :func:`write_common` writes ``result.png`` and the
heatmaps of S for input, target and result. Used by :mod:`.pipeline` and :mod:`.deform`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError
from synthkit.io.images import save_image
from synthkit.methods.symtex.config import SymtexConfig
from synthkit.methods.symtex.objective import Objective, st_window
from synthkit.preview import heatmap_png, plot_curve_png


def apply_filter(S: np.ndarray, cfg: SymtexConfig) -> np.ndarray:
    flt = cfg.filter
    if flt.kind == "identity":
        return sy.standardize(S)
    if flt.kind == "blur":
        return sy.blur(S, flt.sigma)
    if flt.kind == "sharpen":
        return sy.sharpen(S, flt.power)
    if flt.kind == "contrast":
        return sy.contrast(S, flt.amount)
    if flt.kind == "scale":
        if S.ndim != 2:
            raise ConfigError("filter.kind 'scale' needs the translational representation (symmetry.kind)")
        return sy.scale(S, flt.factor)
    if S.ndim != 2:
        shift = int(round(flt.angle / 360.0 * S.shape[0]))
        return sy.standardize(np.roll(S, shift))
    return sy.rotate(S, flt.angle)


def build_objective(cfg: SymtexConfig, shape, targets=None, center=None, source=None) -> Objective:
    """The config's objective for images of ``shape``; with ``symmetry.crop`` resolving to
    ``periods`` (:meth:`SymtexConfig.period_crop`), S_T is of the centred whole-period crop found
    on ``source`` (the input image)."""
    sym = cfg.symmetry
    crop = None
    if source is not None and cfg.period_crop():
        crop = sy.whole_period_crop(sy.signal(np.asarray(source, dtype=np.float64), sym.signals[0]))
    return Objective(
        representation=sym.kind,
        signals=sym.signals,
        kind=cfg.objective_kind(),
        targets=targets,
        window=st_window(crop or shape, sym.window) if sym.kind == "translational" else None,
        mode=sym.mode,
        center=center if center is not None else sym.center,
        n_angles=sym.n_angles,
        crop=crop,
    )


def build_targets(cfg: SymtexConfig, src: np.ndarray, tgt: np.ndarray | None, out_shape) -> list[np.ndarray] | None:
    """Standardized target per signal: S(g) for transfer, FLT(S(f)) for filter (and quilt's identity)."""
    if cfg.objective_kind() != "l2":
        return None
    sym = cfg.symmetry
    image = tgt if cfg.mode == "transfer" else src
    # S_T of the target image over the output's window (toroidal, so a small sketch extends
    # periodically); S_R / S_Ref about the target image's own centre.
    own = Objective(
        representation=sym.kind,
        signals=sym.signals,
        kind="symm",
        window=st_window(out_shape, sym.window) if sym.kind == "translational" else None,
        mode="toroidal" if sym.kind == "translational" else sym.mode,
        center=None,
        n_angles=sym.n_angles,
    )
    reps = [own.represent(sy.signal(image, s), standardize=True) for s in sym.signals]
    if cfg.mode == "filter":
        reps = [apply_filter(S, cfg) for S in reps]
    return reps


def preview_rep(path: Path, S: np.ndarray, title: str) -> None:
    if S.ndim == 2:
        heatmap_png(path, S, title=title)
    else:
        deg = np.arange(S.shape[0]) * (360.0 if title.startswith("S_R") else 180.0) / S.shape[0]
        plot_curve_png(path, deg, S, xlabel="degrees", ylabel="S", title=title)


def write_common(cfg, ctx, src, image, objective: Objective, targets) -> None:
    save_image(ctx.path("result", "result.png"), image)
    name = {"translational": "S_T", "rotational": "S_R", "reflective": "S_Ref"}[cfg.symmetry.kind]
    if ctx.wants_preview("all"):
        sig_in = sy.signal(src, cfg.symmetry.signals[0])
        if objective.representation == "translational" and src.shape[:2] != image.shape[:2]:
            rep_in = sy.translational(sig_in, mode="toroidal", window=objective.window)
        else:
            rep_in = objective.represent(sig_in, standardize=True)
        preview_rep(ctx.path("s_input", "s_input.png"), rep_in, f"{name} input")
        if targets is not None:
            preview_rep(ctx.path("s_target", "s_target.png"), targets[0], f"{name} target")
    rep_out = objective.represent(sy.signal(image, cfg.symmetry.signals[0]), standardize=True)
    preview_rep(ctx.preview_path("s_result", "s_result.png"), rep_out, f"{name} result")
    if rep_out.ndim == 2:
        try:
            ctx.metrics["result_peak"] = list(sy.strongest_peak(rep_out))
        except ValueError:
            ctx.metrics["result_peak"] = None  # a window too small to hold a peak
