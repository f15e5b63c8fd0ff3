"""The arguments of the symmetry-texture stages, built from a config in one place.

:func:`options_of` is the one map from config keys to stage arguments (with the mode's
defaults resolved: the perturbation, ``deform.min_gain``, the stretch bound of a tile, the
gradient bound of symmetrize); the stage modules take these dataclasses and arrays, never the
config or the run context.
"""

from __future__ import annotations

from dataclasses import dataclass

from synthkit.methods.symtex.config import SymtexConfig


@dataclass(frozen=True)
class ObjectiveOptions:
    """The objective (:class:`~synthkit.methods.symtex.objective.Objective`): ``representation``
    (``symmetry.kind``), ``signals``, ``kind`` (``"l2"`` against a target or ``"symm"``),
    ``window`` (fraction of the size), S_T ``mode``, S_R / S_Ref ``center`` and ``n_angles``,
    ``period_crop`` (S_T of the input's whole-period crop, ``symmetry.crop``)."""

    representation: str
    signals: tuple[str, ...]
    kind: str
    window: float
    mode: str
    center: tuple[float, float] | None
    n_angles: int
    period_crop: bool


@dataclass(frozen=True)
class FilterOptions:
    """The symmetry-space filter of mode ``filter`` (section ``filter``)."""

    kind: str
    sigma: float
    power: float
    amount: float
    factor: float
    angle: float


@dataclass(frozen=True)
class SynthOptions:
    """Quilting and the guided walk (section ``synth``)."""

    patch: int
    overlap: int
    tol: float
    candidates: int
    sweeps: int
    init: str
    seams: str
    evaluation: str
    seam_share: float
    polish_sweeps: int


@dataclass(frozen=True)
class DeformOptions:
    """The ARAP warp (section ``deform``): ``max_stretch`` is ``tile.max_stretch`` in mode tile,
    ``max_gradient`` applies to symmetrize only (None otherwise), ``min_gain`` resolved."""

    points: int
    levels: int
    step: float
    min_step: float
    max_cycles: int
    max_evaluations: int
    max_stretch: float | None
    max_gradient: float | None
    min_gain: float
    interpolation: str


@dataclass(frozen=True)
class TileOptions:
    """Mode ``tile`` (section ``tile``)."""

    optimize: bool
    margin: float
    zoom: str
    cut_overlaps: tuple[int, ...]
    mvc_spacing: int


@dataclass(frozen=True)
class LensOptions:
    """The lens search (section ``lens``)."""

    center: tuple[float, float] | None
    k1_min: float
    k1_max: float
    samples: int
    tol: float


@dataclass(frozen=True)
class SymtexOptions:
    """Everything a run's stages take: ``mode``, ``perturbation`` (resolved), ``output_size``
    (None: the source's) and one dataclass per stage."""

    mode: str
    perturbation: str
    output_size: tuple[int, int] | None
    baseline: bool
    objective: ObjectiveOptions
    filter: FilterOptions
    synth: SynthOptions
    deform: DeformOptions
    tile: TileOptions
    lens: LensOptions


def options_of(cfg: SymtexConfig) -> SymtexOptions:
    """The stage arguments of a validated config (``symmetry.signals`` already resolved from
    ``auto``; see :func:`synthkit.methods.symtex.pipeline.resolve_auto_signals`)."""
    sym, dc, tc = cfg.symmetry, cfg.deform, cfg.tile
    signals = ("lum",) if sym.signals == "auto" else tuple(sym.signals)
    return SymtexOptions(
        mode=cfg.mode,
        perturbation=cfg.resolved_perturbation(),
        output_size=None if cfg.output_size is None else tuple(cfg.output_size),
        baseline=cfg.baseline,
        objective=ObjectiveOptions(sym.kind, signals, cfg.objective_kind(), sym.window, sym.mode, sym.center,
                                   sym.n_angles, cfg.period_crop()),
        filter=FilterOptions(**cfg.filter.model_dump()),
        synth=SynthOptions(**cfg.synth.model_dump()),
        deform=DeformOptions(
            points=dc.points, levels=dc.levels, step=dc.step, min_step=dc.min_step, max_cycles=dc.max_cycles,
            max_evaluations=dc.max_evaluations,
            max_stretch=tc.max_stretch if cfg.mode == "tile" else dc.max_stretch,
            max_gradient=dc.max_gradient if cfg.mode == "symmetrize" else None,
            min_gain=cfg.resolved_min_gain(), interpolation=dc.interpolation,
        ),
        tile=TileOptions(optimize=tc.optimize, margin=tc.margin, zoom=tc.zoom,
                         cut_overlaps=tuple(tc.cut_overlaps), mvc_spacing=tc.mvc_spacing),
        lens=LensOptions(**cfg.lens.model_dump()),
    )
