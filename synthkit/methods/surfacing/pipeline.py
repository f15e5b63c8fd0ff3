"""``synthkit surface-by-numbers`` run: mode segment (load, strokes, segmentation), mode views (the
view renders only) and mode transfer (:mod:`.transfer.pipeline`).

Stages (``report.json`` ``timings``): ``load``, ``views``, ``strokes``, ``graph`` (graph, costs,
region term), ``hierarchy`` (LOD maps and the static coarse graphs), ``cut`` (all levels),
``single_level`` (with ``compare_single_level``), ``smoothing``, then, writing, ``export`` and
``previews``. The outputs are listed in :mod:`.outputs`.

Errors: a stroke index out of range, a stroke point off the surface, a vertex or face stroked for
two regions, a region without strokes, a painted PNG of the wrong size or with a colour that maps
to no region, and ``region_term.model: color`` on a mesh without colours are config errors (exit 2)
naming the key and value; a mesh without faces or an unreadable PNG is an input error (exit 3).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from synthkit.errors import ConfigError, KeyedError, user_error
from synthkit.io.inputs import Inputs
from synthkit.methods.surfacing import prepare
from synthkit.methods.surfacing.config import SurfacingConfig
from synthkit.methods.surfacing.options import region_colors
from synthkit.methods.surfacing.outputs import REGION_SUFFIXES, SegmentResult
from synthkit.methods.surfacing.segment import Segmentation, chain_edges, cut_edges
from synthkit.methods.surfacing.smoothing import polyline_length, smooth_chains
from synthkit.methods.surfacing.transfer import pipeline as transfer_pipeline
from synthkit.result import result_fields

__all__ = ["compute", "with_mode"]

log = logging.getLogger("synthkit")


def _metrics(cfg: SurfacingConfig, mesh, seg: Segmentation, cut: np.ndarray) -> dict:
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    area = mesh.area_faces
    regions = []
    for k, region in enumerate(cfg.regions):
        sel = seg.face_labels == k
        regions.append({"name": region.name, "faces": int(sel.sum()),
                        "vertices": int(len(np.unique(F[sel]))) if sel.any() else 0,
                        "area_share": float(area[sel].sum() / area.sum())})
    levels = [{k: v for k, v in st.items() if k != "free_faces"} for st in seg.levels]
    out = {
        "regions": regions, "graph": cfg.graph, "region_model": cfg.region_term.model, "solver": seg.solver,
        "graph_nodes": seg.graph.n, "graph_edges": int(len(seg.graph.edges)), "cut_cost": seg.cut_cost,
        "boundary_cost": seg.boundary_cost,
        "cut_length": float(np.linalg.norm(V[cut[:, 0]] - V[cut[:, 1]], axis=1).sum()),
        "cut_edges": int(len(cut)), "levels": levels, "unstroked_components": seg.unstroked_components,
    }
    if seg.single_level is not None:
        out["single_level_cut_cost"] = seg.single_level["cut_cost"]
        out["single_level_face_agreement"] = seg.single_level["face_agreement"]
        out["single_level_seconds"] = seg.single_level["seconds"]
    return out


def _region_format(cfg: SurfacingConfig, inputs: Inputs, mesh: trimesh.Trimesh) -> tuple[str, bool]:
    """The suffix region meshes are written with (the input's, else ``.ply``) and whether region OBJs
    go without a material (:func:`_invented_material`)."""
    suffix = "" if inputs.is_memory(cfg.input) else cfg.input.suffix.lower()
    suffix = suffix if suffix in REGION_SUFFIXES else ".ply"
    return suffix, suffix == ".obj" and _invented_material(cfg.input, mesh)


def _invented_material(path, mesh: trimesh.Trimesh) -> bool:
    """Whether ``mesh`` (loaded from the OBJ ``path``) carries a material trimesh made up: its UVs
    come with a default material trimesh makes up when the OBJ names no material file (warned here, once) or one
    that is missing (the loader has warned)."""
    if getattr(mesh.visual, "kind", None) != "texture":
        return False
    names = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.startswith("mtllib"):
                names += line.split()[1:]
    if not names:
        log.warning("%s: UVs without a material file (no mtllib): region meshes keep the UVs, with no material",
                    path)
    return not any((Path(path).parent / name).is_file() for name in names)


def _stroked_faces(F, seg: Segmentation) -> np.ndarray:
    if seg.graph.kind == "face":
        return seg.seeds >= 0
    return (seg.seeds[F] >= 0).any(axis=1)


def _views(cfg: SurfacingConfig, ctx, cache: prepare.ViewCache) -> dict:
    """The renders and cameras of ``views.names`` (``views.render`` or mode views)."""
    if not (cfg.mode == "views" or cfg.views.render):
        return {"view_images": {}, "cameras": {}}
    with ctx.stage("views"):
        made = {name: cache[name] for name in cfg.views.names}
    ctx.metrics["views"] = list(cfg.views.names)
    return {"view_images": {name: v[2] for name, v in made.items()},
            "cameras": {name: v[0] for name, v in made.items()}}


def _strokes(cfg: SurfacingConfig, ctx, mesh, cache: prepare.ViewCache, inputs: Inputs):
    """Stroke owners; with painted images, their pixel counts and notes in the metrics and the log."""
    with ctx.stage("strokes"):
        notes: dict = {}
        owners = prepare.stroke_owners(cfg, mesh, cache, inputs, notes, strict=ctx.strict)
    if cfg.images:
        ctx.metrics.update(notes)
        counts = notes["painted_pixels"]
        ignored = sum(max(c["ignored"] - sum(u["pixels"] for u in c["unnamed"]), 0) for c in counts)
        if ignored:
            other = "other " if any(c["unnamed"] for c in counts) else ""
            log.warning("%d %spainted pixels match no stroke colour and were ignored (report.json "
                        "metrics.painted_pixels)", ignored, other)
        for note in notes["stroke_notes"]:
            log.warning("%s", note)
    return owners


def _segment(cfg: SurfacingConfig, inputs: Inputs, ctx) -> SegmentResult:
    """Mode segment (and mode views) over ``inputs``: nothing written."""
    with ctx.stage("load"):
        mesh = inputs.mesh(cfg.input)
    cache = prepare.ViewCache(mesh, cfg.views.size)
    views = _views(cfg, ctx, cache)
    if cfg.mode == "views":
        return SegmentResult(**result_fields(cfg, ctx, inputs), **views)
    vertex_owner, face_owner = _strokes(cfg, ctx, mesh, cache, inputs)
    seg = prepare.segmentation(cfg, ctx, mesh, vertex_owner, face_owner)
    if seg.single_level is not None:
        ctx.timings["single_level"] = seg.single_level["seconds"]
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    cut = cut_edges(V, F, seg.face_labels)
    ctx.metrics.update(_metrics(cfg, mesh, seg, cut))
    curves = None
    if cfg.smooth_cut:
        with ctx.stage("smoothing"):
            curves = smooth_chains(mesh.vertices, mesh.faces, chain_edges(cut), cfg.smooth_cut)
        ctx.metrics["cut_length_smoothed"] = float(sum(polyline_length(c) for c in curves))
    suffix, bare = _region_format(cfg, inputs, mesh)
    return SegmentResult(
        **result_fields(cfg, ctx, inputs), **views, mesh=mesh, face_labels=seg.face_labels.astype(np.int32),
        vertex_labels=seg.vertex_labels.astype(np.int32), region_names=[r.name for r in cfg.regions],
        region_colors=region_colors(cfg), cut_edges=cut, cut_chains=chain_edges(cut), cut_curves=curves,
        stroked_faces=_stroked_faces(F, seg), levels=seg.levels, region_suffix=suffix, bare_obj=bare,
    )


def compute(cfg: SurfacingConfig, inputs: Inputs, ctx):
    """Run ``cfg`` over ``inputs`` without writing: a
    :class:`~synthkit.methods.surfacing.outputs.SegmentResult` (mode segment or views) or a
    :class:`~synthkit.methods.surfacing.transfer.outputs.TransferResult` (mode transfer)."""
    if cfg.mode == "transfer":
        return transfer_pipeline.compute(cfg, inputs, ctx)
    try:
        return _segment(cfg, inputs, ctx)
    except KeyedError as exc:
        raise user_error(exc) from None


def with_mode(keys: dict[str, Any], mode: str, call: str) -> dict[str, Any]:
    """The keyword arguments ``keys`` of ``synthkit.segment`` or ``synthkit.transfer`` (``call``) with
    ``mode`` set; a contradicting ``mode=`` is a ConfigError."""
    given = keys.get("mode", mode)
    if given != mode:
        other = "synthkit.transfer()" if given == "transfer" else "synthkit.segment()"
        hint = f"; use {other}" if given in ("segment", "transfer") else ""
        raise ConfigError(f"{call}: mode: {given!r} contradicts the function (mode {mode}){hint}")
    return {**keys, "mode": mode}
