"""``mode: transfer`` of ``synthkit surface-by-numbers``: read the target and its regions, each
pair's source and signal, synthesize (:mod:`.synth`) and extract; :mod:`.outputs` writes.

Stages (``report.json`` ``timings``): ``load``, ``strokes`` and the segmentation's own stages (when
a region is given by strokes), ``sources``, ``precompute`` (grading, edge tables), ``precompute_fans``,
``position``, ``match``, ``parameterize``, ``trim`` (the step kinds, summed over pairs), ``baseline``,
``extract``, then, writing, ``export`` and ``previews``.

Errors (one line, nothing written): an empty target or source region, a region name or label
that does not exist, a source without the requested signal, a source region smaller than one
patch, an image region outside the image and a mask of the wrong size are config errors (exit 2);
a non-positive scale and a distortion bound below 1 fail validation (exit 2); unreadable files
are input errors (exit 3).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import trimesh

from synthkit.core.mesh import child_uvs, consistent_winding, weld
from synthkit.core.quality import mesh_quality
from synthkit.errors import ConfigError, KeyedError, user_error
from synthkit.io.inputs import Inputs
from synthkit.io.signals import image_grid, read_face_labels, texture_of, vertex_attribute, vertex_colors
from synthkit.methods.surfacing import prepare
from synthkit.methods.surfacing.options import options_of
from synthkit.methods.surfacing.transfer import refine
from synthkit.methods.surfacing.transfer.extract import displacement_field
from synthkit.methods.surfacing.transfer.extraction import (
    Extracted,
    Layout,
    Prepared,
    WorkMesh,
    extract,
    face_errors,
    layout_of,
)
from synthkit.methods.surfacing.transfer.figures import (
    STEP_KINDS,
    pair_metrics,
    patch_domains,
    seam_field,
    seam_figures,
)
from synthkit.methods.surfacing.transfer.outputs import TransferResult
from synthkit.methods.surfacing.transfer.surface import Signal, Surface, make_surface, mean_edge, prefiltered
from synthkit.methods.surfacing.transfer.synth import Result as Synthesized
from synthkit.methods.surfacing.transfer.synth import Synthesis
from synthkit.result import result_fields

__all__ = ["compute", "BYTES_PER_FACE"]

log = logging.getLogger("synthkit")

BYTES_PER_FACE = 18000
"""Peak bytes per target face of a whole transfer (docs/findings/surface-by-numbers.md)."""
MIN_PATCH_EDGES = 3.0
"""The automatic patch radius spans at least this many mean target edge lengths."""


def _segmentation(cfg, ctx, mesh, inputs: Inputs) -> np.ndarray:
    """Face labels of ``mesh`` segmented by ``cfg.regions`` (mode segment's stages)."""
    with ctx.stage("strokes"):
        owners = prepare.stroke_owners(cfg, mesh, prepare.ViewCache(mesh, cfg.views.size), inputs,
                                       strict=ctx.strict)
    return prepare.segmentation(cfg, ctx, mesh, *owners).face_labels


def _label_file(inputs: Inputs, path, n_faces: int) -> np.ndarray:
    """``(#F,)`` face labels of a ``.seg`` or ``labels.ply`` file, or given in memory for ``path``."""
    return inputs.face_labels(path, n_faces) if inputs.is_memory(path) else read_face_labels(path, n_faces)


def _faces(labels, names, region, label_file, label, n_faces: int, key: str, inputs: Inputs) -> np.ndarray:
    """Faces of a region given by name (in ``labels`` of the stroked ``names``) or by label file."""
    if region is not None:
        faces = np.flatnonzero(labels == names.index(region))
        what = f"region {region!r}"
    elif label_file is not None:
        file_labels = _label_file(inputs, label_file, n_faces)
        faces = np.flatnonzero(file_labels == label)
        what = f"label {label} of {label_file}"
    else:
        return np.arange(n_faces)
    if not len(faces):
        raise ConfigError(f"{key}: {what} is empty (no face has it)")
    return faces


def _mesh_signal(kind: str, attribute, mesh: trimesh.Trimesh, path, key: str, smoothing: float | None):
    """``(Signal, channels compared, weld tolerance)`` of a mesh source."""
    F = np.asarray(mesh.faces)
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    if kind == "color":
        c = vertex_colors(mesh)
        if c is None:
            raise ConfigError(f"{key}.signal: color: {path} has no vertex colours")
        return Signal("color", values=c[F]), None, 0.0
    if kind == "texture":
        tex = texture_of(mesh)
        if tex is None:
            raise ConfigError(f"{key}.signal: texture: {path} has no UVs or no texture image")
        return Signal("texture", uv=tex[0][F], texture=tex[1]), None, 1e-7 * diag
    if kind == "attribute":
        a = vertex_attribute(mesh, attribute)
        if a is None:
            raise ConfigError(f"{key}.attribute: {path} has no vertex property {attribute!r}")
        return Signal("attribute", values=a[F]), None, 0.0
    V = np.asarray(mesh.vertices, np.float64)
    length = smoothing if smoothing else 0.05 * diag
    d = displacement_field(V, F, length=length)
    n = np.asarray(mesh.vertex_normals, np.float64)
    return Signal("displacement", values=np.c_[d, (d * n).sum(axis=1)][F]), [3], 0.0


def _image_source(src, key: str, inputs: Inputs) -> Surface:
    """The image region as a flat textured grid (Fig. 6)."""
    img = inputs.image(src.image)
    H, W = img.shape[:2]
    if src.mask is not None:
        mask = inputs.image(src.mask, mode="gray")
        if mask.shape[:2] != (H, W):
            raise ConfigError(f"{key}.mask: {src.mask} is {mask.shape[1]}x{mask.shape[0]} pixels, the image "
                              f"{W}x{H}")
        mask = mask > 0
    else:
        x0, y0, x1, y1 = src.rect if src.rect is not None else (0, 0, W, H)
        if not (0 <= x0 < x1 <= W and 0 <= y0 < y1 <= H):
            raise ConfigError(f"{key}.rect: [{x0}, {y0}, {x1}, {y1}] lies outside the image {src.image} ({W}x{H})")
        mask = np.zeros((H, W), bool)
        mask[y0:y1, x0:x1] = True
    try:
        V, F, uv = image_grid(mask, width=src.width, resolution=src.resolution)
    except ValueError as exc:
        raise ConfigError(f"{key}: image region of {src.image}: {exc} (region is empty)") from None
    return make_surface(V, F, np.arange(len(F)), Signal("texture", uv=uv[F], texture=img[..., :3]))


def _source(cfg, ctx, k: int, target_mesh, target_labels, margin: float,
            inputs: Inputs) -> tuple[Surface, list[int] | None]:
    pair = cfg.transfer.pairs[k]
    src, key = pair.source, f"transfer.pairs[{k}]"
    if src.image is not None:
        if pair.signal not in ("color", "texture"):
            raise ConfigError(f"{key}.signal: {pair.signal}: an image source carries colour only (color or texture)")
        return _image_source(src, f"{key}.source", inputs), None
    mesh, path, names, labels = target_mesh, cfg.input, [r.name for r in cfg.regions], target_labels
    if src.mesh is not None:
        mesh, path, names = inputs.mesh(src.mesh), src.mesh, [r.name for r in src.regions]
        if src.region is not None and src.region not in names:
            raise ConfigError(f"{key}.source.region: {src.region!r} is not a source region "
                              f"(regions: {', '.join(names) or 'none'})")
        if src.region is not None:
            sub = cfg.model_copy(update={"regions": src.regions, "images": [], "input": src.mesh, "mode": "segment"})
            labels = _segmentation(sub, ctx, mesh, inputs)
    faces = _faces(labels, names, src.region, src.labels, src.label, len(mesh.faces), f"{key}.source", inputs)
    smoothing = cfg.transfer.extraction.smoothing
    signal, channels, weld = _mesh_signal(pair.signal, pair.attribute, mesh, path, key, smoothing)
    try:
        surface = make_surface(mesh.vertices, mesh.faces, faces, signal, weld_tol=weld, margin=margin / pair.scale)
    except ValueError as exc:
        raise ConfigError(f"{key}.source: {exc}") from None
    return surface, channels


def _radius(cfg, k: int, target: Surface, source: Surface) -> float:
    """The patch radius: ``synthesis.patch_radius``, or ``0.3 sqrt(min(source, target area))``
    clipped to ``[3 target edges, 0.9 sqrt(source area / pi)]``. ConfigError when the source region
    is smaller than one patch: than the given radius's disc, or (automatic radius) than a disc of
    one mean target edge."""
    pair, syn = cfg.transfer.pairs[k], cfg.transfer.synthesis
    src_area = source.area * pair.scale**2
    edge = mean_edge(target)
    fits = 0.9 * np.sqrt(src_area / np.pi)
    radius = syn.patch_radius or min(max(0.3 * np.sqrt(min(src_area, target.area)), MIN_PATCH_EDGES * edge), fits)
    if src_area < np.pi * radius**2 or (not syn.patch_radius and radius < edge):
        radius = max(radius, edge)
        raise ConfigError(f"transfer.pairs[{k}].source: the source region ({src_area:.4g} square target units at "
                          f"scale {pair.scale:g}) is smaller than one patch (pi r^2 = {np.pi * radius**2:.4g}, "
                          f"synthesis.patch_radius {radius:.4g})")
    return float(radius)


def _margin(cfg, k: int, mesh) -> float:
    """Support margin of the log maps: twice the given patch radius, or a fifth of the mesh's
    bounding-box diagonal when the radius is automatic."""
    r = cfg.transfer.synthesis.patch_radius
    return 2.0 * r if r else 0.2 * float(np.linalg.norm(np.ptp(np.asarray(mesh.vertices), axis=0)))


def _work_mesh(cfg, mesh: trimesh.Trimesh) -> WorkMesh:
    colors = prepare.mesh_colors(mesh)
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    tex = texture_of(mesh)
    original, texture = (tex[0][F], tex[1]) if tex is not None else (None, None)
    if mesh.visual.kind == "texture":
        _, _, o2n = weld(V, F, 1e-7 * float(np.linalg.norm(np.ptp(V, axis=0))), return_index=True)
        _, first = np.unique(o2n, return_index=True)
        V, F = V[first], o2n[F]
        colors = None if colors is None else colors[first]
        F, flipped = consistent_winding(V, F)
        if original is not None:
            original[flipped] = original[flipped][:, ::-1]
    parent = np.arange(len(F))
    for _ in range(cfg.transfer.extraction.subdivide):
        if colors is not None:  # trimesh returns attributes or the face index, not both
            colors = trimesh.remesh.subdivide(V, F, vertex_attributes={"c": colors})[2]["c"]
        V2, F2, children = trimesh.remesh.subdivide(V, F, return_index=True)
        step = np.empty(len(F2), np.int64)
        for old, new in children.items():
            step[new] = old
        if original is not None:
            original = child_uvs(V[F[step]], original[step], V2[F2])
        V, F, parent = V2, F2, parent[step]
    return WorkMesh(trimesh.Trimesh(V, F, process=False), parent, colors, original, texture)


def _prepare(cfg, ctx, mesh, work: WorkMesh, inputs: Inputs) -> list[Prepared]:
    names = [r.name for r in cfg.regions]
    strokes = any(p.target.region is not None or (p.source.mesh is None and p.source.region is not None)
                  for p in cfg.transfer.pairs)
    labels = _segmentation(cfg, ctx, mesh, inputs) if strokes else None
    out = []
    with ctx.stage("sources"):
        for k, pair in enumerate(cfg.transfer.pairs):
            key = f"transfer.pairs[{k}]"
            faces = _faces(labels, names, pair.target.region, pair.target.labels, pair.target.label,
                           len(mesh.faces), f"{key}.target", inputs)
            faces = np.flatnonzero(np.isin(work.parent, faces))
            ctx.budget.require(f"{key}.target", len(faces), len(faces), "target faces", bytes_each=BYTES_PER_FACE)
            margin = _margin(cfg, k, mesh)
            try:
                target = make_surface(work.mesh.vertices, work.mesh.faces, faces, None, largest=False, margin=margin)
            except ValueError as exc:
                raise ConfigError(f"{key}.target: {exc}") from None
            source, channels = _source(cfg, ctx, k, mesh, labels, margin, inputs)
            sharp = source.signal.texture
            if source.signal.texture is not None and cfg.transfer.extraction.sampling == "linear":
                source.signal = prefiltered(source, mean_edge(target) / pair.scale)
            if cfg.transfer.synthesis.orientation == "up":
                target.orient(cfg.transfer.synthesis.up)
                source.orient(pair.source.up)
            out.append(Prepared(target, source, channels, _radius(cfg, k, target, source), key, sharp,
                                pair.scale))
    return out


def _synthesize(cfg, ctx, preps: list[Prepared]) -> list[tuple[Synthesized, Synthesized | None]]:
    out, options = [], options_of(cfg)
    for k, prep in enumerate(preps):
        opt = options.synthesis(k, prep.radius)
        try:
            res = Synthesis(prep.target, prep.source, opt, rng=ctx.rng, channels=prep.channels).run()
        except ValueError as exc:
            raise ConfigError(f"{prep.key}: {exc}") from None
        for name in STEP_KINDS:
            ctx.timings[name] = ctx.timings.get(name, 0.0) + res.timings[name]
        base = None
        if cfg.transfer.baseline:
            with ctx.stage("baseline"):
                bopt = replace(opt, matching="random", trimming="none", fixed_patches=True,
                               max_patches=max(len(res.patches), 1))
                base = Synthesis(prep.target, prep.source, bopt, rng=np.random.default_rng(ctx.seed),
                                 channels=prep.channels).run()
        out.append((res, base))
    return out


def _refine(cfg, ctx, work: WorkMesh, layout: Layout, preps, results) -> tuple[WorkMesh, Layout]:
    """Adaptive refinement (:mod:`.refine`) until no edge is marked or ``refine_levels`` steps."""
    ex = cfg.transfer.extraction
    for _ in range(ex.refine_levels if ex.refine_tolerance else 0):
        V, F = np.asarray(work.mesh.vertices), np.asarray(work.mesh.faces)
        edge, edges = refine.edge_index(F)
        marked = refine.mark_edges(V, F, edge, len(edges), *face_errors(layout, preps, results), ex.refine_tolerance)
        if not marked.any():
            break
        F2, parent, W, new = refine.split_faces(F, edge, marked, len(V))
        ctx.budget.require("extraction.refine_tolerance", ex.refine_tolerance, len(F2), "faces after refinement",
                           bytes_each=BYTES_PER_FACE)
        corners = lambda a, W=W, parent=parent: np.einsum("fjk,fkc->fjc", W, a[parent])  # noqa: E731
        ends = edges[new]
        mids = lambda a, ends=ends: None if a is None else np.concatenate([a, a[ends].mean(axis=1)])  # noqa: E731
        work = WorkMesh(trimesh.Trimesh(mids(V), F2, process=False), work.parent[parent], mids(work.colors),
                        None if work.original is None else corners(work.original), work.texture)
        layout = Layout(layout.pair[parent], layout.patch[parent], corners(layout.uv), layout.origin[parent])
    return work, layout


def _metrics(cfg, ctx, preps, results) -> None:
    ex = cfg.transfer.extraction
    pairs = [{**pair_metrics(p, r, b), **seam_figures(p, r, b, ex)}
             for p, (r, b) in zip(preps, results, strict=True)]
    n = sum(m["target_faces"] for m in pairs)
    m = {
        "pairs": pairs, "patches": sum(p["patches"] for p in pairs),
        "coverage": sum(p["coverage"] * p["target_faces"] for p in pairs) / max(n, 1),
        "uncovered_faces": sorted(f for p in pairs for f in p["uncovered_faces"]),
        "seam_cost": {"per_iteration": pairs[0]["seam_cost"]["per_iteration"] if len(pairs) == 1 else
                      [p["seam_cost"]["per_iteration"] for p in pairs],
                      "final": sum(p["seam_cost"]["final"] for p in pairs)},
        "distortion_mean": sum(p["distortion_mean"] * p["target_faces"] for p in pairs) / max(n, 1),
        "distortion_max": max(p["distortion_max"] for p in pairs),
        "distortion_bound": cfg.transfer.synthesis.bound,
        "seconds": {k: sum(p["seconds"][k] for p in pairs) for k in STEP_KINDS},
    }
    if cfg.transfer.baseline:
        m["baseline_seam_cost"] = sum(p["baseline_seam_cost"] for p in pairs)
        m["seam_ratio"] = m["seam_cost"]["final"] / m["baseline_seam_cost"] if m["baseline_seam_cost"] else None
    ctx.metrics.update(m)
    if m["uncovered_faces"]:
        ctx.status = "partial"
        log.warning("%d target faces stayed uncovered (report.json metrics.uncovered_faces)", len(m["uncovered_faces"]))


def _check_quality(cfg, ctx, mesh: trimesh.Trimesh, work: WorkMesh, ext: Extracted) -> None:
    """``ctx.check_quality`` of the transferred mesh against the target as read. Its faces are the
    target's, refined: on a clean mesh each subdivision or refinement step at most doubles the open
    and non-manifold edges and quadruples the faces, so the limits scale the input's figures by that
    much; no new degenerate or duplicate face beyond the input's, scaled alike. Where the refined
    target itself has more (subdividing coincident or overlapping faces: house1's 132 non-manifold
    edges become 582 and 2436, tudorhouse's 57 become 162), its own figures are the limits, so only
    what the transfer adds to the refined target is flagged."""
    ex = cfg.transfer.extraction
    steps = ex.subdivide + (ex.refine_levels if ex.refine_tolerance is not None else 0)
    before = mesh_quality(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    after = mesh_quality(ext.positions, np.asarray(work.mesh.faces))
    refined = mesh_quality(np.asarray(work.mesh.vertices), np.asarray(work.mesh.faces)) if steps else before
    edges, faces = 2**steps, 4**steps
    limits = {key: max(before[key] * edges, refined[key]) for key in ("open_edges", "nonmanifold_edges")}
    limits |= {key: max(before[key] * faces, refined[key]) for key in ("degenerate_faces", "duplicate_faces")}
    ctx.check_quality("transferred", before, after, limits)


def _transfer(cfg, inputs: Inputs, ctx) -> TransferResult:
    with ctx.stage("load"):
        mesh = inputs.mesh(cfg.input)
        work = _work_mesh(cfg, mesh)
    ctx.budget.require("extraction.subdivide", cfg.transfer.extraction.subdivide, len(work.mesh.faces),
                       "faces after refinement", bytes_each=BYTES_PER_FACE)
    preps = _prepare(cfg, ctx, mesh, work, inputs)
    results = _synthesize(cfg, ctx, preps)
    with ctx.stage("extract"):
        layout = layout_of(work, preps, results)
        work, layout = _refine(cfg, ctx, work, layout, preps, results)
        ext = extract(cfg.transfer.pairs, cfg.transfer.extraction, work, layout, preps, results)
    _metrics(cfg, ctx, preps, results)
    _check_quality(cfg, ctx, mesh, work, ext)
    textures = [work.texture] + [ext.atlases.get(k, prep.texture) if pair.signal == "texture" else None
                                 for k, (prep, pair) in enumerate(zip(preps, cfg.transfer.pairs, strict=True))]
    return TransferResult(
        **result_fields(cfg, ctx, inputs), positions=ext.positions, faces=np.asarray(work.mesh.faces),
        colors=ext.colors, attributes=ext.attributes, patch_ids=ext.patch_ids, corner_uv=ext.uv,
        face_material=ext.material, textures=textures, baked=sorted(ext.atlases),
        input_suffix="" if inputs.is_memory(cfg.input) else cfg.input.suffix.lower(),
        before_positions=np.asarray(work.mesh.vertices), before_colors=work.colors,
        seam_field=seam_field(preps, results, int(layout.origin.max()) + 1)[layout.origin],
        patch_domains=patch_domains(results),
    )


def compute(cfg, inputs: Inputs, ctx) -> TransferResult:
    """Run ``cfg`` (mode transfer) over ``inputs`` without writing."""
    try:
        return _transfer(cfg, inputs, ctx)
    except KeyedError as exc:
        raise user_error(exc) from None
