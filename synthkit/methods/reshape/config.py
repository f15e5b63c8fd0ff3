"""Config schema of ``synthkit reshape`` (paper defaults from Cabral et al. 2009, sections 3 and 5).

Lengths are in model units unless a field says "relative" (a share of the model's bounding-box
diagonal). A config reshapes either one ``input`` or a chain of ``pieces`` joined at portals.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from synthkit.config import USD_NEEDS_EXTRA, InputFile, RunConfig, StrictModel

__all__ = ["CONFIG", "ReshapeConfig", "Box", "HalfSpace", "Selection", "Handle", "Link", "PieceSpec", "Join",
           "GraphSection", "StiffnessSection", "StrictSection", "ContactSection", "GroupSection", "SolverSection",
           "TextureSection", "AxisValues", "PartsSection"]

Vec3 = list[float]


class Box(StrictModel):
    """An axis-aligned box of model space."""

    min: Vec3 = Field(min_length=3, max_length=3, description="Lower corner (x, y, z).")
    max: Vec3 = Field(min_length=3, max_length=3, description="Upper corner (x, y, z).")

    @model_validator(mode="after")
    def _ordered(self):
        if any(a > b for a, b in zip(self.min, self.max, strict=True)):
            raise ValueError(f"box min {self.min} must not exceed max {self.max}")
        return self


class HalfSpace(StrictModel):
    """Every vertex with ``coordinate >= above`` (or ``<= below``) along ``axis``."""

    axis: Literal["x", "y", "z"] = Field(description="Coordinate axis.")
    above: float | None = Field(None, description="Select vertices at or above this coordinate.")
    below: float | None = Field(None, description="Select vertices at or below this coordinate.")

    @model_validator(mode="after")
    def _one(self):
        if (self.above is None) == (self.below is None):
            raise ValueError("give exactly one of above, below")
        return self


class Selection(StrictModel):
    """Vertices chosen one way: by file index, nearest to points, in a box, or in a half-space."""

    piece: str | None = Field(
        None, description="Piece the selection applies to (chains; default: every piece, or the first for index)."
    )
    index: list[int] | None = Field(
        None, min_length=1, description="Vertex indices of the file (OBJ 'v' order or GLB vertices, 0-based)."
    )
    nearest: list[Vec3] | None = Field(None, min_length=1, description="The vertex nearest each of these points.")
    box: Box | None = Field(None, description="Every vertex inside this box.")
    half_space: HalfSpace | None = Field(None, description="Every vertex on one side of an axis-aligned plane.")

    @model_validator(mode="after")
    def _exactly_one(self):
        given = [k for k in ("index", "nearest", "box", "half_space") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of index, nearest, box, half_space (got {', '.join(given) or 'none'})")
        if self.nearest is not None and any(len(p) != 3 for p in self.nearest):
            raise ValueError("nearest points must have 3 coordinates")
        return self


class AxisValues(StrictModel):
    """One positive value per axis; axes left out keep their size."""

    x: float | None = Field(None, gt=0, le=1e6, description="Along x.")
    y: float | None = Field(None, gt=0, le=1e6, description="Along y.")
    z: float | None = Field(None, gt=0, le=1e6, description="Along z.")

    @model_validator(mode="after")
    def _some(self):
        if self.x is None and self.y is None and self.z is None:
            raise ValueError("give at least one of x, y, z")
        return self

    def values(self) -> list[float | None]:
        """``[x, y, z]`` with None for an axis not given."""
        return [self.x, self.y, self.z]


class PartsSection(StrictModel):
    """How parts (face-connected pieces: walls, windows, doors, frames, railings) stay attached."""

    attach_distance: float = Field(
        0.05, gt=0, le=1,
        description="A part within this distance of another part's surface is attached to it (relative); "
        "farther parts are still carried by the nearest surface and listed in metrics.free_parts. 0.05 covers "
        "the chimneys of the real houses (up to 0.034 above their roofs).",
    )
    rigid_share: float = Field(
        0.45, ge=0, le=1,
        description="With scale/size: a part shorter than this share of the model along an axis keeps its "
        "size along it (doors, windows: up to 0.39 on the real houses); longer parts (drainpipes, 0.51) stretch.",
    )
    end_tol: float = Field(
        1e-3, gt=0, le=0.1,
        description="With scale/size: vertices within this share of the extent of either end of a scaled axis "
        "become the handles and fixed vertices.",
    )


class Handle(Selection):
    """Handle vertices and where they go: a ``target`` for their centroid, or a ``displacement``."""

    target: Vec3 | None = Field(None, min_length=3, max_length=3, description="Final position of the centroid.")
    displacement: Vec3 | None = Field(None, min_length=3, max_length=3, description="Motion of every vertex.")

    @model_validator(mode="after")
    def _one_motion(self):
        if (self.target is None) == (self.displacement is None):
            raise ValueError("give exactly one of target, displacement")
        return self


class Link(Selection):
    """A user link (Fig. 6): the two vertices selected (by ``index`` or ``nearest``) move together."""

    @model_validator(mode="after")
    def _two(self):
        chosen = self.index if self.index is not None else self.nearest
        if chosen is None or len(chosen) != 2:
            raise ValueError("a link selects exactly two vertices by index or nearest")
        return self


class PieceSpec(StrictModel):
    """One piece of a chain."""

    name: str = Field(min_length=1, description="Name used by chain, handles and output files.")
    input: InputFile = Field(description="Textured mesh (OBJ+MTL or GLB).")
    portals: dict[str, list[int]] = Field(
        default_factory=dict,
        description="Extra portals by file vertex index; end planes 'x-', 'x+', ... and boundary loops "
        "'loop0', 'loop1', ... are detected.",
    )

    @field_validator("name")
    @classmethod
    def _plain_file_name(cls, name: str) -> str:
        """The name becomes output file names (``<name>.obj``): a plain file name, no folder part."""
        if name in (".", "..") or any(c in name for c in "/\\\0") or name != name.strip():
            raise ValueError("must be a plain file name (no '/', '\\', '..' or surrounding spaces)")
        return name


class Join(StrictModel):
    """Piece ``b``'s portal ``b_portal`` is joined to piece ``a``'s portal ``a_portal`` (b is moved)."""

    a: str = Field(description="Piece already placed.")
    a_portal: str = Field(description="Portal of a ('x+', 'loop0' ... or a name from its portals).")
    b: str = Field(description="Piece placed by this join.")
    b_portal: str = Field(description="Portal of b.")


class GraphSection(StrictModel):
    """Constraint graph (3.1)."""

    weld_tol: float = Field(1e-6, gt=0, le=1e-2, description="Co-located vertices share a node (relative).")
    flat_angle_deg: float = Field(
        0.5, ge=0, le=10, description="Triangles whose normals differ by at most this are coplanar (flat edge)."
    )
    portal_tol: float = Field(
        1e-6, gt=0, le=1e-2, description="Distance of a portal vertex to its end plane (relative)."
    )


class StiffnessSection(StrictModel):
    """Edge stress (eq. 2) with stiffness eq. 3; l_min is the one parameter the paper adapts per model."""

    l_min: float | None = Field(None, gt=0, description="Edges shorter than this are rigid (model units); null: the "
                                  "l_min_quantile of the edge lengths.")
    l_min_quantile: float = Field(
        0.25, ge=0, le=1, description="When l_min is not given: this quantile of the graph's edge lengths."
    )
    w_small: float = Field(1e-3, gt=0, le=1, description="Stiffness at l_min (paper 1e-3).")
    w_long: float = Field(1e-5, gt=0, le=1, description="Stiffness of the longest edge (paper 1e-5).")


class StrictSection(StrictModel):
    """Strict constraints enter the least squares with a large weight [Loa85]."""

    weight: float = Field(
        1e4, gt=0, le=1e8,
        description="Weight of strict rows (eq. 1, 5, links) on squared residuals; residuals fall like 1 / weight.",
    )
    direction_form: Literal["vertex", "edge"] = Field(
        "vertex", description="Eq. 1 per vertex (paper) or one 3-row constraint per edge."
    )


class ContactSection(StrictModel):
    """Contacts (eq. 5 strict coplanarity, eq. 6 soft position)."""

    enabled: bool = Field(True, description="Detect vertices of one component on a triangle of another.")
    tol: float = Field(1e-6, gt=0, le=1e-2, description="Distance of a vertex to the triangle (relative).")
    w_c: float = Field(1e-5, gt=0, le=1, description="Weight of the contact position rows (paper 1e-5).")


class GroupSection(StrictModel):
    """Edge groups (eq. 7): similar direction, similar length, close together."""

    enabled: bool = Field(True, description="Add edge-group rows (switch off to see Fig. 5's distortion).")
    w_g: float = Field(
        0.1, gt=0, le=1,
        description="Group weight: the paper gives 0.1 (3.2) and 1e-2 (3.3); 0.1 keeps risers equal within 1e-4.",
    )
    angle_deg: float = Field(2.0, ge=0, le=45, description="Largest angle between grouped edges.")
    length_tol: float = Field(0.05, ge=0, le=1, description="Largest length difference, share of the longer edge.")
    distance: float = Field(
        2.0, gt=0, le=100, description="Largest distance between grouped edge midpoints, in edge lengths."
    )


class SolverSection(StrictModel):
    """Solver (3.3) and the collapse check (3.4)."""

    steps: int = Field(10, ge=1, le=10000, description="Handles move in this many equal increments.")
    backend: Literal["auto", "cholespy", "splu"] = Field("auto", description="Sparse factorization.")
    short_ratio: float = Field(
        0.2, ge=0, lt=1, description="An edge shorter than this share of its rest length gets l_ki raised."
    )
    raise_factor: float = Field(1.5, gt=1, le=100, description="Factor applied to l_ki of a too-short edge.")
    flip_ratio: float = Field(
        1e-3, ge=0, lt=1, description="An edge at or below this share of its rest length has collapsed (eq. 4)."
    )
    propagation: int | None = Field(
        None, ge=0,
        description="While dragging a chain, only pieces at most this many joins from a handle's piece move; "
        "the last step (release) solves the whole chain (section 5). None: the whole chain at every step.",
    )
    allow_partial: bool = Field(
        False, description="On a refused motion write the last valid step (metrics.status: partial) instead of exit 3."
    )


class TextureSection(StrictModel):
    """Texture reshape (section 4), used with ``texture: reshape``. Autosimilarity maps are in the
    units of the equalized luminance (zero mean, unit variance per texture)."""

    delta: int = Field(10, ge=1, le=64, description="Delta of eq. 9: texels searched each way (paper 10).")
    neighbourhood: int = Field(5, ge=1, le=31, description="Side of the neighbourhoods N(p) of eq. 9 (paper 5).")
    spacing: float = Field(
        1 / 32, gt=0, le=0.5, description="Grid spacing, share of the texture side (paper 1/32); at least one texel."
    )
    s_min: float = Field(
        0.01, gt=0, le=100,
        description="Stiffness of flat texture areas (eq. 13): 0.01 is about half the autosimilarity of plaster "
        "noise, so stochastic grid edges stretch freely while a door (T about 0.5) is 50x stiffer.",
    )
    s_align: float = Field(
        1.0, ge=0, le=100,
        description="Weight of the orthogonal-alignment term of eq. 13: 1 doubles a rigid edge's resistance to "
        "shearing across the direction, which keeps door and window sides straight.",
    )
    t_max: float | None = Field(
        0.4, gt=0, le=1000,
        description="T_dir is clipped here in eq. 13 (4 tau: rigid texels equally stiff); null: the paper's T.",
    )
    samples: int = Field(
        9, ge=1, le=64, description="T_dir read at this many points of a grid edge, largest kept (1: paper midpoint)."
    )
    corner_form: Literal["contour", "triangles"] = Field(
        "contour", description="Corner solve rows: per contour edge (polygon edges) or the paper's eq. 10 per triangle."
    )
    toroidal: Literal["auto"] | list[str] = Field(
        "auto", description="Materials whose texture repeats; auto: every surface whose UVs leave [0, 1]."
    )
    tau: float = Field(0.1, gt=0, le=100, description="Rigid/stochastic threshold on max_dir T_dir (segmentation).")
    smoothness: float = Field(20.0, ge=0, le=1000, description="Boundary weight of the binary graph cut [BJ01].")
    edge_sigma: float = Field(
        0.5, gt=0, le=10, description="Luminance step (equalized units) at which a cut becomes cheap [BJ01]."
    )
    tries: int = Field(8, ge=1, le=1000, description="Random seeds per stochastic region; the largest tile is kept.")
    tile_search: Literal["spiral", "exact"] = Field(
        "spiral", description="Tile per region: spiral growth from random seeds (paper) or the exact largest rectangle."
    )
    min_tile: int = Field(
        16, ge=1, le=4096,
        description="Tiles thinner than this (texels) are dropped: tiled 4-texel tiles put a seam every 4 texels.",
    )
    regions: Literal["connected", "split"] = Field(
        "connected",
        description="One tile per connected stochastic region (paper), or split them by k-means on local statistics "
        "first (its section 6's multi-label remedy).",
    )
    clusters: int = Field(3, ge=2, le=16, description="k of the k-means with regions: split.")
    sigma_s: float = Field(3.0, gt=0, le=50, description="Bilateral filter spatial sigma (texels).")
    sigma_r: float = Field(0.2, gt=0, le=1, description="Bilateral filter range sigma (intensity).")
    ramp: float = Field(
        0.25, gt=0, le=10, description="Stretch at which tiled detail fully replaces the stretched detail (0.25: 25 %)."
    )
    unchanged_texels: float = Field(
        0.5, ge=0, le=100,
        description="A surface none of whose edges would change by this many texels keeps its texture and UVs.",
    )
    max_side: int = Field(4096, ge=16, le=16384, description="Largest side of a baked texture (texels).")
    previews: int = Field(4, ge=0, le=100, description="Surfaces (largest first) that get texture previews.")


class OutputSection(StrictModel):
    """How the reshaped pieces are written."""

    mesh_format: Annotated[Literal["input", "usd", "usda"], USD_NEEDS_EXTRA] = Field(
        "input", description="input = each piece in its input's format (OBJ with its MTL and textures, or GLB; a "
        "piece given in memory as OBJ); usd writes <piece>.usdc, usda text .usda, with UsdPreviewSurface materials "
        "and their textures (the reshaped surfaces' baked ones included) beside it (the usd extra).",
    )


class ReshapeConfig(RunConfig):
    """``synthkit reshape``: structure-preserving reshape of a textured mesh or a chain of pieces."""

    method: Literal["reshape"] = "reshape"
    input: InputFile | None = Field(None, description="Textured mesh (OBJ+MTL or GLB); or give pieces.")
    pieces: list[PieceSpec] = Field(default_factory=list, description="Pieces of a chain (instead of input).")
    chain: list[Join] = Field(default_factory=list, description="Joins placing each later piece at a portal.")
    scale: AxisValues | None = Field(
        None, description="Resize in one line: factor per axis, e.g. {x: 1.3}; handles and fixed vertices are "
        "chosen at the two ends of the model along each axis.",
    )
    size: AxisValues | None = Field(None, description="Like scale, as the new extent per axis (model units).")
    handles: list[Handle] = Field(
        default_factory=list, description="Moved vertices (at least one), when neither scale nor size is given."
    )
    fixed: list[Selection] = Field(default_factory=list, description="Vertices that keep their position.")
    links: list[Link] = Field(default_factory=list, description="User links between two vertices (Fig. 6).")
    graph: GraphSection = Field(default_factory=GraphSection)
    stiffness: StiffnessSection = Field(default_factory=StiffnessSection)
    strict: StrictSection = Field(default_factory=StrictSection)
    contacts: ContactSection = Field(default_factory=ContactSection)
    groups: GroupSection = Field(default_factory=GroupSection)
    parts: PartsSection = Field(default_factory=PartsSection)
    solver: SolverSection = Field(default_factory=SolverSection)
    baseline: bool = Field(False, description="Also run the Laplacian (edge-vector) baseline with the same handles "
                           "(off by default: a comparison, not part of the result).")
    texture: Literal["continue", "reshape", "stretch"] = Field(
        "continue", description="continue: brick, siding and roof tiles keep their texel scale, the patch continued "
        "by whole periods or, without a clear period (plaster), quilted from its own texels (surfaces whose map is not "
        "affine take reshape); reshape: the paper's section 4; "
        "stretch: UVs kept, the texture follows the geometry (the naive baseline).",
    )
    texture_reshape: TextureSection = Field(default_factory=TextureSection)
    preview_size: int = Field(512, ge=64, le=2048, description="Side of the PNG previews in pixels.")
    view: Literal["front", "top", "side", "iso"] = Field("iso", description="View of the previews.")
    output: OutputSection = Field(default_factory=OutputSection)

    @model_validator(mode="after")
    def _input_or_pieces(self):
        if (self.input is None) == (not self.pieces):
            raise ValueError("give either input or pieces")
        names = [p.name for p in self.pieces]
        if len(set(names)) != len(names):
            raise ValueError(f"piece names must be unique (got {names})")
        given = [k for k in ("handles", "scale", "size") if getattr(self, k)]
        if len(given) != 1:
            raise ValueError(f"give exactly one of handles, scale, size (got {', '.join(given) or 'none'})")
        return self


CONFIG = ReshapeConfig
