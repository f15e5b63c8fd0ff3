"""Config schema of ``synthkit surface-by-numbers`` (Zelinka and Garland, section 3).

Paper defaults: eta = gamma = 1 (eq. 1), no region model (3.4), two to four levels of detail with a
coarsest level of thousands of vertices (3.5). Strokes replace the paper's mouse strokes: per
region, vertex or face indices and polylines in model units snapped to the surface.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from synthkit.config import USD_NEEDS_EXTRA, InputFile, RunConfig, StrictModel

__all__ = [
    "CONFIG", "SurfacingConfig", "Region", "ImageStrokes", "ViewsSection", "BoundarySection", "RegionTermSection",
    "MultiresSection", "TransferSection", "TransferPair", "TargetRegion", "TransferSource", "SynthesisSection",
    "ExtractionSection",
]

Point3 = tuple[float, float, float]


class Region(StrictModel):
    """One region the user wants, with the strokes inside its body (any mix of the three kinds)."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$", description="Region name (file names, report).")
    color: tuple[int, int, int] | None = Field(
        None, description="RGB 0-255 of the region in previews and labels.ply; null = a palette colour."
    )
    vertices: list[int] = Field(default_factory=list, description="Stroked vertex indices (0-based).")
    faces: list[int] = Field(default_factory=list, description="Stroked face indices (0-based).")
    points: list[list[Point3]] = Field(
        default_factory=list,
        description="Polylines [[x, y, z], ...] in model units (one polyline, or a list of them), sampled "
        "densely and snapped to the surface.",
    )

    @field_validator("points", mode="before")
    @classmethod
    def _one_or_many(cls, value):
        if isinstance(value, list) and value and isinstance(value[0], list | tuple):
            if value[0] and isinstance(value[0][0], int | float):
                return [value]
        return value

    @field_validator("color")
    @classmethod
    def _rgb(cls, value):
        if value is not None and any(not 0 <= c <= 255 for c in value):
            raise ValueError(f"colour components must lie in [0, 255], got {list(value)}")
        return value


ViewName = Literal["front", "back", "left", "right", "top", "bottom", "iso"]


class ImageStrokes(StrictModel):
    """A PNG painted over the render of a named view (``views/<view>.png`` of a run with
    ``views.render: true`` or ``mode: views``), one colour per region, read back through the
    face-ID buffer of the same camera."""

    image: InputFile = Field(description="The painted PNG, the size of the view (views.size).")
    view: ViewName = Field(description="The view it was painted over.")
    colors: dict[str, tuple[int, int, int]] = Field(
        min_length=1, description="Region name -> the RGB (0-255) its strokes are painted in."
    )
    tolerance: float = Field(
        0.1, gt=0, le=1, description="Largest channel difference (0-1) from the render (unpainted) and from a colour "
        "blended over the render (paint)."
    )
    opacity: float = Field(
        0.25, gt=0, le=1, description="Least opacity of a painted pixel read as a stroke: a soft or semi-transparent "
        "brush leaves render + alpha (colour - render); fainter pixels (brush edges) are ignored and counted."
    )


class ViewsSection(StrictModel):
    """Renders of the named views with their cameras, for painting strokes."""

    render: bool = Field(False, description="Write views/<view>.png and views/<view>.json (CLI --render-views).")
    size: int = Field(512, ge=64, le=4096, description="Side of the view renders in pixels (and of painted PNGs).")
    names: list[ViewName] = Field(
        default_factory=lambda: ["front", "back", "left", "right", "top", "bottom", "iso"],
        min_length=1, description="Views to render.",
    )


class BoundarySection(StrictModel):
    """Boundary cost, eq. 1: e_ij = eta (2 pi - theta_ij) / 2 pi + gamma d_ij / d_mean."""

    eta: float = Field(1.0, ge=0, le=100, description="Weight of the dihedral-angle term (paper: 1).")
    gamma: float = Field(1.0, ge=0, le=100, description="Weight of the edge-length term (paper: 1).")


class RegionTermSection(StrictModel):
    """Region cost (3.4): none (the paper), geodesic distance to the strokes, or stroke colours."""

    model: Literal["none", "geodesic", "color"] = Field(
        "geodesic",
        description="none = boundary costs only (the paper's choice); geodesic = normalised edge-graph distance "
        "to each region's strokes; color = k-means of each region's stroked colours (Lazy Snapping).",
    )
    weight: float = Field(
        0.5, ge=0, le=1e4, description="Balance of the region term against the boundary term (per unit node area)."
    )
    concavity: float = Field(
        1e5,
        ge=0,
        le=1e6,
        description="model: geodesic: extra length of a step across a concave edge, in mean edge lengths times "
        "1 - cos(bending angle) (0 = plain edge-graph distance).",
    )
    trust: float = Field(
        2.0,
        ge=0,
        le=100,
        description="model: geodesic: the term acts at a node only where its nearest region's strokes are more than "
        "`trust` times nearer than the next region's (full weight from 1.5 x trust; between, the boundary term alone "
        "places the cut); 0 = everywhere.",
    )
    wall_deg: float = Field(
        30.0,
        ge=0,
        le=180,
        description="model: geodesic or color: a part closed off by concave creases sharper than this (degrees) "
        "that holds strokes takes only the regions stroked in it (no leak across a strong crease); 180 = off.",
    )
    clusters: int = Field(64, ge=1, le=1024, description="k-means clusters per region for model: color (paper: 64).")


class MultiresSection(StrictModel):
    """Multiresolution solve (3.5): quadric LOD hierarchy, coarse cut, bands of free nodes."""

    enabled: bool = Field(True, description="Use the hierarchy when the graph has more than coarsest_nodes nodes.")
    coarsest_nodes: int = Field(
        8000, ge=100, le=1_000_000,
        description="Stop coarsening at this many graph nodes (paper: thousands to 10^4 vertices; a face graph has "
        "about two nodes per vertex).",
    )
    ratio: float = Field(0.25, gt=0.01, lt=1, description="Vertices kept from one level to the next coarser one.")
    max_levels: int = Field(4, ge=1, le=4, description="At most this many levels including the finest (paper: 2-4).")
    band_rings: int = Field(2, ge=1, le=20, description="Rings around the coarser cut left free at each finer level.")
    crease_deg: float = Field(
        30.0, ge=0, le=180, description="No cluster spans a concave edge bent more than this (degrees; 180 = off)."
    )


class TargetRegion(StrictModel):
    """Where a transfer goes: a region of the top-level ``regions`` (segmented from their strokes,
    as mode segment does), or a label of a labels file from an earlier segment run."""

    region: str | None = Field(None, description="Name of a region in the top-level regions (strokes).")
    labels: InputFile | None = Field(None, description="labels.seg or labels.ply of an earlier segment run.")
    label: int | None = Field(None, ge=0, description="The label in labels (0-based, as labels.seg writes it).")

    @model_validator(mode="after")
    def _one_way(self):
        if (self.region is None) == (self.labels is None):
            raise ValueError("give either region (a stroked region's name) or labels with label")
        if self.labels is not None and self.label is None:
            raise ValueError("labels needs label (the region's label in the file)")
        return self


class TransferSource(StrictModel):
    """Where the detail comes from: a region of a mesh (the target mesh itself when ``mesh`` is
    null) or a region of an image (``mask`` or ``rect``; a flat surface with a colour signal)."""

    mesh: InputFile | None = Field(None, description="Source mesh; null = the target mesh (input).")
    regions: list[Region] = Field(
        default_factory=list, description="Strokes segmenting the source mesh (when mesh is given), as in mode segment."
    )
    region: str | None = Field(None, description="Source region: a name in regions (or, without mesh, in the "
                               "top-level regions); null with no labels = the whole mesh.")
    labels: InputFile | None = Field(None, description="labels.seg or labels.ply of the source mesh.")
    label: int | None = Field(None, ge=0, description="The source region's label in labels.")
    image: InputFile | None = Field(None, description="Source image (instead of a mesh).")
    mask: InputFile | None = Field(None, description="PNG the size of image; non-black pixels are the region.")
    rect: tuple[int, int, int, int] | None = Field(
        None, description="Region [x0, y0, x1, y1] in pixels (x1, y1 excluded)."
    )
    width: float = Field(1.0, gt=0, description="Source units the image's width spans.")
    up: Point3 = Field((0.0, 1.0, 0.0), description="With synthesis.orientation: up, the source's up direction "
                       "(an image's is +y, its rows upwards).")
    resolution: int = Field(192, ge=8, le=2048, description="Grid cells along the image's longer side.")

    @model_validator(mode="after")
    def _one_kind(self):
        if self.image is not None and (self.mesh is not None or self.region or self.labels is not None):
            raise ValueError("an image source takes mask or rect, not mesh, region or labels")
        if self.image is None and (self.mask is not None or self.rect is not None):
            raise ValueError("mask and rect need image")
        if self.mask is not None and self.rect is not None:
            raise ValueError("give mask or rect, not both")
        if self.labels is not None and self.label is None:
            raise ValueError("labels needs label (the region's label in the file)")
        return self


class TransferPair(StrictModel):
    """One (target region, source) correspondence with its signal and scale."""

    target: TargetRegion
    source: TransferSource
    signal: Literal["color", "texture", "displacement", "attribute"] = Field(
        "color", description="color = vertex colours; texture = the texture through UVs (images: the image); "
        "displacement = geometric detail (4.6); attribute = the PLY vertex property named by attribute."
    )
    attribute: str | None = Field(None, description="PLY vertex property (or NAME_* columns) for signal: attribute.")
    scale: float = Field(1.0, description="Target units per source unit (the paper's global scale); > 0.")

    @model_validator(mode="after")
    def _attribute(self):
        if (self.signal == "attribute") != (self.attribute is not None):
            raise ValueError("signal: attribute goes with attribute: NAME (and attribute only with it)")
        if not self.scale > 0:
            raise ValueError(f"scale must be positive, got {self.scale}")
        return self


class SynthesisSection(StrictModel):
    """The four steps of section 4 and their stopping rule."""

    patch_radius: float | None = Field(
        None, gt=0, description="Patch radius in target units; null = 0.3 sqrt(min(source area x scale^2, target "
        "area)), at least three mean target edges, at most 0.9 sqrt(source area / pi)."
    )
    bound: float = Field(2.0, le=10, description="Distortion bound max(s1, 1/s2) of every patch triangle "
                         "(paper: 1.5 to 3, 2 by default); at least 1.")
    matching: Literal["fans", "random"] = Field("fans", description="fans = geodesic-fan matching (4.2); random = "
                                                "random source face and rotation (the paper's other option).")
    parameterization: Literal["vector_heat", "exp_map"] = Field(
        "vector_heat", description="Log maps the patches are laid out by (4.3): vector_heat = potpourri3d's "
        "vector heat log map of the whole surface (one factorization per surface, then two solves per map); "
        "exp_map = the discrete exponential map (Schmidt et al. 2006, faces unfolded) over the vertices a patch "
        "reaches only (faster; seams cost more on curved targets).")
    trimming: Literal["graphcut", "none"] = Field("graphcut", description="graphcut = dual-graph min cut with seam "
                                                  "nodes (4.4); none = a patch overwrites all it covers.")
    orientation: Literal["free", "up"] = Field(
        "free", description="free = any rotation (the paper's orientation-independent matching); up = frames follow "
        "synthesis.up on the target and source.up on the source and only the unrotated match is allowed."
    )
    up: Point3 = Field((0.0, 1.0, 0.0), description="The target's up direction for orientation: up.")
    spokes: int = Field(8, ge=3, le=64, description="Geodesics per fan.")
    steps: int = Field(4, ge=1, le=32, description="Samples per geodesic.")
    fan_share: float = Field(0.5, gt=0, le=2, description="Fan radius as a share of the patch radius.")
    tolerance: float = Field(0.1, ge=0, le=10, description="Choose among positions and matches within (1 + tolerance) "
                             "of the best.")
    edge_samples: int = Field(4, ge=1, le=64, description="Samples per edge of the seam path integral.")
    max_patches: int = Field(200, ge=1, le=100000, description="Stop after this many kept patches.")
    patience: int = Field(5, ge=1, le=1000, description="Stop once covered and the seam cost has not fallen for this "
                          "many iterations.")

    @field_validator("bound")
    @classmethod
    def _bound(cls, value):
        if value < 1:
            raise ValueError(f"distortion bound must be at least 1, got {value}")
        return value


class ExtractionSection(StrictModel):
    """Extraction (4.5) and blending."""

    sampling: Literal["linear", "nearest"] = Field(
        "linear", description="linear = barycentric (bilinear in textures, prefiltered by a Gaussian of half the "
        "target's mean edge); nearest = the nearest source value (corner or texel, no prefilter)."
    )
    blend: Literal["poisson", "kernel", "none"] = Field(
        "poisson", description="poisson = vertex values whose gradients match each patch's own, seams' jumps spread "
        "over about 10 edge lengths (Poisson blending); kernel = area-weighted average of the corners at each vertex "
        "(across patch seams); none = one corner's value. poisson and kernel average the region's border with the "
        "target's own colours. Textures through UVs: poisson and kernel level the texture to these vertex values, "
        "feather it across seams and bake it into an atlas (transferred_transfer_<k>.png); none keeps UVs into the "
        "source image."
    )
    feather: float = Field(
        0.2, ge=0, le=1, description="Textures (blend poisson or kernel): each patch's texture fades out over this "
        "share of the patch radius beyond its own faces, where it maps, so seams cross-fade; 0 = the leveling alone."
    )
    subdivide: int = Field(0, ge=0, le=4, description="Midpoint (1-to-4) subdivision steps of the whole target "
                           "before synthesis, so vertex values can hold finer detail (4.5's refinement, uniform).")
    refine_tolerance: float | None = Field(
        None, gt=0, description="Adaptive refinement (4.5): bisect edges where the signal at an edge midpoint or face "
        "centre differs from the linear reconstruction by more than this (signal units; null = off)."
    )
    refine_levels: int = Field(2, ge=1, le=4, description="At most this many refinement steps.")
    smoothing: float | None = Field(
        None, gt=0, description="Smoothing length (source units) of the smoothed source whose difference is the "
        "displacement field; null = 5% of the source's bounding-box diagonal."
    )


class TransferSection(StrictModel):
    """mode: transfer (section 4)."""

    pairs: list[TransferPair] = Field(min_length=1, description="(target region, source) pairs, done in order.")
    synthesis: SynthesisSection = Field(default_factory=SynthesisSection)
    extraction: ExtractionSection = Field(default_factory=ExtractionSection)
    baseline: bool = Field(False, description="Also run matching: random, trimming: none with the same number of "
                           "patches and report its seam cost (baseline_seam_cost); off by default: it costs as "
                           "much as the run.")


class OutputSection(StrictModel):
    """How mode transfer writes the transferred mesh."""

    mesh_format: Annotated[Literal["input", "usd", "usda"], USD_NEEDS_EXTRA] = Field(
        "input", description="mode transfer: input = transferred.obj + .mtl for texture signals and, for "
        "displacement, the displaced mesh in the input's format; usd writes transferred.usdc instead (usda: text "
        ".usda), with its colours, UVs and UsdPreviewSurface materials, their textures beside it (the usd extra). "
        "transferred.ply is written either way.",
    )


class SurfacingConfig(RunConfig):
    """``synthkit surface-by-numbers``: region-centric segmentation by graph cut (mode: segment)."""

    method: Literal["surface-by-numbers"] = "surface-by-numbers"
    mode: Literal["segment", "views", "transfer"] = Field(
        "segment", description="segment = cut the mesh into the stroked regions; views = only write the view renders; "
        "transfer = synthesize detail over target regions from sources (section 4)."
    )
    input: InputFile = Field(description="Input mesh (OBJ, PLY, GLB, OFF, STL).")
    regions: list[Region] = Field(
        default_factory=list, description="The regions, each with its strokes (at least two for mode: segment)."
    )
    images: list[ImageStrokes] = Field(default_factory=list, description="Painted views adding strokes to regions.")
    views: ViewsSection = Field(default_factory=ViewsSection)
    graph: Literal["vertex", "face"] = Field(
        "face",
        description="vertex = the paper's graph (3.2), one node per vertex, faces by the corner-majority rule; "
        "face = the dual graph, one node per face, cut along mesh edges.",
    )
    boundary: BoundarySection = Field(default_factory=BoundarySection)
    region_term: RegionTermSection = Field(default_factory=RegionTermSection)
    multires: MultiresSection = Field(default_factory=MultiresSection)
    points_tolerance: float = Field(
        0.01, gt=0, le=1, description="Farthest a stroke point may lie from the surface (share of bbox diagonal)."
    )
    compare_single_level: bool = Field(False, description="Also solve on the full graph and report its cut cost.")
    smooth_cut: int = Field(
        0, ge=0, le=1000,
        description="Taubin smoothing steps of the exported boundary curves (cut_smooth.obj; 0 = off, the paper's "
        "cut along mesh edges). Face labels are not changed.",
    )
    preview_size: int = Field(512, ge=64, le=4096, description="Side of the PNG previews in pixels.")
    transfer: TransferSection | None = Field(None, description="mode: transfer: the pairs and the synthesis settings.")
    output: OutputSection = Field(default_factory=OutputSection)

    @model_validator(mode="after")
    def _unique_names(self):
        names = [r.name for r in self.regions]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"region names must be unique, got {', '.join(dup)} twice")
        if self.mode == "segment" and len(names) < 2:
            raise ValueError(f"regions: mode segment needs at least two regions (got {len(names)})")
        if self.mode == "transfer":
            self._check_transfer(names)
        elif self.output.mesh_format != "input":
            raise ValueError(f"output.mesh_format: {self.output.mesh_format} applies to mode transfer (mode "
                             f"{self.mode} writes its meshes in the input's format)")
        for k, item in enumerate(self.images):
            unknown = sorted(set(item.colors) - set(names))
            if unknown:
                raise ValueError(f"images[{k}].colors: {unknown[0]!r} is not a region (regions: {', '.join(names)})")
        return self


    def _check_transfer(self, names: list[str]) -> None:
        if self.transfer is None:
            raise ValueError("transfer: mode transfer needs a transfer section with pairs")
        for k, pair in enumerate(self.transfer.pairs):
            used = [("target", pair.target.region)]
            if pair.source.mesh is None:
                used.append(("source", pair.source.region))
            for side, name in used:
                if name is not None and name not in names:
                    raise ValueError(f"transfer.pairs[{k}].{side}.region: {name!r} is not a region "
                                     f"(regions: {', '.join(names) or 'none'})")
            if any(name is not None for _, name in used) and len(names) < 2:
                raise ValueError(f"regions: segmenting the target needs at least two regions (got {len(names)})")


CONFIG = SurfacingConfig
