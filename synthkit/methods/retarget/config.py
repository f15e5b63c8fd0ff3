"""Config schema of ``synthkit retarget`` (paper defaults from Wu et al., sections IV and V)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from synthkit.config import USD_NEEDS_EXTRA, InputFile, RunConfig, StrictModel

__all__ = ["CONFIG", "RetargetConfig", "AnalysisSection", "TargetSection", "Pin"]


class AnalysisSection(StrictModel):
    """Offset statistics (section III-A, IV, V); lengths in normalised units (longest side = 2)."""

    dense_radius: float = Field(0.02, gt=0, le=0.5, description="Poisson-disk spacing of the dense support cloud.")
    feature_radius: float = Field(0.06, gt=0, le=0.5, description="Poisson-disk spacing of the feature samples.")
    use_vertices: bool = Field(True, description="Add the mesh vertices as features.")
    descriptor: Literal["shot", "fpfh"] = Field("shot", description="Feature descriptor (SHOT 352-d or FPFH 33-d).")
    descriptor_radius: float = Field(
        0.2, gt=0, le=1.0, description="Support radius of the descriptor (0.2 for SHOT; about 0.1 suits FPFH)."
    )
    tau: float = Field(0.15, ge=0, le=2.0, description="Minimum offset length of a match (eq. 1).")
    bin_size: float = Field(0.05, gt=0, le=0.5, description="Side of a cubic offset-histogram bin.")
    nms_window: float = Field(0.15, gt=0, le=1.0, description="Non-maximum suppression window.")
    min_peak_share: float = Field(
        0.01, ge=0, le=1, description="Offsets a dominant offset's window must hold, as a share of all offsets."
    )
    max_dominant: int = Field(20, ge=1, le=200, description="Dominant offsets kept and refined by ICP.")
    min_overlap: float = Field(
        0.15, ge=0, le=1, description="Share of the dense cloud a principal offset must map onto the surface."
    )
    min_grip: float = Field(
        0.005, ge=0, le=1, description="Share of the surface that must pin a principal offset (rejects sliding)."
    )
    generator_grip_ratio: float = Field(
        2.0,
        ge=0,
        le=100,
        description="A dominant offset stands for an eligible multiple that pins this many times more surface "
        "(a slide, not a generator; 0: off).",
    )
    statistics_features: Literal["samples", "all"] = Field(
        "samples",
        description="Features the sparsity statistics are taken over: the Poisson-disk features (section IV) "
        "or all features, vertices included.",
    )
    min_angle_deg: float = Field(
        60.0, ge=1, le=90, description="Minimum angle between principal offsets (theta); below 1 degree two "
        "offsets span no lattice."
    )
    max_principal: int = Field(3, ge=0, le=3, description="At most this many principal offsets.")
    dummy_length: float = Field(
        0.2, ge=0.01, le=2.0, description="Length of the orthogonal dummy directions (at least 0.01, a fifth of "
        "the default bin, so that the canonical basis stays invertible)."
    )


class TargetSection(StrictModel):
    """Target size: exactly one of ``steps``, ``axis_steps`` or ``scale``."""

    steps: list[int] | None = Field(
        None, min_length=1, max_length=3,
        description="Integer steps per principal offset, in report order; null (with axis_steps and scale null "
        "too): one step along the first principal offset."
    )
    axis_steps: dict[Literal["x", "y", "z"], int] | None = Field(
        None, description="Steps along the principal offset closest to each named world axis, e.g. {x: 2}; null: "
        "steps or scale decide."
    )
    scale: list[float] | None = Field(
        None, min_length=1, max_length=3,
        description="Scale factor per principal offset, rounded to steps; null: steps or axis_steps decide."
    )

    @model_validator(mode="after")
    def _one_way(self):
        given = [k for k in ("steps", "axis_steps", "scale") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give only one of steps, axis_steps, scale (got {', '.join(given)})")
        if self.scale is not None and any(f <= 0 for f in self.scale):
            raise ValueError(f"scale factors must be > 0 (got {self.scale})")
        return self


class Pin(StrictModel):
    """A user constraint: output voxel ``voxel`` copies the input shifted by ``shift`` steps."""

    voxel: list[int] = Field(min_length=3, max_length=3, description="Output voxel index (i, j, k).")
    shift: list[int] = Field(min_length=3, max_length=3, description="Label: integer shift per grid axis.")


class OutputSection(StrictModel):
    """How the retargeted mesh is written."""

    mesh_format: Annotated[Literal["input", "obj", "glb", "ply", "usd", "usda"], USD_NEEDS_EXTRA] = Field(
        "input", description="Format of the retargeted meshes: input = the input's (glTF as GLB, a mesh given in "
        "memory as GLB when it has UVs or materials, else PLY); usd writes .usdc, usda text .usda, with "
        "UsdPreviewSurface materials and their textures beside it (the usd extra).",
    )


class RetargetConfig(RunConfig):
    """``synthkit retarget``: resize a mesh along its principal offsets by a graph cut."""

    method: Literal["retarget"] = "retarget"
    input: InputFile = Field(description="Input mesh (OBJ, PLY, GLB, OFF, STL).")
    analyze_only: bool = Field(False, description="Stop after the offset statistics (CLI --analyze-only).")
    analysis: AnalysisSection = Field(default_factory=AnalysisSection)
    target: TargetSection = Field(default_factory=lambda: TargetSection(steps=[1]))
    offsets: Literal["statistics", "regular"] = Field(
        "statistics", description="Label space: principal offsets, or the conventional regular grid (baseline)."
    )
    regular_spacing: float = Field(0.1, gt=0, le=1.0, description="Voxel size of the regular baseline.")
    compare_baseline: bool = Field(
        False, description="With offsets: statistics, also run the regular baseline and report it (metrics.baseline)."
    )
    label_margin: int = Field(0, ge=0, le=4, description="Extra shifts beyond the steps on each side.")
    pins: list[Pin] = Field(default_factory=list, description="Voxels pinned to labels (interactive use).")
    max_cycles: int = Field(20, ge=1, le=1000, description="Alpha-expansion cycles at most.")
    weld_tolerance: float = Field(
        1e-6,
        gt=0,
        le=1e-2,
        description=(
            "Seam weld distance, normalised units: vertices of two copies closer than this across a "
            "seam become one vertex."
        ),
    )
    preview_size: int = Field(256, ge=64, le=2048, description="Side of the PNG previews in pixels.")
    output: OutputSection = Field(default_factory=OutputSection)


CONFIG = RetargetConfig
