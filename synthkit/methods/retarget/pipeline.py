"""``synthkit retarget``: read a mesh, compute offset statistics, retarget by graph cut.

:func:`compute` runs every stage on the inputs (files or objects given in memory) and returns a
:class:`~synthkit.methods.retarget.outputs.RetargetResult`; :func:`run` (the command line) also
writes it. Stages (``report.json`` ``timings``): ``load``, ``analysis``, ``synthesis`` (grid,
voxel descriptor sets, MRF terms), ``graphcut`` (alpha-expansion), ``assemble`` (pieces, weld
along the seams, map back), the same three prefixed ``baseline_`` when the regular-offset baseline
runs, ``quality`` (:func:`~synthkit.methods.retarget.figures.output_quality`) and ``output``.
The stage modules take arrays and the settings of :mod:`~synthkit.methods.retarget.options` and
raise ValueError; this module alone maps them to a ConfigError or InputError naming the input
and the config key.

The regular baseline (``offsets: regular`` or ``compare_baseline``) keeps its best labeling even
when it joins empty to non-empty voxels (infinite energy, reported as null with the number of such
seams in ``infinite_terms``), as the paper's conventional MRF shows its artifacts.

No repetition (no principal offset): :class:`NoRepetition` (an InputError with
``keep_outputs=True``, exit 3) is raised; from the command line the statistics and previews are
written first (the runner keeps the folder, ``report.json`` has ``"status": "refused"``).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import trimesh

from synthkit.asset import Asset
from synthkit.core.mesh import normalize_unit
from synthkit.errors import InputError, KeyedError, user_error
from synthkit.io.inputs import Inputs
from synthkit.io.usd import mesh_suffix
from synthkit.methods.retarget.analysis import Analysis, analyze
from synthkit.methods.retarget.corners import pack
from synthkit.methods.retarget.figures import (
    degenerate,
    input_quality,
    output_quality,
    result_metrics,
    statistics_metrics,
    written_faces,
)
from synthkit.methods.retarget.options import SynthesisOptions, Target, options_of
from synthkit.methods.retarget.outputs import RetargetedMesh, RetargetResult
from synthkit.methods.retarget.problem import build_problem, offsets_found, resolve_steps, working_steps
from synthkit.methods.retarget.seams import Retargeted, stitch
from synthkit.result import result_fields

__all__ = ["compute", "NoRepetition", "check_analysis_budget"]


_MESH_OUT = {".obj": ".obj", ".ply": ".ply", ".glb": ".glb", ".gltf": ".glb", ".off": ".off", ".stl": ".stl"}
"""Output mesh format per input format (glTF is written as GLB, with the textures embedded)."""

log = logging.getLogger("synthkit")

SAMPLE_BYTES = 200
"""Bytes per Poisson-disk sample: position, normal, pool share, kd-tree (estimate)."""

PAIR_BYTES = 64
"""Bytes per (feature, support sample) pair gathered by the descriptor (estimate)."""

BIN_BYTES = 40
"""Bytes per bin of the dense offset histogram searched for peaks: counts, window sums, scores."""

OFFSET_SPAN = 4.0
"""Largest extent of the offsets along an axis in normalised units (the model spans [-1, 1])."""


def _disk_count(area: float, radius: float) -> float:
    """Poisson-disk samples of spacing ``radius`` on ``area`` (hexagonal packing), inf when it
    overflows."""
    try:
        return area * 2.0 / (math.sqrt(3.0) * radius * radius)
    except (OverflowError, ZeroDivisionError):
        return float("inf")


def check_analysis_budget(budget, a, area: float, n_vertices: int) -> None:
    """Refuse sampling radii whose samples or descriptor neighbourhoods exceed the memory budget,
    before anything is sampled. ``area`` is the normalised mesh's surface area."""
    dense = _disk_count(area, a.dense_radius)
    budget.require("analysis.dense_radius", a.dense_radius, dense, "samples", bytes_each=SAMPLE_BYTES)
    features = _disk_count(area, a.feature_radius) + (n_vertices if a.use_vertices else 0)
    budget.require("analysis.feature_radius", a.feature_radius, features, "features", bytes_each=SAMPLE_BYTES)
    support = min(dense, _disk_count(np.pi * a.descriptor_radius**2, a.dense_radius))
    budget.require("analysis.dense_radius", a.dense_radius, features * support, "descriptor neighbour pairs",
                   bytes_each=PAIR_BYTES)
    try:
        side = OFFSET_SPAN / a.bin_size + 2 * (a.nms_window / a.bin_size) + 1
    except (OverflowError, ZeroDivisionError):
        side = float("inf")
    budget.require("analysis.bin_size", a.bin_size, side**3, "histogram bins", bytes_each=BIN_BYTES)


class NoRepetition(InputError):
    """No principal offset was found: a refusal (exit 3) that keeps the statistics, which
    ``result`` (the :class:`RetargetResult` of the analysis) writes."""

    def __init__(self, message: str, *, keep_outputs: bool = True, result: RetargetResult | None = None):
        super().__init__(message, keep_outputs=keep_outputs, result=result)


def _load(cfg, inputs: Inputs, src: str, ctx):
    """Read the input with its appearance: ``(asset, Vn (#V, 3) normalised, center (3,), scale,
    (Va, Fa) the mesh the analysis samples, normalised, suffix of the output mesh (``output.mesh_format``,
    by default the input's))``. A scene of
    several meshes (a GLB/glTF scene) becomes one mesh (materials kept per face; the nodes are not:
    ``metrics.merged_meshes`` and one warning). An OBJ's material groups are one mesh already.

    The analysis samples the surface as :func:`~synthkit.io.meshes.load_mesh` gives it, the
    stitching the asset's faces and corners (docs/findings/retarget.md, "OBJ face order")."""
    asset = inputs.asset(cfg.input)
    V, F = asset.V, asset.F
    mesh = inputs.mesh(cfg.input)
    if inputs.is_memory(cfg.input):
        suffix = ".glb" if asset.corner_uv is not None or asset.materials else ".ply"
    else:
        suffix = _MESH_OUT.get(Path(cfg.input).suffix.lower(), ".ply")
    merged = int(mesh.metadata.get("merged_geometries", 1)) if suffix == ".glb" else 1
    ctx.metrics["merged_meshes"] = merged
    if merged > 1:
        log.warning("merged %d meshes of %s", merged, src)
    if cfg.output.mesh_format != "input":
        suffix = mesh_suffix(cfg.output.mesh_format)
    try:
        _, center, scale = normalize_unit(V[np.unique(F)])
    except ValueError as exc:
        raise InputError(f"{src}: {exc}") from None
    Vn = (V - center) / scale
    Va, Fa = (np.asarray(mesh.vertices, dtype=np.float64) - center) / scale, np.asarray(mesh.faces, dtype=np.int64)
    ctx.metrics["input_faces"] = int(len(F))
    return asset, Vn, center, scale, (Va, Fa), suffix


def _synthesize(Vn, F, an: Analysis, basis, steps, opt: SynthesisOptions, ctx, *, src: str, prefix: str,
                step_keys=None, attr=None) -> Retargeted:
    """Retarget the normalised mesh ``Vn``, ``F`` on the grid spanned by ``basis (3, 3)`` by
    ``steps (3,)`` voxels per axis, timing ``<prefix>synthesis``, ``<prefix>graphcut`` and
    ``<prefix>assemble``. Steps that leave fewer than 2 cells along an axis and bad pins are a
    ConfigError naming the key (``step_keys[axis]``); no finite labeling is an InputError, except
    for the regular baseline, which keeps its best labeling as the paper's conventional MRF does."""
    regular = prefix in ("regular_", "baseline_")
    with ctx.stage(f"{prefix}synthesis"):
        try:
            grid, problem = build_problem(Vn, F, an, basis, steps, opt, regular=regular,
                                          pinned=prefix != "baseline_", step_keys=step_keys)
        except KeyedError as exc:
            raise user_error(exc, f"{src}: ") from None
    with ctx.stage(f"{prefix}graphcut"):
        try:
            result = problem.solve(rng=ctx.rng, max_cycles=opt.max_cycles)
        except ValueError as exc:
            raise InputError(f"{src}: no valid labeling: {exc}") from None
    if not np.isfinite(result.energy) and not regular:
        raise InputError(_with_hint(
            f"{src}: no seamless retargeting for steps {np.asarray(steps).tolist()}: every labeling joins an empty "
            "voxel to a non-empty one", Vn, F, an, opt, ctx, steps))
    with ctx.stage(f"{prefix}assemble"):
        return stitch(Vn, F, attr, grid, problem, result, weld_tol=opt.weld_tolerance, dense_radius=opt.dense_radius)


def _with_hint(message: str, Vn, F, an: Analysis, opt: SynthesisOptions, ctx, tried) -> str:
    """A refusal's ``message`` with what the model repeats (:func:`offsets_found`) and the nearest
    request that works (:func:`working_steps`, a graph cut per candidate, seeded by the run's seed)."""
    steps = working_steps(Vn, F, an, opt, np.random.default_rng(ctx.seed), np.asarray(tried))
    if steps is None:
        hint = "one step along any of them, or back, has no seamless labeling either"
    else:
        hint = f"nearest request that works: target: {{steps: {steps[:an.n_principal].tolist()}}}"
    return f"{message}; {offsets_found(an)}; {hint}"


def _retarget_all(cfg, opt: SynthesisOptions, target: Target, an: Analysis, Vn, F, attr, ctx,
                  src: str) -> list[tuple[str, Retargeted, np.ndarray, float]]:
    """The retargeted meshes the config asks for: ``(prefix, result, steps, graph-cut seconds)``
    of the statistics result (prefix ``""``) and of the regular baseline (``"baseline_"``, or
    ``""`` with ``offsets: regular``)."""
    step_keys: dict[int, str] = {}
    try:
        steps = resolve_steps(target, an, Vn, keys=step_keys)
    except KeyedError as exc:
        raise InputError(_with_hint(str(user_error(exc, f"{src}: ")), Vn, F, an, opt, ctx, np.zeros(3))) from None
    results = []
    if cfg.offsets == "statistics":
        res = _synthesize(Vn, F, an, an.basis, steps, opt, ctx, src=src, prefix="", step_keys=step_keys, attr=attr)
        results.append(("", res, steps, ctx.timings["graphcut"]))
    if cfg.offsets == "regular" or cfg.compare_baseline:
        h = cfg.regular_spacing
        reg_steps = np.rint(an.basis @ steps / h).astype(np.int64)
        prefix = "baseline_" if cfg.offsets == "statistics" else ""
        res_b = _synthesize(Vn, F, an, h * np.eye(3), reg_steps, opt, ctx, src=src, prefix=prefix or "regular_",
                            attr=attr)
        results.append((prefix, res_b, reg_steps, ctx.timings[f"{prefix or 'regular_'}graphcut"]))
    if cfg.offsets == "regular":
        ctx.timings["graphcut"] = ctx.timings.get("regular_graphcut", 0.0)
    return results


def _in_model_units(res: Retargeted, asset: Asset, center, scale, ctx, *, src: str, prefix: str,
                    suffix: str) -> RetargetedMesh:
    """One result as written, in model units, without its degenerate faces (one warning line
    saying how many, ``metrics.degenerate_faces_dropped``)."""
    Vm = res.V * scale + center
    F, mat, uv, col, dropped = written_faces(res, Vm, asset)
    if dropped:
        log.warning("%s: %d degenerate faces left out of %sretargeted%s", src, dropped, prefix, suffix)
    ctx.metrics.setdefault("degenerate_faces_dropped", {})[f"{prefix}mesh"] = dropped
    lab_keep = ~degenerate(Vm, res.labelled_F)
    out = Asset(V=Vm, F=F, corner_uv=uv, corner_color=col, face_material=mat, materials=asset.materials,
                name=asset.name, source=asset.source)
    return RetargetedMesh(
        asset=out, mesh=trimesh.Trimesh(Vm, F, process=False),
        label_volume=res.problem.volume(res.labeling).astype(np.int32),
        labelled_mesh=trimesh.Trimesh(Vm, res.labelled_F[lab_keep], process=False),
        face_labels=res.face_label[lab_keep], label_shifts=res.problem.labels, n_nodes=int(res.problem.n_nodes),
    )


def compute(cfg, inputs: Inputs, ctx) -> RetargetResult:
    """Run the retargeting described by ``cfg`` (a
    :class:`~synthkit.methods.retarget.config.RetargetConfig`) on ``inputs``; write nothing. Raises
    :class:`NoRepetition` (an InputError that keeps the statistics) when the analysis finds no
    principal offset and the config asks for more than the analysis."""
    src = inputs.source(cfg.input)
    with ctx.stage("load"):
        asset, Vn, center, scale, (Va, Fa), suffix = _load(cfg, inputs, src, ctx)
        V, F = asset.V, asset.F
        area = 0.5 * np.linalg.norm(np.cross(Vn[F[:, 1]] - Vn[F[:, 0]], Vn[F[:, 2]] - Vn[F[:, 0]]), axis=1)
        if not area.sum() > 1e-12:
            raise InputError(f"{src}: degenerate mesh: all {len(F)} triangles have zero area")
    analysis_options, synthesis_options, target = options_of(cfg)
    check_analysis_budget(ctx.budget, cfg.analysis, float(area.sum()), len(np.unique(F)))
    with ctx.stage("analysis"):
        an = analyze(Va, Fa, analysis_options, rng=ctx.rng)
    ctx.metrics.update(statistics_metrics(an, center, scale))
    ctx.metrics["analyze_only"] = bool(cfg.analyze_only)
    result = RetargetResult(**result_fields(cfg, ctx, inputs), input_asset=asset, analysis=an, center=center,
                            scale=float(scale), suffix=suffix)
    if cfg.analyze_only:
        return result
    if an.n_principal == 0:
        ctx.metrics["error"] = "no repetition found"
        raise NoRepetition(
            f"{src}: no repetition found (no dominant offset maps at least {cfg.analysis.min_overlap:.0%} of "
            f"the surface onto itself; {len(an.dominant)} histogram peaks, top-7% share {an.top7:.2f}); "
            "refusing to resize",
            result=result,
        )
    attr = pack(asset.face_material, asset.corner_uv, asset.corner_color)
    results = _retarget_all(cfg, synthesis_options, target, an, Vn, F, attr, ctx, src)
    with ctx.stage("quality"):
        in_quality = input_quality(V, F)
        for prefix, res, st, secs in results:
            out = _in_model_units(res, asset, center, scale, ctx, src=src, prefix=prefix, suffix=suffix)
            metrics = result_metrics(res, st, secs, scale)
            quality, limits, figures = output_quality(res, out.asset.F, center, scale, Vn, F, in_quality)
            ctx.check_quality(f"{prefix}mesh", in_quality, quality, limits)
            metrics.update(figures)
            if prefix:
                ctx.metrics["baseline"] = metrics
                result.baseline = out
            else:
                ctx.metrics.update(metrics)
                result.retargeted = out
    return result
