"""Config schema of ``synthkit symmetry-texture`` (Kim, Lipman, Funkhouser 2012).

A config picks the application (``mode``), the input signal(s), the symmetry representation, the
target (another image's representation for ``transfer``, a filter of the input's own for
``filter``) and the perturbation model (``synth``: guided quilting; ``deform``: as-rigid-as-possible
warping; ``lens``: one-parameter radial undistortion). The objective follows from the mode: E_L2
against the target for ``transfer``/``filter``, E_symm (maximized) for ``tile``/``symmetrize``.
Every row of the paper's Fig. 14 is one such combination.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from synthkit.config import InputFile, RunConfig, StrictModel

Signal = Literal["lum", "1-lum", "edge"]


class SymmetrySection(StrictModel):
    """Symmetry representation S and the input signals it is computed from."""

    kind: Literal["translational", "rotational", "reflective"] = Field(
        "translational", description="S_T (translations), S_R (rotations about a centre), S_Ref (reflections)."
    )
    signals: list[Signal] | Literal["auto"] = Field(
        "auto",
        min_length=1,
        description=(
            "Input signals f_lum, f_1-lum, f_edge; objective summed over them (Fig. 7: lum + 1-lum). "
            "auto: for E_symm (tile, symmetrize) the one of lum and 1-lum whose raw S has the larger "
            "variance (dark line art on white: 1-lum; a signal near constant 1 puts its S near 1 "
            "everywhere); for E_L2 lum (standardized S of lum and 1-lum are the same). "
            "metrics.signals says which."
        ),
    )
    mode: Literal["toroidal", "zero", "overlap"] = Field(
        "toroidal",
        description=(
            "S_T autocorrelation on a torus, with zero padding, or overlap: the mean-free "
            "correlation per overlapping pixel, for photographs that are not tori (deform/lens only)."
        ),
    )
    crop: Literal["auto", "none", "periods"] = Field(
        "auto",
        description=(
            "periods: S_T of the centred crop to a whole number of periods of the input along each "
            "axis (the strongest autocorrelation displacement from 4 px to half the size), so the "
            "torus of eq. 2 wraps the pattern onto itself; none: of the whole image. auto: periods "
            "for symmetrize by deform (a photograph whose period does not divide its size is "
            "irregular across the wrap, and E_symm then warps even an unwarped one), none otherwise."
        ),
    )
    window: float = Field(
        0.5,
        gt=0.0,
        le=0.5,
        description=(
            "S_T displacement window as a fraction of the output's height/width; 0.5 = every "
            "translation, the paper's S_T; smaller values limit S_T to shorter displacements (the "
            "paper's optional reduced domain, for smaller patterns)."
        ),
    )
    center: tuple[float, float] | None = Field(
        None, description="Centre (row, col) in pixels for S_R / S_Ref; default the image centre."
    )
    n_angles: int = Field(360, ge=8, le=4096, description="Angular samples of S_R / S_Ref.")


class FilterSection(StrictModel):
    """Symmetry-space filter that turns S(f) into the target (mode: filter)."""

    kind: Literal["identity", "blur", "sharpen", "contrast", "scale", "rotate"] = Field(
        "identity", description="Filter applied to the input's own representation."
    )
    sigma: float = Field(2.0, ge=0.0, le=100.0, description="Gaussian blur sigma in samples (paper: 2 and 4).")
    power: float = Field(4.0, gt=0.0, le=16.0, description="Sharpen exponent (paper: 4).")
    amount: float = Field(2.0, gt=0.0, le=20.0, description="Contrast curve exponent (1 = identity).")
    factor: float = Field(2.0, gt=0.0, le=8.0, description="Scale factor of the pattern (paper: 2).")
    angle: float = Field(90.0, ge=-360.0, le=360.0, description="Rotation in degrees (paper: 90).")


class SynthSection(StrictModel):
    """Guided image quilting (theta_synth)."""

    patch: int = Field(32, ge=4, le=256, description="Patch size in pixels (paper: 32).")
    overlap: int = Field(12, ge=1, le=128, description="Overlap in pixels (paper: 12).")
    tol: float = Field(
        0.1, ge=0.0, le=10.0, description="Unguided quilting: accept patches within (1+tol) of the best overlap error."
    )
    candidates: int = Field(
        24, ge=1, le=1024, description="Guided walk: overlap-consistent candidate patches tried per tile (k best)."
    )
    sweeps: int = Field(
        4, ge=0, le=100, description="Guided walk: passes over all tiles (stops early when none changes)."
    )
    init: Literal["random", "quilt"] = Field(
        "random", description="Start from random patches (paper) or from the unguided quilting result."
    )
    seams: Literal["dp", "graphcut"] = Field(
        "dp", description="Seams: minimum-error boundary cuts (Efros-Freeman) or graph cuts (Kwatra 2003)."
    )
    evaluation: Literal["incremental", "full"] = Field(
        "incremental",
        description="Candidate evaluation: incremental dS_T of the changed block, or a full S_T per candidate.",
    )
    seam_share: float = Field(
        0.15,
        ge=0.0,
        le=1.0,
        description=(
            "Guided walk: share of a tile's best E_L2 gain it may give up for a candidate whose patch "
            "border shows less (0: the paper's choice, the best E_L2)."
        ),
    )
    polish_sweeps: int = Field(
        1,
        ge=0,
        le=100,
        description=(
            "Guided walk: passes after `sweeps` in which a tile takes, among the candidates that still "
            "lower E_L2, the one whose patch border shows least."
        ),
    )


class DeformSection(StrictModel):
    """As-rigid-as-possible warping on corner-detected control points (theta_deform)."""

    points: int = Field(256, ge=8, le=4096, description="Control points N (paper: 256), corners then dart throwing.")
    levels: int = Field(3, ge=1, le=8, description="Levels of the coarse-to-fine hierarchy.")
    step: float = Field(5.0, gt=0.0, le=100.0, description="Initial gradient step in pixels (paper: 5).")
    min_step: float = Field(
        1.0, gt=0.0, le=100.0, description="Stop a level once the step falls below this (paper: 1)."
    )
    max_cycles: int = Field(4, ge=1, le=100, description="Cycles over the control points per step size.")
    max_evaluations: int = Field(20000, ge=10, description="Budget of objective evaluations (paper: up to 20000).")
    max_stretch: float | None = Field(
        1.25,
        ge=1.0,
        le=100.0,
        description=(
            "Distortion bound: a move is refused when it would stretch (or squeeze) any mesh "
            "triangle by more than this factor against the start (max singular value, or 1/min); "
            "null = unbounded (the paper's model)."
        ),
    )
    max_gradient: float | None = Field(
        0.15,
        gt=0.0,
        le=10.0,
        description=(
            "Mode symmetrize: bound of the displacement field's gradient (largest singular value of "
            "its Jacobian per mesh triangle): two points d px apart move by at most this times d "
            "against each other. Moves beyond it are refused, "
            "and a result beyond it, or whose E_symm is not above the input's by deform.min_gain, is "
            "not returned: the input comes back (metrics.status, metrics.status_reason). null: "
            "unbounded gradient (E_symm still checked)."
        ),
    )
    min_gain: float | None = Field(
        None,
        ge=0.0,
        le=0.5,
        description=(
            "A move is taken only when it improves the objective by more than this share of its "
            "value. null: 0.01 for symmetrize (a regularizer toward small displacement, so an already "
            "regular photograph comes back unchanged), 0 otherwise (the paper's descent)."
        ),
    )
    interpolation: Literal["linear", "cubic", "lanczos"] = Field(
        "lanczos",
        description=(
            "Resampling of the rendered result (the optimizer's probes are bilinear): a half-pixel "
            "shift keeps 0.84 of a brick photo's high-frequency energy with lanczos, 0.70 with "
            "cubic, 0.34 with linear (which averages neighbours at every sub-pixel shift)."
        ),
    )


class LensSection(StrictModel):
    """One-parameter radial distortion (Tsai k1) about a given centre (theta_lens)."""

    center: tuple[float, float] | None = Field(
        None, description="Distortion centre (row, col) in pixels; default the image centre."
    )
    k1_min: float = Field(-0.5, ge=-2.0, le=2.0, description="Lower end of the k1 search range.")
    k1_max: float = Field(0.5, ge=-2.0, le=2.0, description="Upper end of the k1 search range.")
    samples: int = Field(41, ge=3, le=1001, description="Coarse grid samples before the golden-section refinement.")
    tol: float = Field(1e-4, gt=0.0, le=0.1, description="Final k1 tolerance of the refinement.")


class TileSection(StrictModel):
    """Toroidal tiling by symmetrization (mode: tile)."""

    optimize: bool = Field(
        False,
        description=(
            "Run the paper's optimization (ARAP warp of the centre maximizing E_symm, then blended) "
            "for one more candidate, the optimized tile. Off: only the blended input and the cut "
            "tiles are compared with the input, in seconds."
        ),
    )
    margin: float = Field(
        0.2, ge=0.0, le=0.45, description="Start on the centre leaving this fraction as margin (paper: 20%)."
    )
    zoom: Literal["crop", "upsample"] = Field(
        "crop",
        description=(
            "crop: the tile is the centre less the margins at the input's resolution (smaller than "
            "the input, no resampling); upsample: the paper's zoom of the centre to the input's "
            "size (blurs by 1 / (1 - 2 margin))."
        ),
    )
    max_stretch: float | None = Field(
        1.1,
        ge=1.0,
        le=100.0,
        description=(
            "Distortion bound of the tile's warp, in place of deform.max_stretch (a tile repeats its "
            "warp, so it is bounded tighter)."
        ),
    )
    cut_overlaps: list[Annotated[int, Field(ge=1, le=512)]] = Field(
        [8, 16, 24],
        max_length=16,
        description=(
            "Overlaps in pixels of the cut tiles, candidates besides the optimized tile and the "
            "blended input: the input's opposite borders overlapped by this much, joined by "
            "minimum-error boundary cuts (Efros-Freeman) and made interior-like across the cuts; "
            "a tile is smaller than the input by its overlap, and the toroidal E_symm depends on "
            "how the pattern wraps at that size (the default spans the paper's 12 px quilting "
            "overlap). Overlaps of half the input or more are skipped with a warning; []: none."
        ),
    )
    mvc_spacing: int = Field(
        1,
        ge=1,
        le=64,
        description=(
            "Spacing in pixels of the border vertices carrying the seam correction that MVC spreads "
            "inward; 1 makes every wrap-around step exactly interior-like, larger is a faster "
            "least-squares fit (border pixels between vertices interpolate linearly)."
        ),
    )


SYMMETRIZE_MIN_GAIN = 0.01
"""Default ``deform.min_gain`` of mode symmetrize: each move must buy 1% of E_symm, so that an
already regular photograph comes back nearly unchanged (docs/findings/symmetry-texture.md)."""


class SymtexConfig(RunConfig):
    """Symmetry-guided texture synthesis, filtering, tiling and symmetrization."""

    method: Literal["symmetry-texture"] = "symmetry-texture"
    mode: Literal["transfer", "filter", "tile", "symmetrize", "quilt"] = Field(
        description="Application: transfer, filter, tile, symmetrize, or plain unguided quilting."
    )
    source: InputFile = Field(description="Input image f (the source texture).")
    target: InputFile | None = Field(
        None, description="Target image or sketch g (mode: transfer; null in the other modes).")
    perturbation: Literal["synth", "deform", "lens"] | None = Field(
        None,
        description="Perturbation model; default synth for transfer/filter/quilt, deform for tile/symmetrize.",
    )
    output_size: tuple[int, int] | None = Field(
        None, description="Synthesis output (height, width) in pixels; default the source's size."
    )
    symmetry: SymmetrySection = Field(default_factory=SymmetrySection, description="Symmetry representation.")
    filter: FilterSection = Field(default_factory=FilterSection, description="Symmetry-space filter (mode: filter).")
    synth: SynthSection = Field(default_factory=SynthSection, description="Guided quilting parameters.")
    deform: DeformSection = Field(default_factory=DeformSection, description="ARAP warping parameters.")
    lens: LensSection = Field(default_factory=LensSection, description="Lens undistortion search.")
    tile: TileSection = Field(default_factory=TileSection, description="Tiling parameters (mode: tile).")
    baseline: bool = Field(
        False, description="Modes transfer and filter: also quilt the source unguided with the same seed and "
        "report its E_L2 and seam visibility beside the result (baseline.png, comparison.png); off by default: "
        "a comparison, not part of the result.")

    @model_validator(mode="after")
    def _check_combination(self):
        pert = self.resolved_perturbation()
        if self.mode == "transfer" and self.target is None:
            raise ValueError("mode 'transfer' needs 'target' (an image or sketch)")
        if self.mode == "quilt" and pert != "synth":
            raise ValueError("mode 'quilt' uses perturbation 'synth'")
        if self.mode == "tile" and pert != "deform":
            raise ValueError("mode 'tile' uses perturbation 'deform'")
        if self.mode in ("transfer", "filter") and pert == "lens":
            raise ValueError("perturbation 'lens' applies to mode 'symmetrize' only")
        if self.mode == "symmetrize" and pert == "synth":
            raise ValueError("mode 'symmetrize' uses perturbation 'deform' or 'lens'")
        if pert == "synth" and self.symmetry.kind != "translational":
            raise ValueError("perturbation 'synth' is guided by the translational representation (symmetry.kind)")
        if pert == "synth" and self.symmetry.mode != "toroidal":
            raise ValueError(
                "perturbation 'synth' evaluates the toroidal S_T of its toroidal tiling; "
                "symmetry.mode 'zero' applies to perturbation 'deform' or 'lens' only"
            )
        if pert == "synth" and self.symmetry.signals != "auto" and "edge" in self.symmetry.signals:
            raise ValueError("perturbation 'synth' supports the signals 'lum' and '1-lum' (symmetry.signals)")
        if pert == "synth" and self.synth.overlap >= self.synth.patch:
            raise ValueError(f"synth.overlap {self.synth.overlap} must be smaller than synth.patch {self.synth.patch}")
        toroidal_st = (self.symmetry.kind, self.symmetry.mode) == ("translational", "toroidal")
        if self.symmetry.crop == "periods" and not toroidal_st:
            raise ValueError("symmetry.crop 'periods' applies to the toroidal translational representation")
        if self.symmetry.crop == "periods" and (self.mode == "tile" or pert == "synth"):
            raise ValueError("symmetry.crop 'periods' applies to symmetrize, transfer and filter by deform or lens")
        if self.deform.min_step > self.deform.step:
            raise ValueError("deform.min_step must not exceed deform.step")
        if self.lens.k1_min >= self.lens.k1_max:
            raise ValueError("lens.k1_min must be below lens.k1_max")
        if self.output_size is not None and min(self.output_size) < 1:
            raise ValueError(f"output_size must be positive, got {self.output_size}")
        return self

    def resolved_perturbation(self) -> str:
        """The perturbation model in effect (the mode's default when not given)."""
        if self.perturbation is not None:
            return self.perturbation
        return "deform" if self.mode in ("tile", "symmetrize") else "synth"

    def period_crop(self) -> bool:
        """Whether S_T is of the input's whole-period crop (``symmetry.crop``, see its description)."""
        if self.symmetry.crop == "auto":
            return (
                self.mode == "symmetrize"
                and self.resolved_perturbation() == "deform"
                and self.symmetry.kind == "translational"
                and self.symmetry.mode == "toroidal"
            )
        return self.symmetry.crop == "periods"

    def resolved_min_gain(self) -> float:
        """``deform.min_gain``, or its default for the mode (see its description)."""
        if self.deform.min_gain is not None:
            return self.deform.min_gain
        return SYMMETRIZE_MIN_GAIN if self.mode == "symmetrize" else 0.0

    def objective_kind(self) -> str:
        """``"l2"`` (minimized, against a target) or ``"symm"`` (maximized)."""
        return "l2" if self.mode in ("transfer", "filter", "quilt") else "symm"


CONFIG = SymtexConfig
