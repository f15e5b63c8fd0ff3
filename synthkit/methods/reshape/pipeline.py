"""``synthkit reshape``: read the pieces, build the constraint graph and system, drag the handles,
reshape the textures; the only module that knows config keys and exit codes.

:func:`compute` runs every stage over inputs read through an :class:`~synthkit.io.inputs.Inputs`
(files, or meshes given in memory) and returns a
:class:`~synthkit.methods.reshape.outputs.ReshapeResult`; :func:`run` (the command line) writes it.
Stages (``report.json`` ``timings``): ``load``, ``assemble`` (portals, chain placement), ``graph``
(3.1), ``constraints`` (3.2, handles, links), ``factor`` and ``solve`` (3.3-3.4), ``baseline``
(Laplacian edge-vector deformation with the same handles), ``texture`` (section 4), then
``texture_previews`` and ``outputs`` when written. Metrics: the paper's Table 4 columns (``vars``,
``nnz_A``, ``nnz_AtA``, ``nodes``, ``edges``, ``equations``, ``factor_ms``, ``solve_ms``) and the
quality figures (docs/reshape.md).

The geometry has no random choice; the texture stage draws tile seeds and quilting patches from
the run's ``rng`` (same seed, same textures).

A motion that would flip an edge is refused: by default an InputError (exit 3) naming the edge
and the step, nothing written; with ``solver.allow_partial`` the last valid step is written and
``metrics.status`` is ``"partial"``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from synthkit.core.quality import mesh_quality
from synthkit.errors import ConfigError, InputError, KeyedError, user_error
from synthkit.io.assets import load_asset
from synthkit.io.images import load_image
from synthkit.io.inputs import Inputs, image_from_array
from synthkit.methods.reshape import retexture as RT
from synthkit.methods.reshape.assemble import assemble, frozen_nodes, place_pieces, portal_gaps, snap_joined
from synthkit.methods.reshape.graph import ConstraintGraph, build_graph
from synthkit.methods.reshape.handles import PieceRange, resolve_fixed, resolve_handles, resolve_links
from synthkit.methods.reshape.options import Options, options_of
from synthkit.methods.reshape.outputs import PreviewData, ReshapeResult, reshaped
from synthkit.methods.reshape.parts import mesh_parts, part_distances
from synthkit.methods.reshape.resize import Resize, axis_factors, plan_resize, resize_metrics
from synthkit.methods.reshape.solver import DragResult, FactorCache, drag
from synthkit.methods.reshape.system import (
    baseline_positions,
    build_system,
    quality_figures,
    strict_residuals,
)
from synthkit.methods.reshape.textured import TexturedMesh, material_textures, textured_from_asset
from synthkit.result import result_fields

__all__ = ["compute", "load_textured", "Scene", "MEMORY_PIECE"]

log = logging.getLogger("synthkit")

_BYTES_PER_NNZ = 400.0
"""Memory per nonzero of A, counting A^T A, its Cholesky factor and work arrays (measured order)."""

MAX_MOTION = 100.0
"""Largest motion of a handle or of a resized end, in model sizes (bounding-box diagonals); farther
motions are refused (ConfigError): the strict residuals grow with the motion (docs/findings/reshape.md)."""

_BYTES_PER_TEXEL = 160.0
"""Memory per texel of the texture stage (maps, base and detail, distortion map, bake, naive)."""


TEXTURED_SUFFIXES = (".obj", ".glb", ".gltf")
"""The mesh formats reshape reads (with their UVs and materials)."""

MEMORY_PIECE = "mesh"
"""The piece name (and output file stem) of an ``input`` mesh given in memory."""


def _pieces(cfg, inputs: Inputs | None = None) -> list[tuple[str, object, dict]]:
    """``(name, input, portals)`` per piece; an ``input`` given in memory is named ``mesh``."""
    if cfg.input is not None:
        memory = inputs is not None and inputs.is_memory(cfg.input)
        return [(MEMORY_PIECE if memory else cfg.input.stem, cfg.input, {})]
    return [(p.name, p.input, p.portals) for p in cfg.pieces]


def _vertex_name(node: int, graph: ConstraintGraph, ranges: list[PieceRange]) -> str:
    """'vertex 12 of piece' for a node (its first render vertex)."""
    r = int(np.flatnonzero(graph.node_of_vertex == node)[0])
    p = next(p for p in ranges if p.start <= r < p.stop)
    return f"vertex {int(p.position_index[r - p.start])} of {p.name}"


def _check_motion(key: str, value, motion: float, size: float) -> None:
    """Refuse (ConfigError naming ``key`` and ``value``) a motion past ``MAX_MOTION`` model sizes."""
    if not motion <= MAX_MOTION * size:
        raise ConfigError(
            f"{key}: {value} moves vertices by {motion / size:.3g} model sizes; at most {MAX_MOTION:g} "
            "(farther, the solve leaves the model's numeric range)"
        )


def _handle_motions(cfg, graph, size: float) -> None:
    """Every handle's ``displacement`` (its length), or its ``target`` (the distance to the model's
    bounding box), within ``MAX_MOTION`` model sizes."""
    lo, hi = graph.X0.min(axis=0), graph.X0.max(axis=0)
    for i, h in enumerate(cfg.handles):
        if h.displacement is not None:
            _check_motion(f"handles[{i}].displacement", h.displacement, float(np.linalg.norm(h.displacement)), size)
        else:
            t = np.asarray(h.target)
            _check_motion(f"handles[{i}].target", h.target, float(np.linalg.norm(t - np.clip(t, lo, hi))), size)


def _selections(cfg, graph, V, ranges, resize=None):
    """Handles ``(k,)`` with targets ``(k, 3)``, fixed ``(f,)`` and link pairs, as ConfigErrors. A
    resize's end nodes are handles where its rest shape moves them and fixed elsewhere."""
    try:
        links = resolve_links(cfg.links, ranges, V, graph.node_of_vertex)
        if resize is not None:
            moved = np.linalg.norm(resize.R[resize.known] - graph.X0[resize.known], axis=1) > 1e-12 * np.ptp(graph.X0)
            handles = resize.known[moved]
            return handles, resize.R[handles], resize.known[~moved], links
        handles, targets = resolve_handles(cfg.handles, ranges, V, graph.node_of_vertex, graph.X0)
        fixed = resolve_fixed(cfg.fixed, handles, ranges, V, graph.node_of_vertex)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    return handles, targets, fixed, links


def _resize(cfg, opt: Options, graph, sc) -> Resize | None:
    """The resize of a ``scale`` or ``size`` config (None for explicit handles)."""
    if cfg.scale is None and cfg.size is None:
        return None
    used = np.unique(graph.Fn)
    extent = graph.X0[used].max(axis=0) - graph.X0[used].min(axis=0)
    try:
        factors, asked = axis_factors(cfg.scale, cfg.size, extent)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    key = "scale" if cfg.scale is not None else "size"
    for a, value in enumerate((cfg.scale or cfg.size).values()):
        if value is not None:
            _check_motion(f"{key}.{'xyz'[a]}", value, abs(factors[a] - 1.0) * extent[a], sc.size)
    p = opt.parts
    return plan_resize(graph.X0, graph.Fn, factors, asked, rigid_share=p.rigid_share, end_tol=p.end_tol)


def _known(graph, handles, fixed) -> np.ndarray:
    """Known nodes: handles, fixed, then the nodes no triangle uses (they keep their place)."""
    used = np.zeros(graph.n_nodes, bool)
    used[graph.Fn.reshape(-1)] = True
    return np.concatenate([handles, fixed, np.flatnonzero(~used)])


def _check_quality(ctx, name: str, mesh, P) -> None:
    """``ctx.check_quality`` of a written piece against its input: a reshape moves vertices and
    keeps the faces, so no figure may exceed the input's (a face collapsed by the move shows as a
    new degenerate face)."""
    before = mesh_quality(mesh.V, mesh.F)
    after = mesh_quality(P[mesh.position_index], mesh.F)
    limits = {key: before[key] for key in ("open_edges", "nonmanifold_edges", "degenerate_faces", "duplicate_faces")}
    ctx.check_quality(f"mesh_{name}", before, after, limits)


def _refuse(cfg, result: DragResult, graph, ranges, steps: int) -> None:
    a, b = (_vertex_name(n, graph, ranges) for n in result.edge)
    key = "handles" if cfg.handles else ("scale" if cfg.scale is not None else "size")
    msg = (
        f"{key}: the edge between {a} and {b} would flip at step {result.step} of {steps}; "
        f"motion refused, last valid step {result.steps_done} (solver.allow_partial: true writes it)"
    )
    raise InputError(msg)


@dataclass
class Scene:
    """The assembled pieces: names, meshes, world offsets ``(3,)``, joins (report) and joined portal
    vertices, render vertices ``V (#V, 3)``, ``F (#F, 3)``, materials, piece ranges, model size."""

    names: list
    meshes: list
    offsets: list
    joins: list
    joined: list
    V: np.ndarray
    F: np.ndarray
    face_material: np.ndarray
    ranges: list
    size: float
    source: object


def load_textured(path: Path | str) -> TexturedMesh:
    """The textured mesh of the OBJ or glTF file ``path``. Raises InputError naming the file for
    another format and whatever :func:`~synthkit.io.assets.load_asset` refuses."""
    suffix = Path(path).suffix.lower()
    if suffix not in TEXTURED_SUFFIXES:
        raise InputError(f"{path}: unsupported textured mesh format {suffix!r} (use {', '.join(TEXTURED_SUFFIXES)})")
    return textured_from_asset(load_asset(path))


def _read(inputs: Inputs, path) -> TexturedMesh:
    """The textured mesh at ``path``, or given in memory for it."""
    if not inputs.is_memory(path):
        return load_textured(path)
    asset = inputs.asset(path)
    key = str(asset.source)
    textures = {m.name: image_from_array(m.image, f"{key}: material {m.name}")
                for m in asset.materials if m.image is not None}
    return textured_from_asset(asset, key, textures)


def _load(cfg, opt: Options, inputs: Inputs, ctx) -> Scene:
    specs = _pieces(cfg, inputs)
    names = [n for n, _, _ in specs]
    with ctx.stage("load"):
        meshes = [_read(inputs, path) for _, path, _ in specs]
    with ctx.stage("assemble"):
        lo = np.min([m.V.min(axis=0) for m in meshes], axis=0)
        hi = np.max([m.V.max(axis=0) for m in meshes], axis=0)
        piece_size = float(np.linalg.norm(hi - lo)) or 1.0
        try:
            offsets, joins, joined = place_pieces(names, meshes, [p for _, _, p in specs], cfg.chain,
                                                  tol=opt.graph.portal_tol * piece_size)
        except KeyedError as exc:
            raise user_error(exc) from None
        V, F, fm, ranges = assemble(names, meshes, offsets)
        snap_joined(V, ranges, joined)
    size = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) or 1.0
    return Scene(names, meshes, offsets, joins, joined, V, F, fm, ranges, size, meshes[0].source)


def _graph(opt: Options, ctx, sc: Scene) -> ConstraintGraph:
    with ctx.stage("graph"):
        try:
            graph = build_graph(
                sc.V, sc.F, sc.face_material, weld_tol=opt.graph.weld_tol * sc.size,
                flat_angle_deg=opt.graph.flat_angle_deg,
            )
        except ValueError as exc:
            raise InputError(f"{sc.source}: {exc}") from None
    if not len(graph.edges):
        raise InputError(f"{sc.source}: the constraint graph has no edge")
    if graph.counts["ill_formed_contour_vertices"]:
        log.warning("%s: %d contour vertices are not on exactly two contour edges (contours not well formed)",
                    sc.source, graph.counts["ill_formed_contour_vertices"])
    return graph


def _metrics(cfg, sc, graph, system, solver, result, quality, extra) -> dict:
    """The report's metrics: the drag's outcome first (the CLI's one-line summary shows the first
    four), then Table 4 columns, counts and the ``quality`` figures."""
    m = dict(
        status=result.status, steps_done=result.steps_done, max_angle_error_deg=quality["max_angle_error_deg"],
        factor_ms=solver.factor_ms, vars=solver.vars, nnz_A=solver.nnz_A, nnz_AtA=solver.nnz_AtA,
        nodes=graph.counts["nodes"], edges=int(len(graph.edges)), equations=int(system.A.shape[0]),
        solve_ms=float(np.median(solver.solve_ms)) if solver.solve_ms else None,
        backend=solver.backend, steps=cfg.solver.steps,
        length_raises=result.length_raises, edge_groups=len(system.groups),
        grouped_edges=int(sum(len(g) for g in system.groups)), contacts=int(len(system.contacts)),
        l_min=system.l_min, rigid_edges=int(system.rigid.sum()), graph=graph.counts, joins=sc.joins,
        strict_weight=cfg.strict.weight,
        strict_residuals=strict_residuals(system, result.X, cfg.strict.weight, sc.size),
        **extra,
    )
    m.update(quality)
    for join, gap in zip(sc.joins, portal_gaps(sc.joined, sc.ranges, result.X[graph.node_of_vertex]), strict=True):
        join["gap"] = gap / sc.size
    if result.status == "partial":
        m["refused_edge"] = [_vertex_name(n, graph, sc.ranges) for n in result.edge]
        m["refused_step"] = result.step
    return m


def _textures(opt: Options, ctx, sc, graph, X) -> tuple[dict, dict]:
    """The texture stage (``texture: reshape``): per piece index the Retexture entries, and per
    surface ``(job, result, analysis)`` (the previews draw them); metrics ``surfaces`` and their
    worst case go into the report."""
    ctx.metrics["texture"] = opt.texture.mode
    if opt.texture.mode == "stretch":
        return {}, {}
    options = opt.texture
    with ctx.stage("texture"):
        textures, notes, given = _texture_sources(sc)
        images, skipped = {}, {}
        try:
            jobs, untouched = RT.surface_jobs(
                sc.meshes, textures, sc.ranges, graph.face_surface, sc.V, X[graph.node_of_vertex], options=options,
                read=lambda path: given[path] if path in given else load_image(path), images=images, skipped=skipped,
            )
            texels = float(sum(img.shape[0] * img.shape[1] for img in images.values()))
            ctx.budget.require("texture_reshape", f"{len(images)} textures", 4.0 * texels, "texels",
                               bytes_each=_BYTES_PER_TEXEL)
            results = RT.reshape_jobs(jobs, images, ctx.rng, options=options)
        except KeyedError as exc:
            raise user_error(exc) from None
        entries, boxes = RT.atlas_entries(sc.meshes, results, images)
        boxes = {name: (box, f"{sc.names[results[name][0].piece]}_{file}") for name, (box, file) in boxes.items()}
        ctx.metrics.update(RT.texture_metrics(results, notes, untouched, skipped, boxes))
        ctx.metrics["texture_images"] = sum(len(e) for e in entries.values())
    return entries, results


def _texture_sources(sc: Scene) -> tuple[list[dict | None], dict, dict]:
    """Per piece material -> texture path (an OBJ's ``map_Kd`` files; for a mesh given in memory a
    stand-in path ``<key>/<material>``), or None for a GLB (embedded textures keep the naive
    stretch: a note per such piece); and the stand-in path -> texture of meshes given in memory."""
    textures, notes, given = [], {}, {}
    for mesh, r in zip(sc.meshes, sc.ranges, strict=True):
        if mesh.in_memory:
            found = {m: Path(str(mesh.source), m) for m in mesh.textures}
            given.update({found[m]: img for m, img in mesh.textures.items()})
        elif mesh.source.suffix.lower() == ".obj":
            found = material_textures(mesh)
        else:
            found = None
            notes[r.name] = "GLB: embedded textures keep the naive stretch"
        textures.append(found)
    return textures, notes, given


def _free_parts(opt: Options, graph, sc, links) -> list[dict]:
    """Parts (face-connected components; the one with most nodes is the root) farther than
    ``parts.attach_distance`` from every other part and not linked to one (``links (k, 2)``):
    carried by the nearest surface all the same, listed in ``metrics.free_parts`` and named in
    one warning line."""
    part = mesh_parts(graph.Fn, graph.n_nodes)
    if part.max() < 1:
        return []
    dist = part_distances(graph.X0, graph.Fn, part) / sc.size
    dist[np.argmax(np.bincount(part[part >= 0]))] = 0.0
    pl = part[np.asarray(links, np.int64).reshape(-1, 2)]
    linked = np.unique(pl[pl[:, 0] != pl[:, 1]])
    free = []
    for k in np.setdiff1d(np.flatnonzero(dist > opt.parts.attach_distance), linked):
        nodes = np.flatnonzero(part == k)
        free.append({"part": int(k), "first": _vertex_name(int(nodes[0]), graph, sc.ranges),
                     "nodes": int(len(nodes)), "centre": graph.X0[nodes].mean(axis=0).round(6).tolist(),
                     "distance": float(dist[k])})
    if free:
        names = "; ".join(f"part {f['part']} ({f['nodes']} nodes from {f['first']}, {f['distance']:.3g})"
                          for f in free)
        log.warning("%s: %d parts lie farther than parts.attach_distance (%g of the model size) from any other "
                    "part and are carried by the nearest surface: %s", sc.source, len(free),
                    opt.parts.attach_distance, names)
    return free


def _stretches_nothing(cfg, quality) -> None:
    """Refuse (ConfigError) a recipe whose result only moves the model rigidly (handles that select
    everything, or nothing fixed)."""
    key = "handles" if cfg.handles else ("scale" if cfg.scale is not None else "size")
    if quality["max_stretch"] - 1 < 1e-6 and 1 - quality["min_stretch"] < 1e-6:
        raise ConfigError(
            f"{key}: the recipe stretches nothing (every edge keeps its length within 1e-6; the handles move the "
            "model rigidly): select handles and fixed vertices on different sides of what should stretch"
        )


def _solve(cfg, opt: Options, ctx, sc, graph, system, handles, targets, known, rest):
    """Factor and drag (one step for a resize: its rest shape is the target); returns the drag
    result, the positions the known nodes reached, the solver, the cache and the frozen nodes."""
    T = rest.copy()
    T[handles] = targets
    frozen = frozen_nodes(sc.ranges, graph.node_of_vertex, cfg.chain, handles, opt.drag.propagation)
    options = opt.drag
    steps = options.steps
    with ctx.stage("factor"):
        cache = FactorCache(system.A, backend=options.backend)
        try:
            full = cache.get(known)
            limited = cache.get(np.union1d(known, frozen)) if len(frozen) else full
        except ValueError as exc:
            raise InputError(f"{sc.source}: constraint system cannot be solved: {exc}") from None
    with ctx.stage("solve"):
        result = drag(
            lambda step: full if step == steps else limited, system.b, X0=rest, T=T, edges=graph.edges,
            stress_slice=system.slices["stress"], stress_weights=system.stress_weights, options=options,
            progress=lambda s: ctx.progress(s, total=steps, desc="reshape steps"), lengths=system.lengths,
        )
    if result.status == "partial" and not options.allow_partial:
        _refuse(cfg, result, graph, sc.ranges, steps)
    reached = rest[known] + (result.steps_done / steps) * (T[known] - rest[known])
    return result, reached, full, cache, frozen


def compute(cfg, inputs: Inputs, ctx) -> ReshapeResult:
    """Reshape the pieces of a validated :class:`~synthkit.methods.reshape.config.ReshapeConfig`
    read through ``inputs``; every stage, nothing written (:meth:`ReshapeResult.write` writes)."""
    opt = options_of(cfg)
    sc = _load(cfg, opt, inputs, ctx)
    graph = _graph(opt, ctx, sc)
    with ctx.stage("constraints"):
        resize = _resize(cfg, opt, graph, sc)
        _handle_motions(cfg, graph, sc.size)
        handles, targets, fixed, links = _selections(cfg, graph, sc.V, sc.ranges, resize)
        ctx.budget.require("input" if cfg.input is not None else "pieces", str(sc.source),
                           60.0 * len(graph.edges) + 30.0 * graph.n_nodes,
                           "matrix entries", bytes_each=_BYTES_PER_NNZ)
        rest = graph.X0 if resize is None else resize.R
        system = build_system(graph, links, options=opt.system, size=sc.size,
                              known=np.concatenate([handles, fixed]),
                              rest=None if resize is None else rest,
                              factors=None if resize is None else resize.node_factors())
        known = _known(graph, handles, fixed)
        free = _free_parts(opt, graph, sc, links)
    result, reached, full, cache, frozen = _solve(cfg, opt, ctx, sc, graph, system, handles, targets, known, rest)
    counts = dict(links=int(len(links)), handles=int(len(handles)), fixed=int(len(fixed)),
                  attached_parts=int(len(system.attachment.nodes)), free_parts=free, frozen_nodes=int(len(frozen)),
                  factorizations=len(cache), factor_cache_hits=cache.hits)
    quality = quality_figures(graph, system, result.X, known, reached, sc.size, rest)
    _stretches_nothing(cfg, quality)
    if resize is not None:
        counts.update(resize_metrics(resize, graph.X0, graph.Fn, result.X))
    ctx.metrics.update(_metrics(cfg, sc, graph, system, full, result, quality, counts))
    if result.status == "partial":
        ctx.status = "partial"
    Xb = None
    if cfg.baseline:
        with ctx.stage("baseline"):
            Xb = baseline_positions(graph, known, reached, opt.drag.backend)
        base = quality_figures(graph, system, Xb, known, reached, sc.size, rest)
        ctx.metrics["baseline"] = base
        ctx.metrics["baseline_angle_ratio"] = base["max_angle_error_deg"] / max(
            ctx.metrics["max_angle_error_deg"], 1e-12
        )
    retex, surfaces = _textures(opt, ctx, sc, graph, result.X)
    pieces = _reshaped_pieces(ctx, sc, graph, result.X)
    log.info("reshape: %d nodes, %d equations, factor %.1f ms", graph.counts["nodes"], system.A.shape[0],
             full.factor_ms)
    return ReshapeResult(
        **result_fields(cfg, ctx, inputs),
        meshes={n: trimesh.Trimesh(m.positions, m.position_index[m.F], process=False) for n, m in pieces.items()},
        textured=pieces, retexture={n: retex.get(i, []) for i, n in enumerate(sc.names)}, X=result.X,
        previews=PreviewData(sc.F, graph, result.X, Xb, handles, surfaces),
    )


def _reshaped_pieces(ctx, sc: Scene, graph, X) -> dict[str, TexturedMesh]:
    """Piece name -> its textured mesh at the reshaped positions; each checked against its input
    (:func:`_check_quality`)."""
    out = {}
    for name, m, off, r in zip(sc.names, sc.meshes, sc.offsets, sc.ranges, strict=True):
        P = m.positions.copy()
        P[m.position_index] = X[graph.node_of_vertex[r.start:r.stop]] - off
        out[name] = reshaped(m, P)
        _check_quality(ctx, name, m, P)
    return out
