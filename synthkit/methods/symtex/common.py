"""What the symmetry-texture modes share: the objective, its targets, and the S of the result.

:func:`build_objective` and :func:`build_targets` turn a config into the :class:`Objective` and
its standardized target representations; :func:`representations` gives S of input, target and
result (the previews of :mod:`.outputs`). Used by :mod:`.pipeline` and :mod:`.deform`.
"""

from __future__ import annotations

import numpy as np

from synthkit.core import symmetry as sy
from synthkit.errors import ConfigError
from synthkit.methods.symtex.config import SymtexConfig
from synthkit.methods.symtex.objective import Objective, st_window


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


def representations(cfg: SymtexConfig, src: np.ndarray, image: np.ndarray, objective: Objective,
                    targets) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Standardized S of the first signal of the input ``src``, the target and the result
    ``image`` (the result's by ``objective``; the input's too, unless the result's size differs,
    when the input's S_T is over the same window)."""
    signal = cfg.symmetry.signals[0]
    sig_in = sy.signal(src, signal)
    if objective.representation == "translational" and src.shape[:2] != image.shape[:2]:
        rep_in = sy.translational(sig_in, mode="toroidal", window=objective.window)
    else:
        rep_in = objective.represent(sig_in, standardize=True)
    rep_out = objective.represent(sy.signal(image, signal), standardize=True)
    return rep_in, None if targets is None else targets[0], rep_out


def result_peak(rep: np.ndarray) -> list[int] | None:
    """The strongest peak of an S_T lattice ``(a, b)`` (:func:`synthkit.core.symmetry.strongest_peak`);
    None for a window too small to hold a peak."""
    try:
        return list(sy.strongest_peak(rep))
    except ValueError:
        return None
