"""petri-synth's options: the one place the config's keys become the stages' arguments."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from synthkit.methods.petri.curves import PLANE_AXES, VIEW_AXES

if TYPE_CHECKING:
    from synthkit.methods.petri.config import PetriConfig

__all__ = ["LatticeOptions", "SpaceOptions", "PetriOptions", "options_of", "curves_of", "unit_key"]

@dataclass(frozen=True)
class LatticeOptions:
    """How the example is cut (``lattice``, ``labels``): :func:`analysis.resolve_lattice`'s unit or
    annotation ``(view, rect, depth_unit)``, the cut faces and the classification of the pieces."""

    unit: tuple | None
    origin: tuple | None
    annotation: tuple | None
    fit_tolerance: float
    caps: str
    tolerance: float
    match_geometry: bool
    boundary: bool


@dataclass(frozen=True)
class SpaceOptions:
    """What the construction space of a curve or a network is built with (``construction``): the
    projection plane, the side of the offset lines, the lattice units along (a, b, c) ``(3,)``, S_Y,
    S_Z, the sweep's first coordinate, and where the config sets the unit along the curve (messages)."""

    plane: str
    side: str
    units: np.ndarray
    size_y: int
    size_z: int
    sweep_origin: float
    unit_key: str


@dataclass(frozen=True)
class PetriOptions:
    """Every stage's options of one config (:func:`options_of`): the example's cut (``lattice``) and
    the construction space's settings, which :meth:`space` completes with the example's lattice."""

    lattice: LatticeOptions
    plane: str
    side: str
    size_y: int | None
    size_z: int | None
    unit_key: str

    def space(self, spec) -> SpaceOptions:
        """:class:`SpaceOptions` on the example's lattice ``spec`` (an :class:`analysis.LatticeSpec`;
        S_Y and S_Z default to the example's counts)."""
        axes = PLANE_AXES[self.plane]
        return SpaceOptions(
            plane=self.plane, side=self.side, units=spec.unit[list(axes)],
            size_y=self.size_y if self.size_y is not None else int(spec.counts[axes[1]]),
            size_z=self.size_z if self.size_z is not None else int(spec.counts[axes[2]]),
            sweep_origin=float(spec.origin[axes[2]]), unit_key=self.unit_key,
        )


def options_of(cfg: PetriConfig) -> PetriOptions:
    """The :class:`PetriOptions` of a config."""
    lat, ann, con = cfg.lattice, cfg.lattice.annotation, cfg.construction
    lattice = LatticeOptions(
        unit=lat.unit, origin=lat.origin,
        annotation=None if ann is None else (ann.view, ann.rect, ann.depth_unit),
        fit_tolerance=lat.fit_tolerance, caps=lat.caps, tolerance=cfg.labels.tolerance,
        match_geometry=cfg.labels.match == "geometry", boundary=cfg.labels.boundary,
    )
    return PetriOptions(lattice, con.plane, con.side, con.size_y, con.size_z, unit_key(cfg, PLANE_AXES[con.plane][0]))


def curves_of(cfg: PetriConfig) -> list[tuple[list, bool]]:
    """``(points, closed)`` of the config's curve, or of every curve of its network."""
    con = cfg.construction
    if con.curves is not None:
        return [(c.points, c.closed) for c in con.curves]
    return [(con.points, con.closed)]


def unit_key(cfg: PetriConfig, axis: int) -> str:
    """Where the config sets the lattice unit along world ``axis`` (for error messages)."""
    name = "XYZ"[axis]
    ann = cfg.lattice.annotation
    if ann is None:
        return f"lattice.unit[{axis}], along {name}"
    ax, ay, _ = VIEW_AXES[ann.view]
    if axis == ax:
        return f"the width of lattice.annotation.rect, along {name}"
    if axis == ay:
        return f"the height of lattice.annotation.rect, along {name}"
    if ann.depth_unit is None:
        return f"the example's whole depth along {name}, lattice.annotation.depth_unit: null"
    return f"lattice.annotation.depth_unit, along {name}"
