"""The label problem of one retargeting (section III-B): the steps the target asks for, each
voxel's descriptor set and the MRF of eq. 3 on the voxel grid spanned by the offsets.

Arrays in normalised units (the model's longest side spans [-1, 1]). An error a config entry
causes is a :class:`KeyedError`, a ValueError naming the entry (``target.steps[0]=-6``, ``pins``).
"""

from __future__ import annotations

import numpy as np

from synthkit.errors import KeyedError
from synthkit.methods.retarget.analysis import Analysis, describe
from synthkit.methods.retarget.options import SynthesisOptions, Target
from synthkit.methods.retarget.synthesis import RetargetProblem, VoxelGrid, make_grid

__all__ = ["resolve_steps", "voxel_sets", "build_problem", "offsets_found", "working_steps", "AXIS_ANGLE_MAX"]

AXIS_ANGLE_MAX = 45.0
"""Degrees: ``axis_steps`` along a world axis take the principal offset nearest it, if it is at most
this far off (farther, the model does not repeat along that axis)."""


def resolve_steps(target: Target, an: Analysis, Vn, *, keys: dict | None = None) -> np.ndarray:
    """Steps ``(3,)`` per basis column of ``an`` for ``target`` (steps, axis_steps or scale) over the
    normalised vertices ``Vn (#V, 3)``.

    ``scale`` factor f along principal offset i becomes ``round((f - 1) * extent_i)`` steps, with
    ``extent_i`` the model's extent along canonical axis i in steps. Steps along dummy directions
    are refused (:class:`KeyedError`), as the paper never resizes along them. ``keys``, when
    given, is filled with ``axis -> "key=value"`` for the config entries that gave each axis its steps.
    """
    keys = {} if keys is None else keys
    k = an.n_principal
    steps = np.zeros(3, dtype=np.int64)
    if target.axis_steps is not None:
        used: dict[int, str] = {}
        for name, s in target.axis_steps.items():
            axis = np.eye(3)["xyz".index(name)]
            if k == 0:
                if s:
                    raise KeyedError(f"target.axis_steps.{name}={s}", "no principal offset was found")
                continue
            P = an.basis[:, :k].T
            cos = np.abs(P @ axis) / np.linalg.norm(P, axis=1)
            i = int(np.argmax(cos))
            off = float(np.degrees(np.arccos(min(cos[i], 1.0))))
            if s and off > AXIS_ANGLE_MAX:
                raise KeyedError(f"target.axis_steps.{name}={s}", f"no principal offset runs along {name} (the "
                                 f"nearest, #{i}, is {off:.0f} degrees off it)")
            if i in used and s:
                raise KeyedError("target.axis_steps", f"{used[i]} and {name} both map to principal offset {i}")
            if s:
                used[i] = name
                steps[i] += s
                keys[i] = f"target.axis_steps.{name}={s}"
        return steps
    if target.scale is not None:
        ext = np.ptp(Vn @ np.linalg.inv(an.basis).T, axis=0)
        for i, f in enumerate(target.scale):
            steps[i] = int(round((f - 1.0) * ext[i]))
            keys[i] = f"target.scale[{i}]={f} ({int(steps[i])} steps)"
            if steps[i] and i >= k:
                raise KeyedError(f"target.scale[{i}]={f}", f"only {k} principal offset(s) were found")
        return steps
    given = target.steps if target.steps is not None else [1]
    for i, s in enumerate(given):
        if s and i >= k:
            raise KeyedError(f"target.steps[{i}]={s}", f"only {k} principal offset(s) were found")
        steps[i] = s
        keys[i] = f"target.steps[{i}]={s}"
    return steps


def voxel_sets(an: Analysis, grid: VoxelGrid, *, descriptor: str, radius: float) -> list[np.ndarray]:
    """Descriptor set G of every input voxel (flat C order): the features inside it. A voxel that
    holds dense samples but no feature (a sliver thinner than the feature spacing) gets up to 8
    of its dense samples, described the same way, so that it is not mistaken for empty; a voxel
    with no dense sample counts as empty (its surface is below the sampling resolution)."""
    fs = an.features
    shape = tuple(grid.shape)
    vox = grid.voxel_of(grid.to_canonical(fs.P))
    ok = np.all((vox >= 0) & (vox < grid.shape), axis=1)
    flat = np.full(len(vox), -1)
    flat[ok] = np.ravel_multi_index(tuple(vox[ok].T), shape)
    sets = [fs.D[flat == i] for i in range(grid.n_voxels)]
    dvox = grid.voxel_of(grid.to_canonical(fs.dense_P))
    dok = np.all((dvox >= 0) & (dvox < grid.shape), axis=1)
    dflat = np.full(len(dvox), -1)
    dflat[dok] = np.ravel_multi_index(tuple(dvox[dok].T), shape)
    occupied = np.unique(dflat[dflat >= 0])
    for i in occupied:
        if len(sets[i]) == 0:
            idx = np.flatnonzero(dflat == i)
            idx = idx[np.linspace(0, len(idx) - 1, min(8, len(idx))).astype(int)]
            sets[i] = describe(
                fs.dense_P[idx], fs.dense_N[idx], fs.dense_P, fs.dense_N, descriptor=descriptor, radius=radius
            )
    return sets


def build_problem(Vn, F, an: Analysis, basis, steps, opt: SynthesisOptions, *, regular: bool = False,
                  pinned: bool = True, step_keys: dict | None = None) -> tuple[VoxelGrid, RetargetProblem]:
    """The voxel grid spanned by ``basis (3, 3)`` over the normalised mesh ``Vn (#V, 3)``,
    ``F (#F, 3)`` and the MRF that grows it by ``steps (3,)`` voxels per axis: ``(grid, problem)``.
    ``regular`` (the regular baseline) gives every axis ``opt.label_margin`` extra shifts, else only
    the principal ones; ``pinned`` applies ``opt.pins``. Raises :class:`KeyedError` naming
    ``step_keys[axis]`` (from :func:`resolve_steps`) when steps leave fewer than 2 cells along an
    axis, or ``pins`` when a pin is not a valid label of a voxel."""
    used = np.unique(F)
    grid = make_grid(basis, an.features.dense_P, an.features.dense_N, Vn[used], dense_radius=opt.dense_radius)
    sets = voxel_sets(an, grid, descriptor=opt.descriptor, radius=opt.descriptor_radius)
    steps = np.asarray(steps, dtype=np.int64)
    out_shape = grid.shape + steps
    for axis in np.flatnonzero(steps):
        if out_shape[axis] < 2:
            what = step_keys.get(int(axis)) if step_keys else None
            what = what or f"{int(steps[axis])} steps along grid axis {int(axis)}"
            raise KeyedError(what, f"would shrink below one cell (the input spans {int(grid.shape[axis])} "
                                   "cells along it; at least 2 must remain)")
    margin = [opt.label_margin] * 3 if regular else np.where(np.arange(3) < an.n_principal, opt.label_margin, 0)
    try:
        problem = RetargetProblem(grid.shape, steps, sets, margin=margin, pins=opt.pins if pinned else [])
    except ValueError as exc:
        raise KeyedError("pins", str(exc)) from None
    return grid, problem


def _along(v: np.ndarray) -> str:
    """``v (3,)``'s length and the world axis it runs along (with its angle to it when not along it)."""
    i = int(np.argmax(np.abs(v)))
    off = float(np.degrees(np.arccos(min(abs(v[i]) / np.linalg.norm(v), 1.0))))
    return f"{np.linalg.norm(v):.3g} along {'xyz'[i]}" + (f" ({off:.0f} degrees off)" if off >= 5 else "")


def offsets_found(an: Analysis) -> str:
    """What the model repeats, in one phrase: each principal offset's length (normalised units) and axis."""
    k = an.n_principal
    found = ", ".join(f"#{i} {_along(an.basis[:, i])}" for i in range(k))
    return f"the model repeats by {k} principal offset(s) ({found}; normalised units)"


def working_steps(Vn, F, an: Analysis, opt: SynthesisOptions, rng, tried) -> np.ndarray | None:
    """Steps ``(3,)`` of the nearest request that retargets ``Vn``, ``F`` seamlessly: one step, then
    one step back, along each principal offset in turn (``tried`` left out); None when none does.
    Each candidate is one graph cut."""
    for sign in (1, -1):
        for i in range(an.n_principal):
            steps = np.zeros(3, np.int64)
            steps[i] = sign
            if np.array_equal(steps, tried):
                continue
            try:
                _, problem = build_problem(Vn, F, an, an.basis, steps, opt)
            except KeyedError:
                continue
            if np.isfinite(problem.solve(rng=rng, max_cycles=opt.max_cycles).energy):
                return steps
    return None
