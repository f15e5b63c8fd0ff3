"""What the symmetry-texture modes share: the objective, its targets, and the S of the result.

:func:`build_objective` and :func:`build_targets` turn the options
(:class:`~synthkit.methods.symtex.options.ObjectiveOptions`) into the :class:`Objective` and its
standardized target representations; :func:`representations` gives S of input, target and
result (the previews of :mod:`.outputs`). Used by :mod:`.pipeline` and :mod:`.deform`.
"""

from __future__ import annotations

import numpy as np

from synthkit.core import symmetry as sy
from synthkit.methods.symtex.objective import Objective, st_window
from synthkit.methods.symtex.options import FilterOptions, ObjectiveOptions


def apply_filter(S: np.ndarray, flt: FilterOptions) -> np.ndarray:
    """The symmetry-space filter ``flt`` of a standardized representation ``S``; a ``ValueError``
    naming ``filter.kind`` when it needs an S_T lattice and ``S`` is a curve (S_R / S_Ref)."""
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
            raise ValueError("filter.kind 'scale' needs the translational representation (symmetry.kind)")
        return sy.scale(S, flt.factor)
    if S.ndim != 2:
        shift = int(round(flt.angle / 360.0 * S.shape[0]))
        return sy.standardize(np.roll(S, shift))
    return sy.rotate(S, flt.angle)


def build_objective(opts: ObjectiveOptions, shape, targets=None, source=None) -> Objective:
    """The objective for images of ``shape``; with ``opts.period_crop``, S_T is of the centred
    whole-period crop found on ``source`` (the input image)."""
    crop = None
    if source is not None and opts.period_crop:
        crop = sy.whole_period_crop(sy.signal(np.asarray(source, dtype=np.float64), opts.signals[0]))
    return Objective(
        representation=opts.representation,
        signals=opts.signals,
        kind=opts.kind,
        targets=targets,
        window=st_window(crop or shape, opts.window) if opts.representation == "translational" else None,
        mode=opts.mode,
        center=opts.center,
        n_angles=opts.n_angles,
        crop=crop,
    )


def build_targets(opts: ObjectiveOptions, image: np.ndarray, out_shape,
                  flt: FilterOptions | None = None) -> list[np.ndarray] | None:
    """Standardized target per signal: S of ``image`` (the target g of transfer, the source of
    filter and quilt), filtered by ``flt`` (mode filter); None for E_symm."""
    if opts.kind != "l2":
        return None
    # S_T of the target image over the output's window (toroidal, so a small sketch extends
    # periodically); S_R / S_Ref about the target image's own centre.
    translational = opts.representation == "translational"
    own = Objective(
        representation=opts.representation,
        signals=opts.signals,
        kind="symm",
        window=st_window(out_shape, opts.window) if translational else None,
        mode="toroidal" if translational else opts.mode,
        center=None,
        n_angles=opts.n_angles,
    )
    reps = [own.represent(sy.signal(image, s), standardize=True) for s in opts.signals]
    if flt is not None:
        reps = [apply_filter(S, flt) for S in reps]
    return reps


def representations(src: np.ndarray, image: np.ndarray, objective: Objective,
                    targets) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Standardized S of the first signal of the input ``src``, the target and the result
    ``image`` (the result's by ``objective``; the input's too, unless the result's size differs,
    when the input's S_T is over the same window)."""
    signal = objective.signals[0]
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


def similarity(image: np.ndarray, reference: np.ndarray) -> float:
    """SSIM (``skimage.metrics.structural_similarity``, 7x7 windows, per channel) of two images
    ``(H, W, C)`` in [0, 1]: 1 for equal images; the figure ``ssim_to_input`` of symmetrize."""
    from skimage.metrics import structural_similarity

    return float(structural_similarity(image, reference, channel_axis=2, data_range=1.0))
