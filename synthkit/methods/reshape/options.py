"""The one map from ``synthkit reshape``'s config keys to the stages' arguments.

Stage modules take these dataclasses (or plain arrays), never the config. :func:`options_of` builds
them all: :class:`GraphOptions` (:mod:`graph`, :mod:`assemble`), :class:`SystemOptions`
(:mod:`system`), :class:`DragOptions` (:mod:`solver`), :class:`PartsOptions` (:mod:`parts`,
:mod:`resize`) and :class:`TextureOptions` (:mod:`retexture`). The selections (``handles``,
``fixed``, ``links``, ``scale``, ``size``, ``chain``) are passed as the config gives them.
"""

from __future__ import annotations

from dataclasses import dataclass

from synthkit.methods.reshape.texture.surface import TextureParams

__all__ = ["Options", "options_of", "GraphOptions", "PartsOptions", "TextureOptions", "DragOptions",
           "SystemOptions"]

PARAM_KEYS = ("delta", "neighbourhood", "spacing", "s_min", "s_align", "t_max", "samples", "corner_form", "tau",
              "smoothness", "edge_sigma", "tries", "tile_search", "min_tile", "regions", "clusters", "sigma_s",
              "sigma_r", "ramp", "max_side")
"""Keys of ``texture_reshape`` that are :class:`TextureParams` fields of the same name."""


@dataclass(frozen=True)
class TextureOptions:
    """The texture stage's options.

    Attributes
    ----------
    mode : ``texture``: "continue", "reshape" or "stretch"
    params : section 4's parameters (``texture_reshape``, with ``solver.backend``)
    toroidal : ``texture_reshape.toroidal``: "auto" or the materials whose textures tile
    unchanged_texels : ``texture_reshape.unchanged_texels``
    """

    mode: str
    params: TextureParams
    toroidal: str | tuple[str, ...]
    unchanged_texels: float


def _texture(cfg) -> TextureOptions:
    """The :class:`TextureOptions` of a :class:`~synthkit.methods.reshape.config.ReshapeConfig`."""
    t = cfg.texture_reshape
    params = TextureParams(**{n: getattr(t, n) for n in PARAM_KEYS}, backend=cfg.solver.backend)
    toroidal = t.toroidal if isinstance(t.toroidal, str) else tuple(t.toroidal)
    return TextureOptions(cfg.texture, params, toroidal, t.unchanged_texels)


@dataclass(frozen=True)
class DragOptions:
    """How the handles are dragged (``solver``): ``steps``, eq. 4's ``short_ratio`` and
    ``raise_factor``, the ``flip_ratio`` that refuses a motion, the factorization ``backend``, the
    ``propagation`` limit (joins; None: none) and whether a refused motion keeps its last valid
    step (``allow_partial``)."""

    steps: int
    short_ratio: float
    raise_factor: float
    flip_ratio: float
    backend: str
    propagation: int | None
    allow_partial: bool


def _drag(cfg) -> DragOptions:
    """The :class:`DragOptions` of a config: one step for a resize (its rest shape is the target)."""
    sv = cfg.solver
    steps = 1 if cfg.handles == [] else sv.steps
    return DragOptions(steps, sv.short_ratio, sv.raise_factor, sv.flip_ratio, sv.backend, sv.propagation,
                       sv.allow_partial)


@dataclass(frozen=True)
class SystemOptions:
    """The constraint rows of section 3.2: ``stiffness`` (``l_min`` or its ``l_min_quantile``,
    ``w_small``, ``w_long``), ``strict`` (``strict_weight``, ``direction_form``), ``contacts``
    (on/off, ``contact_tol``, ``w_c``) and ``groups`` (on/off, ``group_angle_deg``,
    ``group_length_tol``, ``group_distance``, ``w_g``)."""

    l_min: float | None
    l_min_quantile: float
    w_small: float
    w_long: float
    strict_weight: float
    direction_form: str
    contacts: bool
    contact_tol: float
    w_c: float
    groups: bool
    group_angle_deg: float
    group_length_tol: float
    group_distance: float
    w_g: float


def _system(cfg) -> SystemOptions:
    """The :class:`SystemOptions` of a config."""
    st, c, g = cfg.stiffness, cfg.contacts, cfg.groups
    return SystemOptions(st.l_min, st.l_min_quantile, st.w_small, st.w_long, cfg.strict.weight,
                         cfg.strict.direction_form, c.enabled, c.tol, c.w_c, g.enabled, g.angle_deg, g.length_tol,
                         g.distance, g.w_g)


@dataclass(frozen=True)
class GraphOptions:
    """The constraint graph (``graph``): ``weld_tol`` and the portals' ``portal_tol`` (shares of the
    model size) and ``flat_angle_deg``."""

    weld_tol: float
    flat_angle_deg: float
    portal_tol: float


@dataclass(frozen=True)
class PartsOptions:
    """How parts stay attached and resize (``parts``): ``attach_distance`` (share of the model
    size), ``rigid_share`` and ``end_tol`` (shares of the extent)."""

    attach_distance: float
    rigid_share: float
    end_tol: float


@dataclass(frozen=True)
class Options:
    """Every stage's options of one config (:func:`options_of`)."""

    graph: GraphOptions
    system: SystemOptions
    drag: DragOptions
    parts: PartsOptions
    texture: TextureOptions


def options_of(cfg) -> Options:
    """The :class:`Options` of a :class:`~synthkit.methods.reshape.config.ReshapeConfig`."""
    g, p = cfg.graph, cfg.parts
    return Options(GraphOptions(g.weld_tol, g.flat_angle_deg, g.portal_tol), _system(cfg), _drag(cfg),
                   PartsOptions(p.attach_distance, p.rigid_share, p.end_tol), _texture(cfg))
