"""``synthkit retarget``: read a mesh, compute offset statistics, retarget by graph cut.

:func:`compute` runs every stage on the inputs (files or objects given in memory) and returns a
:class:`~synthkit.methods.retarget.outputs.RetargetResult`; :func:`run` (the command line) writes
it (:mod:`~synthkit.methods.retarget.outputs`). Stages (``report.json`` ``timings``): ``load``,
``analysis``, ``synthesis`` (grid, voxel descriptor sets, MRF terms), ``graphcut``
(alpha-expansion), ``assemble`` (pieces, weld along the seams, map back), the same three prefixed
``baseline_`` when the regular-offset baseline runs, ``quality`` and ``output`` (the files).

Each result's mesh is checked with the shared mesh-quality figures against retargeting's limits
(:func:`_check_result`, ``metrics.mesh_quality``); degenerate faces are never written.

The regular baseline (``offsets: regular`` or ``compare_baseline``) keeps its best labeling even
when it joins empty to non-empty voxels (infinite energy, reported as null with the number of such
seams in ``infinite_terms``), as the paper's conventional MRF shows its artifacts.

A GLB/glTF scene of several meshes is merged into one; the number merged is
``metrics.merged_meshes`` (1 for a single mesh) and a merge logs the warning "merged N meshes of
<file>" on the ``synthkit`` logger.

No repetition (no principal offset): ``ctx.metrics`` is filled and :class:`NoRepetition` (an
:class:`~synthkit.errors.InputError` with ``keep_outputs=True``, exit 3) is raised; from the
command line the statistics and previews are written first (the runner keeps the folder,
``report.json`` has ``"status": "refused"``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from synthkit.api import result_fields
from synthkit.core.mesh import merge_vertices, normalize_unit, weld
from synthkit.core.quality import WELD_REL_TOL, degenerate_faces, mesh_quality
from synthkit.errors import ConfigError, InputError
from synthkit.io.assets import Asset
from synthkit.io.inputs import Inputs
from synthkit.methods.retarget.analysis import Analysis, analyze, describe
from synthkit.methods.retarget.corners import carry, pack, unpack
from synthkit.methods.retarget.options import options_of
from synthkit.methods.retarget.outputs import RetargetedMesh, RetargetResult
from synthkit.methods.retarget.synthesis import (
    RetargetProblem,
    VoxelGrid,
    assemble,
    collapse_short_seam_edges,
    flip_sliver_edges,
    make_grid,
    merge_coplanar_faces,
    repair_t_junctions,
    sliver_figures,
    unique_faces,
)

__all__ = ["compute", "run", "NoRepetition", "Retargeted", "synthesize", "resolve_steps", "weld_seams",
           "statistics_metrics"]

_MESH_OUT = {".obj": ".obj", ".ply": ".ply", ".glb": ".glb", ".gltf": ".glb", ".off": ".off", ".stl": ".stl"}
"""Output mesh format per input format (glTF is written as GLB, with the textures embedded)."""
log = logging.getLogger("synthkit")


@dataclass
class Retargeted:
    """One synthesis result in normalised units: ``V (n, 3)``, ``F (m, 3)`` (the retargeted mesh,
    flat regions re-triangulated across seams), ``labelled_F (k, 3)`` with ``face_label (k,)`` (the
    same surface with every face inside one label's copy, for ``labels.ply``), the grid, the
    problem (labels, shapes), the labeling ``(N,)`` and its energy; ``attr (m, 3, k)`` the
    corner values of ``F`` (:mod:`~synthkit.methods.retarget.corners`) when the input had them."""

    V: np.ndarray
    F: np.ndarray
    face_label: np.ndarray
    grid: VoxelGrid
    problem: RetargetProblem
    labeling: np.ndarray
    energy: float
    cycles: int
    labelled_F: np.ndarray | None = None
    attr: np.ndarray | None = None


def _voxel_sets(an: Analysis, grid: VoxelGrid, *, descriptor: str, radius: float) -> list[np.ndarray]:
    """Descriptor set G of every input voxel (flat C order): the features inside it. A voxel that
    holds dense samples but no feature (a sliver thinner than the feature spacing) gets up to 8
    of its dense samples, described the same way, so that it is not mistaken for empty; a voxel
    with no dense sample counts as empty (its surface is below the sampling resolution)."""
    fs = an.features
    shape = tuple(grid.shape)
    vox = grid.voxel_of(grid.to_canonical(fs.P))
    ok = np.all((vox >= 0) & (vox < grid.shape), axis=1)
    flat = np.full(len(vox), -1)
    flat[ok] = np.ravel_multi_index(tuple(vox[ok].T), shape)
    sets = [fs.D[flat == i] for i in range(grid.n_voxels)]
    dvox = grid.voxel_of(grid.to_canonical(fs.dense_P))
    dok = np.all((dvox >= 0) & (dvox < grid.shape), axis=1)
    dflat = np.full(len(dvox), -1)
    dflat[dok] = np.ravel_multi_index(tuple(dvox[dok].T), shape)
    occupied = np.unique(dflat[dflat >= 0])
    for i in occupied:
        if len(sets[i]) == 0:
            idx = np.flatnonzero(dflat == i)
            idx = idx[np.linspace(0, len(idx) - 1, min(8, len(idx))).astype(int)]
            sets[i] = describe(
                fs.dense_P[idx], fs.dense_N[idx], fs.dense_P, fs.dense_N, descriptor=descriptor, radius=radius
            )
    return sets


def synthesize(
    Vn, F, an: Analysis, basis, steps, *, cfg, ctx, prefix: str = "", allow_infinite: bool = False, step_keys=None,
    attr=None,
) -> Retargeted:
    """Retarget the normalised mesh ``Vn``, ``F`` on the grid spanned by ``basis (3, 3)`` by
    ``steps (3,)`` voxels per axis; stages timed on ``ctx`` as ``<prefix>synthesis``,
    ``<prefix>graphcut``, ``<prefix>assemble``. Raises InputError when no finite labeling exists,
    unless ``allow_infinite`` (the regular baseline: like the paper's conventional MRF it still
    yields its best labeling, whose infinite seams are counted in the metrics). Steps that leave
    fewer than 2 cells along an axis are a ConfigError naming ``step_keys[axis]`` (the config key
    and value that asked for them, from :func:`resolve_steps`)."""
    a = cfg.analysis
    with ctx.stage(f"{prefix}synthesis"):
        used = np.unique(F)
        grid = make_grid(basis, an.features.dense_P, an.features.dense_N, Vn[used], dense_radius=a.dense_radius)
        sets = _voxel_sets(an, grid, descriptor=a.descriptor, radius=a.descriptor_radius)
        steps = np.asarray(steps, dtype=np.int64)
        out_shape = grid.shape + steps
        for axis in np.flatnonzero(steps):
            if out_shape[axis] < 2:
                what = step_keys.get(int(axis)) if step_keys else None
                what = what or f"{int(steps[axis])} steps along grid axis {int(axis)}"
                raise ConfigError(
                    f"{cfg.input}: {what}: would shrink below one cell (the input spans {int(grid.shape[axis])} "
                    f"cells along it; at least 2 must remain)"
                )
        regular = prefix in ("regular_", "baseline_")
        margin = [cfg.label_margin] * 3 if regular else np.where(np.arange(3) < an.n_principal, cfg.label_margin, 0)
        pins = [(p.voxel, p.shift) for p in cfg.pins] if prefix != "baseline_" else []
        try:
            problem = RetargetProblem(grid.shape, steps, sets, margin=margin, pins=pins)
        except ValueError as exc:
            raise ConfigError(f"{cfg.input}: pins: {exc}") from None
    with ctx.stage(f"{prefix}graphcut"):
        try:
            result = problem.solve(rng=ctx.rng, max_cycles=cfg.max_cycles)
        except ValueError as exc:
            raise InputError(f"{cfg.input}: no valid labeling: {exc}") from None
    if not np.isfinite(result.energy) and not allow_infinite:
        raise InputError(
            f"{cfg.input}: no seamless retargeting for steps {steps.tolist()}: every labeling joins an empty voxel "
            "to a non-empty one (try other steps)"
        )
    with ctx.stage(f"{prefix}assemble"):
        return _stitch(Vn, F, attr, grid, problem, result, weld_tol=cfg.weld_tolerance, dense_radius=a.dense_radius)


def _stitch(Vn, F, attr, grid: VoxelGrid, problem: RetargetProblem, result, *, weld_tol: float, dense_radius: float):
    """Assemble the labeling's copies, weld them along the seams, close T-junctions, collapse
    short seam edges, re-triangulate flat regions and flip slivers (per label for ``labelled_F``,
    across seams for ``F``), carrying the corner values ``attr (#F, 3, k)`` through every step."""
    Vc, Fo, fl, A = assemble(grid.to_canonical(Vn), F, grid, problem, result.labels, attr)
    Vw, Fw, old_to_new = weld_seams(Vc, Fo, fl, grid, weld_tol)
    Fm = old_to_new[Fo]
    alive = (Fm[:, 0] != Fm[:, 1]) & (Fm[:, 1] != Fm[:, 2]) & (Fm[:, 2] != Fm[:, 0])
    fl, A = fl[alive], _take(A, alive)
    keep = unique_faces(Vw, Fw)
    Fw, fl, A = Fw[keep], fl[keep], _take(A, keep)
    F0 = Fw
    on_seam = _on_voxel_planes(Vw, grid, weld_tol)
    Vw, Fw, src = repair_t_junctions(Vw, Fw, tol=weld_tol, split_at=on_seam)
    fl, A = fl[src], carry(Vw, Fw, F0, src, A)
    F0 = Fw
    Fw, src = collapse_short_seam_edges(Vw, Fw, on_seam, SEAM_COLLAPSE * dense_radius)
    fl, A = fl[src], carry(Vw, Fw, F0, src, A)
    Fl, src = merge_coplanar_faces(Vw, Fw, fl, tol=weld_tol, attr=A, active=on_seam[Fw].any(axis=1))
    fl, Al = fl[src], carry(Vw, Fl, Fw, src, A)
    F0 = Fl
    Fl = flip_sliver_edges(Vw, Fl, fl, attr=Al, active=on_seam[Fl].any(axis=1))
    Al = carry(Vw, Fl, F0, np.arange(len(Fl)), Al)
    Fw, src = merge_coplanar_faces(Vw, Fl, None, tol=weld_tol, attr=Al, active=on_seam[Fl].any(axis=1))
    A = carry(Vw, Fw, Fl, src, Al)
    F0 = Fw
    Fw = flip_sliver_edges(Vw, Fw, attr=A, active=on_seam[Fw].any(axis=1))
    A = carry(Vw, Fw, F0, np.arange(len(Fw)), A)
    used = np.unique(Fl)
    remap = np.full(len(Vw), -1)
    remap[used] = np.arange(len(used))
    return Retargeted(
        Vw[used], remap[Fw], fl, grid, problem, result.labels, result.energy, result.cycles,
        labelled_F=remap[Fl], attr=A,
    )


def _take(A, rows):
    """``A[rows]``, None when ``A`` is None."""
    return None if A is None else A[rows]


SEAM_COLLAPSE = 0.5
"""Seam edges shorter than this many dense spacings are collapsed where that improves the faces'
shape (:func:`collapse_short_seam_edges`): finer than the descriptors see, and fanned across a
face they make slivers."""


def _on_voxel_planes(V, grid: VoxelGrid, tol: float) -> np.ndarray:
    """``(n,) bool``: the normalised vertices ``V (n, 3)`` within ``tol`` of a voxel face plane."""
    frac = grid.to_canonical(V) - grid.origin
    return ((np.abs(frac - np.rint(frac)) / np.linalg.norm(grid.inverse, axis=1)) <= tol).any(axis=1)


def weld_seams(Vc, F, face_label, grid: VoxelGrid, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weld the assembled copies along their seams only.

    ``Vc (n, 3)`` canonical vertices of :func:`~synthkit.methods.retarget.synthesis.assemble`
    (one block of vertices per label), ``F (m, 3)``, ``face_label (m,)``. Two vertices are merged
    when they are within ``tol`` (normalised units) of each other, belong to different labels'
    copies and lie within ``tol`` of a voxel face plane (a seam between two labels' voxels may run
    across any axis); every other vertex is kept as it is, so parts of the input
    that only touch (a baluster standing on a rail, the unwelded UV seams of an asset) keep their
    own vertices, as in the input.

    Returns ``(V (#V2, 3) normalised, F2 (#F2, 3), old_to_new (n,))`` as :func:`~synthkit.core.mesh.weld`.
    """
    Vc = np.asarray(Vc, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    Vn = grid.to_normalised(Vc)
    pairs = np.zeros((0, 2), np.int64)
    if len(Vc):
        vlab = np.full(len(Vc), -1, np.int64)
        vlab[F.reshape(-1)] = np.repeat(np.asarray(face_label, np.int64), 3)
        frac = Vc - grid.origin
        dist = np.abs(frac - np.rint(frac)) / np.linalg.norm(grid.inverse, axis=1)  # normalised units
        on_seam = np.flatnonzero((dist <= tol).any(axis=1) & (vlab >= 0))
        if len(on_seam) > 1:
            pairs = on_seam[cKDTree(Vn[on_seam]).query_pairs(tol, output_type="ndarray")]
            pairs = pairs[vlab[pairs[:, 0]] != vlab[pairs[:, 1]]]
    return merge_vertices(Vn, F, pairs, return_index=True)


def resolve_steps(target, an: Analysis, Vn, *, source, keys: dict | None = None) -> np.ndarray:
    """Steps ``(3,)`` per basis column from the config's target (steps, axis_steps or scale).

    ``scale`` factor f along principal offset i becomes ``round((f - 1) * extent_i)`` steps, with
    ``extent_i`` the model's extent along canonical axis i in steps. Steps along dummy directions
    are refused (InputError naming the key), as the paper never resizes along them. ``keys``, when
    given, is filled with ``axis -> "key=value"`` for the config entries that gave each axis its steps.
    """
    keys = {} if keys is None else keys
    k = an.n_principal
    steps = np.zeros(3, dtype=np.int64)
    if target.axis_steps is not None:
        used: dict[int, str] = {}
        for name, s in target.axis_steps.items():
            axis = np.eye(3)["xyz".index(name)]
            if k == 0:
                if s:
                    raise InputError(f"{source}: target.axis_steps.{name}={s}: no principal offset was found")
                continue
            P = an.basis[:, :k].T
            cos = np.abs(P @ axis) / np.linalg.norm(P, axis=1)
            i = int(np.argmax(cos))
            if i in used and s:
                raise InputError(f"{source}: target.axis_steps: {used[i]} and {name} both map to principal offset {i}")
            if s:
                used[i] = name
                steps[i] += s
                keys[i] = f"target.axis_steps.{name}={s}"
        return steps
    if target.scale is not None:
        ext = np.ptp(Vn @ np.linalg.inv(an.basis).T, axis=0)
        for i, f in enumerate(target.scale):
            steps[i] = int(round((f - 1.0) * ext[i]))
            keys[i] = f"target.scale[{i}]={f} ({int(steps[i])} steps)"
            if steps[i] and i >= k:
                raise InputError(f"{source}: target.scale[{i}]={f}: only {k} principal offset(s) were found")
        return steps
    given = target.steps if target.steps is not None else [1]
    for i, s in enumerate(given):
        if s and i >= k:
            raise InputError(f"{source}: target.steps[{i}]={s}: only {k} principal offset(s) were found")
        steps[i] = s
        keys[i] = f"target.steps[{i}]={s}"
    return steps


def _written_faces(res: Retargeted, Vm, asset: Asset):
    """The result's faces as written: ``(F (k, 3), face_material (k,), corner_uv (k, 3, 2) or None,
    corner_color (k, 3, 4) uint8 or None, dropped)``, without its degenerate faces
    (:func:`_degenerate` in model units ``Vm``; ``dropped`` counts them)."""
    keep = ~_degenerate(Vm, res.F)
    if res.attr is None:
        return res.F[keep], np.zeros(int(keep.sum()), np.int64), None, None, int((~keep).sum())
    mat, uv, col = unpack(res.attr[keep], asset.corner_uv is not None, asset.corner_color is not None)
    return res.F[keep], mat, uv, col, int((~keep).sum())


def _degenerate(V, F) -> np.ndarray:
    """``(#F,) bool``: the faces :func:`~synthkit.core.quality.mesh_quality` counts as degenerate,
    :func:`~synthkit.core.quality.degenerate_faces` or collapsed by its weld (an edge shorter than
    :data:`~synthkit.core.quality.WELD_REL_TOL` of the diagonal)."""
    if len(F) == 0:
        return np.zeros(0, bool)
    diag = float(np.linalg.norm(np.ptp(V[np.unique(F)], axis=0)))
    Fw = weld(V, np.zeros((0, 3), np.int64), WELD_REL_TOL * diag, return_index=True)[2][F]
    collapsed = (Fw[:, 0] == Fw[:, 1]) | (Fw[:, 1] == Fw[:, 2]) | (Fw[:, 2] == Fw[:, 0])
    return degenerate_faces(V, F) | collapsed


def _input_quality(V, F) -> dict:
    """:func:`~synthkit.core.quality.mesh_quality` of the input (model units) with each surface
    stored twice counted once (the output is judged the same way, since :func:`synthesize` drops
    such faces), except ``duplicate_faces``, which counts the input's own. A face and its duplicate
    close each other's edges: house1_baked's 528 faces show 74 open edges, its 422 distinct faces
    128."""
    diag = float(np.linalg.norm(np.ptp(V[np.unique(F)], axis=0)))
    keep = unique_faces(V, F, tol=WELD_REL_TOL * diag)
    q = mesh_quality(V, F[keep])
    if not keep.all():
        q["duplicate_faces"] = mesh_quality(V, F)["duplicate_faces"]
    return q


def _check_result(res: Retargeted, F_written, center, scale, Vn, F, input_quality: dict, ctx, key: str) -> dict:
    """Check the written mesh (``F_written`` over the result's vertices) against the input with
    :meth:`~synthkit.runner.RunContext.check_quality` under ``key`` and return retargeting's own
    figures. Limits: open and non-manifold edges at most the input's times the copies used (each
    copy brings its own: the generated facade's touching boxes have 96 non-manifold edges, two
    copies of them 142; the Kenney houses and house1 have none, so none may appear), no degenerate
    or duplicate face. Extras:
    ``copies``, ``volume_ratio`` (output bounding box over input bounding box), ``face_ratio``,
    ``faces_limit`` (issue 15's bound, input faces x volume ratio x 1.5: a figure, no longer a
    limit, since flat regions now merge only within one UV map and house1_baked's atlas charts keep
    1,132 faces against 892), the smallest angle and the faces below
    :data:`~synthkit.methods.retarget.synthesis.SLIVER_DEG` of input and output
    (:func:`~synthkit.methods.retarget.synthesis.sliver_figures`)."""
    copies = int(len(np.unique(res.labeling)))
    used = np.unique(F)
    vin = float(np.prod(np.maximum(np.ptp(Vn[used], axis=0), 1e-12)))
    vout = float(np.prod(np.maximum(np.ptp(res.V, axis=0), 1e-12))) if len(res.V) else 0.0
    ratio = vout / vin
    q = mesh_quality(res.V * scale + center, F_written)
    limits = {
        "open_edges": int(input_quality["open_edges"] * copies),
        "nonmanifold_edges": int(input_quality["nonmanifold_edges"] * copies),
        "degenerate_faces": 0,
        "duplicate_faces": 0,
    }
    ctx.check_quality(key, input_quality, q, limits)
    s_in, s_out = sliver_figures(Vn, F[unique_faces(Vn, F)]), sliver_figures(res.V, F_written)
    return {
        "copies": copies,
        "volume_ratio": ratio,
        "face_ratio": q["faces"] / max(input_quality["faces"], 1),
        "faces_limit": int(np.floor(input_quality["faces"] * ratio * 1.5)),
        "min_angle_deg": s_out["min_angle_deg"],
        "input_min_angle_deg": s_in["min_angle_deg"],
        "sliver_faces": s_out["sliver_faces"],
        "input_sliver_faces": s_in["sliver_faces"],
    }


def _result_metrics(res: Retargeted, steps, graphcut_seconds: float, scale: float) -> dict:
    p = res.problem
    lab = res.labeling
    pair = p.pairwise(np.arange(len(p.edges)), lab[p.edges[:, 0]], lab[p.edges[:, 1]]) if len(p.edges) else np.zeros(0)
    return {
        "infinite_terms": int((~np.isfinite(pair)).sum()),
        "energy_finite_part": float(pair[np.isfinite(pair)].sum()),
        "growth": (res.grid.basis @ np.asarray(steps) * scale).tolist(),
        "grid_basis_normalised": res.grid.basis.T.tolist(),
        "grid_origin": res.grid.origin.tolist(),
        "graph_nodes": int(res.problem.n_nodes),
        "graph_labels": int(res.problem.n_labels),
        "graph_edges": int(len(res.problem.edges)),
        "energy": float(res.energy),  # infinite when seams join empty to non-empty voxels (JSON null)
        "cycles": int(res.cycles),
        "graphcut_seconds": float(graphcut_seconds),
        "steps": np.asarray(steps).tolist(),
        "grid_in": res.grid.shape.tolist(),
        "grid_out": res.problem.out_shape.tolist(),
        "label_shifts": res.problem.labels.tolist(),
        "labels_used": int(len(np.unique(res.labeling))),
        "output_faces": int(len(res.F)),
        "labelled_faces": int(len(res.labelled_F)),
        "output_vertices": int(len(res.V)),
    }


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
        super().__init__(message, keep_outputs=keep_outputs)
        self.result = result


def _load(cfg, inputs: Inputs, ctx):
    """Read the input with its appearance: ``(asset, Vn (#V, 3) normalised, center (3,), scale,
    (Va, Fa) the mesh the analysis samples, normalised, suffix of the output mesh)``. A scene of
    several meshes (a GLB/glTF scene) becomes one mesh (materials kept per face; the nodes are not:
    ``metrics.merged_meshes`` and one warning). An OBJ's material groups are one mesh already.

    The analysis samples the surface as :func:`~synthkit.io.meshes.load_mesh` gives it (the
    figures of the README's table). Finding (issue 22): :func:`~synthkit.io.assets.load_asset`
    keeps an OBJ's faces in file order, trimesh groups them otherwise; the Poisson-disk pool is
    drawn per face in order, and on house1_baked the other sample (1,313 features against 1,314)
    picks a 0.403 x slide instead of the 0.383 floor as principal offset, along which no labeling
    is seamless. Both are the same surface; only the stitching needs the asset's corners."""
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
        log.warning("merged %d meshes of %s", merged, cfg.input)
    try:
        _, center, scale = normalize_unit(V[np.unique(F)])
    except ValueError as exc:
        raise InputError(f"{cfg.input}: {exc}") from None
    Vn = (V - center) / scale
    Va, Fa = (np.asarray(mesh.vertices, dtype=np.float64) - center) / scale, np.asarray(mesh.faces, dtype=np.int64)
    ctx.metrics["input_faces"] = int(len(F))
    return asset, Vn, center, scale, (Va, Fa), suffix


def statistics_metrics(an: Analysis, center, scale: float) -> dict:
    """``report.json``'s figures of the analysis (model units unless ``_normalised``)."""
    order = np.argsort(-an.dominant_counts, kind="stable")
    return {
        "principal_offsets": (an.principal * scale).tolist(),
        "principal_offsets_normalised": an.principal.tolist(),
        "n_principal": an.n_principal,
        "basis_normalised": an.basis.T.tolist(),
        "dominant_offsets": [
            {
                "offset": (an.dominant_refined[i] * scale).tolist(),
                "offset_normalised": an.dominant_refined[i].tolist(),
                "before_icp_normalised": an.dominant[i].tolist(),
                "count": int(an.dominant_counts[i]),
                "overlap": float(an.dominant_overlap[i]),
                "grip": float(an.dominant_grip[i]),
                "principal": int(i) in an.principal_index,
            }
            for i in order
        ],
        "sparsity_top7": an.top7,
        "sparsity_top20": an.top20,
        "n_features": int(len(an.features.P)),
        "n_vertex_features": int(an.features.n_vertex_features),
        "n_dense_samples": int(len(an.features.dense_P)),
        "n_offsets": int(len(an.offsets)),
        "n_statistics_features": int(an.n_statistics_features),
        "n_statistics_offsets": int(len(an.stat_offsets)),
        "n_bins": int(len(an.bin_counts)),
        "normalisation": {"center": np.asarray(center).tolist(), "scale": float(scale)},
    }


def _retarget_all(cfg, an: Analysis, Vn, F, attr, ctx) -> list[tuple[str, Retargeted, np.ndarray, float]]:
    """The retargeted meshes the config asks for: ``(prefix, result, steps, graph-cut seconds)``
    of the statistics result (prefix ``""``) and of the regular baseline (``"baseline_"``, or
    ``""`` with ``offsets: regular``)."""
    step_keys: dict[int, str] = {}
    steps = resolve_steps(cfg.target, an, Vn, source=cfg.input, keys=step_keys)
    growth = an.basis @ steps
    results = []
    if cfg.offsets == "statistics":
        res = synthesize(Vn, F, an, an.basis, steps, cfg=cfg, ctx=ctx, step_keys=step_keys, attr=attr)
        results.append(("", res, steps, ctx.timings["graphcut"]))
    if cfg.offsets == "regular" or cfg.compare_baseline:
        h = cfg.regular_spacing
        reg_steps = np.rint(growth / h).astype(np.int64)
        prefix = "baseline_" if cfg.offsets == "statistics" else ""
        res_b = synthesize(
            Vn, F, an, h * np.eye(3), reg_steps, cfg=cfg, ctx=ctx, prefix=prefix or "regular_", allow_infinite=True,
            attr=attr,
        )
        results.append((prefix, res_b, reg_steps, ctx.timings[f"{prefix or 'regular_'}graphcut"]))
    if cfg.offsets == "regular":
        ctx.timings["graphcut"] = ctx.timings.get("regular_graphcut", 0.0)
    return results


def _in_model_units(res: Retargeted, asset: Asset, center, scale, suffix: str, cfg, ctx, prefix: str) -> RetargetedMesh:
    """One result as written, in model units, without its degenerate faces (one warning line
    saying how many, ``metrics.degenerate_faces_dropped``)."""
    Vm = res.V * scale + center
    F, mat, uv, col, dropped = _written_faces(res, Vm, asset)
    if dropped:
        log.warning("%s: %d degenerate faces left out of %sretargeted%s", cfg.input, dropped, prefix, suffix)
    ctx.metrics.setdefault("degenerate_faces_dropped", {})[f"{prefix}mesh"] = dropped
    lab_keep = ~_degenerate(Vm, res.labelled_F)
    out = Asset(V=Vm, F=F, corner_uv=uv, corner_color=col, face_material=mat, materials=asset.materials,
                name=asset.name, source=asset.source)
    return RetargetedMesh(
        asset=out, mesh=trimesh.Trimesh(Vm, F, process=False),
        label_volume=res.problem.volume(res.labeling).astype(np.int32),
        labelled_mesh=trimesh.Trimesh(Vm, res.labelled_F[lab_keep], process=False),
        face_labels=res.face_label[lab_keep], label_shifts=res.problem.labels, n_nodes=int(res.problem.n_nodes),
    )


def compute(cfg, inputs: Inputs, ctx) -> RetargetResult:
    """Run the retargeting described by ``cfg`` (a :class:`RetargetConfig`) on ``inputs``; write
    nothing. Raises :class:`NoRepetition` (an InputError that keeps the statistics) when the
    analysis finds no principal offset and the config asks for more than the analysis."""
    with ctx.stage("load"):
        asset, Vn, center, scale, (Va, Fa), suffix = _load(cfg, inputs, ctx)
        V, F = asset.V, asset.F
        attr = pack(asset.face_material, asset.corner_uv, asset.corner_color)
        area = 0.5 * np.linalg.norm(np.cross(Vn[F[:, 1]] - Vn[F[:, 0]], Vn[F[:, 2]] - Vn[F[:, 0]]), axis=1)
        if not area.sum() > 1e-12:
            raise InputError(f"{cfg.input}: degenerate mesh: all {len(F)} triangles have zero area")
    check_analysis_budget(ctx.budget, cfg.analysis, float(area.sum()), len(np.unique(F)))
    with ctx.stage("analysis"):
        an = analyze(Va, Fa, options_of(cfg)[0], rng=ctx.rng)
    ctx.metrics.update(statistics_metrics(an, center, scale))
    ctx.metrics["analyze_only"] = bool(cfg.analyze_only)
    result = RetargetResult(**result_fields(cfg, ctx, inputs), input_asset=asset, analysis=an, center=center,
                            scale=float(scale), suffix=suffix)
    if cfg.analyze_only:
        return result
    if an.n_principal == 0:
        ctx.metrics["error"] = "no repetition found"
        raise NoRepetition(
            f"{cfg.input}: no repetition found (no dominant offset maps at least {cfg.analysis.min_overlap:.0%} of "
            f"the surface onto itself; {len(an.dominant)} histogram peaks, top-7% share {an.top7:.2f}); "
            "refusing to resize",
            result=result,
        )
    results = _retarget_all(cfg, an, Vn, F, attr, ctx)
    with ctx.stage("quality"):
        input_quality = _input_quality(V, F)
        for prefix, res, st, secs in results:
            out = _in_model_units(res, asset, center, scale, suffix, cfg, ctx, prefix)
            metrics = _result_metrics(res, st, secs, scale)
            metrics.update(_check_result(res, out.asset.F, center, scale, Vn, F, input_quality, ctx, f"{prefix}mesh"))
            if prefix:
                ctx.metrics["baseline"] = metrics
                result.baseline = out
            else:
                ctx.metrics.update(metrics)
                result.retargeted = out
    return result


def run(cfg, ctx) -> None:
    """Run the retargeting described by ``cfg`` into ``ctx`` (the command line's path): compute,
    then write; a mesh without repetition writes its statistics before it is refused."""
    try:
        result = compute(cfg, Inputs(), ctx)
    except NoRepetition as exc:
        if exc.result is not None:
            exc.result.write(ctx)
        raise
    result.write(ctx)
