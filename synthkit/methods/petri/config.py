"""Config schema of ``synthkit petri-synth``."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from synthkit.config import USD_NEEDS_EXTRA, InputFile, RunConfig, StrictModel
from synthkit.methods.petri.curves import polyline_problem

COORDINATE_LIMIT = 1e9
"""Largest magnitude of a coordinate in model units (keeps lengths and products finite)."""

Coordinate = Annotated[float, Field(ge=-COORDINATE_LIMIT, le=COORDINATE_LIMIT)]
Point2 = tuple[Coordinate, Coordinate]
Point3 = tuple[Coordinate, Coordinate, Coordinate]


def checked_points(pts, info: ValidationInfo):
    """A polyline's points as :func:`curves.polyline_problem` keeps them (None stays None); its
    problem as the validation error."""
    if pts is None:
        return pts
    problem, kept = polyline_problem(pts, bool(info.data.get("closed", False)))
    if problem is not None:
        raise ValueError(problem)
    return kept


class Annotation(StrictModel):
    """The user's rectangle around one self-similar unit in an orthographic view (paper Fig. 2b)."""

    view: Literal["front", "top", "side"] = Field(
        "front",
        description="View the rectangle is drawn in: front = (X, Y) with depth Z, top = (X, Z) with depth Y, "
        "side = (Z, Y) with depth X (world coordinates of the example).",
    )
    rect: tuple[float, float, float, float] = Field(
        description="[x0, y0, x1, y1]: the rectangle in the view's two axes, world units."
    )
    depth_unit: float | None = Field(
        None,
        gt=0,
        description="Lattice unit along the view's depth axis; null = the whole depth is one layer.",
    )

    @model_validator(mode="after")
    def _ordered(self):
        x0, y0, x1, y1 = self.rect
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"rect must have x1 > x0 and y1 > y0, got {list(self.rect)}")
        return self


class Lattice(StrictModel):
    """The lattice that cuts the example into pieces e_ijk: an annotation rectangle or a unit cell."""

    unit: Point3 | None = Field(None, description="Unit cell size (X, Y, Z); alternative to 'annotation'.")
    origin: Point3 | None = Field(
        None, description="A lattice corner (X, Y, Z); null = the example's bounding-box minimum."
    )
    annotation: Annotation | None = Field(None, description="Rectangle drawn in a view (paper Fig. 2b).")
    fit_tolerance: float = Field(
        0.02,
        gt=0,
        le=0.5,
        description="How far (in units) the example's bounding box may end from a lattice plane.",
    )
    caps: Literal["open", "capped"] = Field(
        "open",
        description="Cut faces of the pieces: 'open' (default: neighbouring pieces share their cut "
        "vertices and the result has no interior walls) or 'capped' (each piece closed by planar caps).",
    )

    @model_validator(mode="after")
    def _one_source(self):
        if (self.unit is None) == (self.annotation is None):
            raise ValueError("give exactly one of 'unit' and 'annotation'")
        if self.unit is not None and min(self.unit) <= 0:
            raise ValueError(f"unit sizes must be > 0, got {list(self.unit)}")
        return self


class Labels(StrictModel):
    """Classification of pieces by their feature vectors (eq. 1, Table 1)."""

    tolerance: float = Field(
        0.01,
        ge=0,
        le=0.5,
        description="Pieces share a label when their areas differ by at most this fraction and their "
        "bounding boxes by at most this fraction of the unit, with equal corner flags.",
    )
    match: Literal["features", "geometry"] = Field(
        "features",
        description="'features': the paper's feature vector alone (eq. 1); 'geometry': also require the "
        "pieces' vertices to coincide within the tolerance (tells mirror images apart).",
    )
    boundary: bool = Field(
        True,
        description="Treat the outside of the lattice as a label, so pieces that end the example (walls, "
        "corners) end the result too (Merrell-style; the paper does not say).",
    )
    join_ends: Literal["auto", "always", "never"] = Field(
        "auto",
        description="With 'boundary', let a piece that ends the example along the curve be followed by one "
        "that begins it, so copies of the example stand side by side along the curve. 'auto' (default) "
        "joins only when some row of the example along the curve holds no piece that may repeat: such an "
        "example (a one-bay house: every piece along the curve is a corner) cannot grow past its own "
        "length otherwise, and the paper's users draw curves longer than the example (Fig. 6, 9).",
    )

    @model_validator(mode="after")
    def _join_needs_boundary(self):
        if self.join_ends == "always" and not self.boundary:
            raise ValueError("join_ends: always needs boundary: true (the example ends where it meets the outside)")
        return self


class Curve(StrictModel):
    """One polyline of a curve network (Fig. 6d): open or closed, on the network's projection plane."""

    closed: bool = Field(False, description="Close this polyline (last point joins the first).")
    plane: Literal["xy", "xz", "yz"] | None = Field(
        None,
        description="Projection plane of this curve; null = 'construction.plane'. All curves of a network "
        "must lie on the same plane.",
    )
    points: list[Point2] = Field(
        description="Polyline points in the plane's two world coordinates: at least 2, all distinct (as "
        "'construction.points'). Where it crosses another curve both must run straight through the junction "
        "(S_Y offset lines on the side given by 'construction.side') and on for at least one unit beyond it.",
        min_length=2,
    )

    @field_validator("points")
    @classmethod
    def _points(cls, pts, info: ValidationInfo):
        return checked_points(pts, info)


class Construction(StrictModel):
    """The user's curve (or curve network) on a projection plane and the sizes S_Y, S_Z (Algorithm 1, eq. 2)."""

    plane: Literal["xy", "xz", "yz"] = Field(
        "xy",
        description="Projection plane of the curve: its two axes are the along-curve and offset lattice "
        "axes; the construction plane is swept along the third (xy: sweep Z, xz: sweep Y, yz: sweep X).",
    )
    closed: bool = Field(
        False,
        description="Close the polyline (last point joins the first; the first point may be repeated at the end).",
    )
    points: Annotated[list[Point2], Field(min_length=2)] | None = Field(
        None,
        description="Polyline points in the plane's two world coordinates: at least 2, all distinct (an open "
        "curve may not end at its first point; set 'closed' instead). The curve must be at least one lattice "
        "unit long; it is cut into S_X = floor(length / unit + 1/2) cells (nearest integer, halves up), so "
        "each piece is stretched or shrunk along the curve by length / (S_X * unit), within 1 +- 1 / (2 S_X). "
        "Give either 'points' (one curve) or 'curves' (a network).",
    )
    curves: Annotated[list[Curve], Field(min_length=1)] | None = Field(
        None,
        description="A curve network (paper Fig. 6d) instead of 'points': polylines on the same plane that may "
        "cross; where two cross, the overlap of their bands is one block of S_Y x S_Y x S_Z junction cells "
        "shared by both, the rest of each curve is cut into arms of S_X cells ending at the junctions. Crossings "
        "must be at least 30 degrees, inside a straight segment of each curve, and at least one unit from "
        "curve ends and other crossings; 'construction.closed' is then per curve.",
    )
    side: Literal["left", "right", "center"] = Field(
        "left",
        description="Where the offset lines go: left of the curve (as drawn), right of it, or centred on it.",
    )
    fit_cells: bool = Field(
        True,
        description="When every row of the example along the curve can repeat but some row cannot take S_X "
        "cells with its own pieces (an example joined end to end repeats every n cells, labels.join_ends), "
        "cut the curve into the nearest S_X every row takes instead (pieces stretch or shrink by length / "
        "(S_X unit); reported as metrics.fitted_cells): a curve drawn by hand has no exact length, and users "
        "expect a result rather than a refusal over one cell. false: refuse, naming that S_X. Single curves only.",
    )
    size_y: int | None = Field(
        None, ge=1, le=10000, description="S_Y: cells across the curve; null = the example's count."
    )
    size_z: int | None = Field(
        None, ge=1, le=10000, description="S_Z: cells along the sweep axis; null = the example's count."
    )

    @field_validator("points")
    @classmethod
    def _points(cls, pts, info: ValidationInfo):
        return checked_points(pts, info)

    @model_validator(mode="after")
    def _one_curve_source(self):
        if (self.points is None) == (self.curves is None):
            raise ValueError("give exactly one of 'points' (one curve) and 'curves' (a curve network)")
        if self.curves is not None:
            if self.closed:
                raise ValueError("'closed' applies to 'points'; with 'curves' set 'closed' on each curve")
            for i, c in enumerate(self.curves):
                if c.plane is not None and c.plane != self.plane:
                    raise ValueError(
                        f"curves[{i}].plane is '{c.plane}' but construction.plane is '{self.plane}': all curves of "
                        f"a network must lie on the same projection plane"
                    )
        return self


class Inference(StrictModel):
    """Algorithm 2 and what the paper leaves open."""

    max_restarts: int = Field(
        20, ge=0, le=10000, description="Restarts with a derived seed after a contradiction before failing."
    )


class Output(StrictModel):
    """What the run writes besides report.json and the previews."""

    mesh_format: Annotated[Literal["ply", "obj", "glb", "usd", "usda"], USD_NEEDS_EXTRA] = Field(
        "ply", description="Format of the assembled mesh (PLY also stores a per-face label; usd writes .usdc, "
        "usda text .usda, with UsdPreviewSurface materials and their textures beside it: the usd extra)."
    )
    export_net: Literal["none", "pnml", "dot", "both"] = Field(
        "pnml", description="Export the target Petri net as PNML and/or Graphviz DOT."
    )
    baseline: bool = Field(
        False,
        description="Also run Merrell-style model synthesis on the orthogonal lattice (a straight curve "
        "of the same length) and report its normal-histogram D beside the curved result's (off by "
        "default: a comparison, not part of the result).",
    )
    weld: bool = Field(
        True,
        description="Merge the vertices where neighbouring pieces meet in the output mesh (the boundary "
        "vertices their example pieces shared), making the result one connected surface.",
    )


class PetriConfig(RunConfig):
    """petri-synth: extend and deform an example's lattice pieces along a user curve (Song et al. 2013)."""

    method: Literal["petri-synth"] = "petri-synth"
    example: InputFile = Field(description="The example mesh (OBJ, PLY, GLB, OFF, STL).")
    lattice: Lattice = Field(description="How the example is cut into pieces.")
    labels: Labels = Field(default_factory=Labels, description="Piece classification.")
    construction: Construction = Field(description="The curve and sizes of the construction space.")
    inference: Inference = Field(default_factory=Inference, description="Inference options.")
    output: Output = Field(default_factory=Output, description="Outputs.")


CONFIG = PetriConfig
