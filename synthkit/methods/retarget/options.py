"""The settings of retargeting's stages, built from the config in one place (:func:`options_of`):
the one map from config keys to the stages' arguments."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AnalysisOptions", "SynthesisOptions", "Target", "options_of"]


@dataclass(frozen=True)
class AnalysisOptions:
    """Settings of :func:`~synthkit.methods.retarget.analysis.analyze` (config section ``analysis``,
    whose descriptions say what each does; lengths in normalised units). ``min_angle`` is in
    radians (``min_angle_deg``); ``icp_sources`` is how many dense samples the ICP moves at most."""

    dense_radius: float
    feature_radius: float
    use_vertices: bool
    descriptor: str
    descriptor_radius: float
    tau: float
    bin_size: float
    nms_window: float
    min_peak_share: float
    max_dominant: int
    min_overlap: float
    min_grip: float
    min_angle: float
    max_principal: int
    dummy_length: float
    statistics_features: str
    generator_grip_ratio: float
    icp_sources: int = 4000


@dataclass(frozen=True)
class SynthesisOptions:
    """Settings of the label problem and the stitching (:mod:`~synthkit.methods.retarget.problem`,
    :mod:`~synthkit.methods.retarget.seams`): ``label_margin`` extra shifts on each side,
    ``pins`` ``[(voxel (3,), shift (3,)), ...]``, ``max_cycles`` of alpha-expansion,
    ``weld_tolerance`` of the seams, and the analysis's ``dense_radius``, ``descriptor`` and
    ``descriptor_radius`` (voxels are described as the features are)."""

    label_margin: int
    pins: list
    max_cycles: int
    weld_tolerance: float
    dense_radius: float
    descriptor: str
    descriptor_radius: float


@dataclass(frozen=True)
class Target:
    """The size asked for (config section ``target``; at most one given): ``steps`` per principal
    offset, ``axis_steps`` along the principal offset nearest each named world axis
    (``{"x": 2}``), or a ``scale`` factor per principal offset. None of them: one step along the
    first principal offset."""

    steps: list[int] | None
    axis_steps: dict[str, int] | None
    scale: list[float] | None


def options_of(cfg) -> tuple[AnalysisOptions, SynthesisOptions, Target]:
    """The stages' settings from a :class:`~synthkit.methods.retarget.config.RetargetConfig`."""
    keys = cfg.analysis.model_dump()  # every key of the section, by its name
    keys["min_angle"] = np.radians(keys.pop("min_angle_deg"))
    analysis, a = AnalysisOptions(**keys), cfg.analysis
    synthesis = SynthesisOptions(
        label_margin=cfg.label_margin, pins=[(p.voxel, p.shift) for p in cfg.pins], max_cycles=cfg.max_cycles,
        weld_tolerance=cfg.weld_tolerance, dense_radius=a.dense_radius, descriptor=a.descriptor,
        descriptor_radius=a.descriptor_radius,
    )
    t = cfg.target
    return analysis, synthesis, Target(steps=t.steps, axis_steps=t.axis_steps, scale=t.scale)
