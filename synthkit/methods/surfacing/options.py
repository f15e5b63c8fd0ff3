"""The one map from the keys of a surface-by-numbers config to the arguments of its stages: the
segmentation's :class:`~synthkit.methods.surfacing.segment.Options`, each transfer pair's
:class:`~synthkit.methods.surfacing.transfer.synth.Options` and the region colours."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.methods.surfacing.segment import Options
from synthkit.methods.surfacing.transfer import synth
from synthkit.preview import SET1

__all__ = ["SurfacingOptions", "options_of", "region_colors", "stroke_colors"]


@dataclass(frozen=True)
class SurfacingOptions:
    """Every stage's options of one config (:func:`options_of`): the segmentation's (``segment``),
    and each transfer pair's synthesis, which :meth:`synthesis` completes with its patch radius."""

    segment: Options
    synthesis_of: tuple[dict, ...]

    def synthesis(self, k: int, radius: float) -> synth.Options:
        """Synthesis options of ``transfer.pairs[k]`` with the patch ``radius`` the pipeline chose."""
        return synth.Options(patch_radius=radius, **self.synthesis_of[k])


def options_of(cfg) -> SurfacingOptions:
    """The :class:`SurfacingOptions` of a config: ``graph``, ``boundary``, ``region_term`` and
    ``multires`` for the segmentation, ``transfer.synthesis`` and each pair's ``scale`` for its synthesis."""
    m, r = cfg.multires, cfg.region_term
    segment = Options(
        graph=cfg.graph, eta=cfg.boundary.eta, gamma=cfg.boundary.gamma, region_model=r.model,
        region_weight=r.weight, concavity=r.concavity, trust=r.trust, wall_deg=r.wall_deg, clusters=r.clusters,
        multires=m.enabled,
        coarsest_nodes=m.coarsest_nodes, ratio=m.ratio, max_levels=m.max_levels, band_rings=m.band_rings,
        crease_deg=m.crease_deg, compare_single_level=cfg.compare_single_level,
    )
    if cfg.transfer is None:
        return SurfacingOptions(segment, ())
    syn = cfg.transfer.synthesis
    shared = dict(bound=syn.bound, matching=syn.matching, parameterization=syn.parameterization,
                  trimming=syn.trimming, spokes=syn.spokes, steps=syn.steps, fan_share=syn.fan_share,
                  tolerance=syn.tolerance, edge_samples=syn.edge_samples, max_patches=syn.max_patches,
                  patience=syn.patience, fixed_orientation=syn.orientation == "up")
    return SurfacingOptions(segment, tuple({"scale": pair.scale, **shared} for pair in cfg.transfer.pairs))


def region_colors(cfg) -> np.ndarray:
    """``(L, 3) uint8`` colour of each region: its ``color``, else the colour it is painted in (the first
    image that lists it), else the palette's (:data:`synthkit.preview.SET1`)."""
    painted = {}
    for item in cfg.images:
        for name, rgb in item.colors.items():
            painted.setdefault(name, rgb)
    return np.array([r.color if r.color is not None else painted.get(r.name, SET1[k % len(SET1)])
                     for k, r in enumerate(cfg.regions)], dtype=np.uint8)


def stroke_colors(cfg, k: int) -> np.ndarray:
    """``(L, 3)`` float RGB in [0, 1] each region is painted in on ``images[k]`` (NaN: not painted there)."""
    names = [r.name for r in cfg.regions]
    colors = np.full((len(names), 3), np.nan)
    for name, rgb in cfg.images[k].colors.items():
        colors[names.index(name)] = np.asarray(rgb) / 255.0
    return colors
