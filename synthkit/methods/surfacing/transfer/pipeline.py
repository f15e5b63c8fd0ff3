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
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np
import trimesh

from synthkit.core.mesh import barycentric, face_areas, face_normals, weld
from synthkit.core.quality import mesh_quality
from synthkit.errors import ConfigError, KeyedError, user_error
from synthkit.io.inputs import Inputs
from synthkit.io.signals import image_grid, read_face_labels, texture_of, vertex_attribute, vertex_colors
from synthkit.methods.surfacing import prepare
from synthkit.methods.surfacing.options import options_of
from synthkit.methods.surfacing.transfer import refine
from synthkit.methods.surfacing.transfer.bake import (
    bake,
    feathered,
    texture_seam_visibility,
)
from synthkit.methods.surfacing.transfer.extract import (
    corner_sources,
    corner_values,
    displacement_field,
    seam_visibility,
    transfer_displacement,
    vertex_values,
)
from synthkit.methods.surfacing.transfer.outputs import TransferResult
from synthkit.methods.surfacing.transfer.surface import Signal, Surface, make_surface
from synthkit.methods.surfacing.transfer.synth import Result as Synthesized
from synthkit.methods.surfacing.transfer.synth import Synthesis
from synthkit.methods.surfacing.transfer.trim import seam_costs
from synthkit.result import result_fields

__all__ = ["compute", "texel_size", "Prepared", "WorkMesh", "Extracted", "Layout", "prefiltered", "STEP_KINDS",
           "BYTES_PER_FACE"]

log = logging.getLogger("synthkit")

BYTES_PER_FACE = 18000
"""Peak bytes per target face of a whole transfer (docs/findings/surface-by-numbers.md)."""
MIN_PATCH_EDGES = 3.0
"""The automatic patch radius spans at least this many mean target edge lengths."""


@dataclass
class Prepared:
    """One pair ready to synthesize: surfaces, compared channels, patch radius, config key, the
    source's unfiltered texture and the scale (target units per source unit)."""

    target: Surface
    source: Surface
    channels: list[int] | None
    radius: float
    key: str
    texture: np.ndarray | None = None
    scale: float = 1.0


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


def _mean_edge(surface: Surface) -> float:
    return float(np.linalg.norm(surface.V[surface.edges[:, 0]] - surface.V[surface.edges[:, 1]], axis=1).mean())


def texel_size(source: Surface) -> float:
    """The size of a texel of the source's texture on its surface (source units):
    ``sqrt(surface area / texture area covered, in texels)``."""
    sig = source.signal
    H, W = sig.texture.shape[:2]
    uv = sig.uv * [W, H]
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    uv_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    return float(np.sqrt(source.area / max(uv_area, 1e-300)))


def prefiltered(source: Surface, spacing: float) -> Signal:
    """The source's texture blurred to the target's sampling: a Gaussian of ``spacing / 2``
    (source units) in texels (:func:`texel_size`), so vertex samples read the texture's local mean,
    not aliased texels."""
    sig = source.signal
    sigma = 0.5 * spacing / texel_size(source)
    if sigma < 0.5:
        return sig
    import cv2

    blurred = cv2.GaussianBlur(sig.texture.astype(np.float32), (0, 0), sigmaX=float(sigma))
    return Signal(sig.kind, uv=sig.uv, texture=blurred.astype(np.float64))


def _radius(cfg, k: int, target: Surface, source: Surface) -> float:
    """The patch radius: ``synthesis.patch_radius``, or ``0.3 sqrt(min(source, target area))``
    clipped to ``[3 target edges, 0.9 sqrt(source area / pi)]``. ConfigError when the source region
    is smaller than one patch: than the given radius's disc, or (automatic radius) than a disc of
    one mean target edge."""
    pair, syn = cfg.transfer.pairs[k], cfg.transfer.synthesis
    src_area = source.area * pair.scale**2
    edge = _mean_edge(target)
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


@dataclass
class WorkMesh:
    """The target as the transfer works on it: texture seams welded (face order kept) and faces
    wound consistently, refined by
    ``extraction.subdivide`` midpoint steps. ``parent (#F,)`` is each face's face in the input,
    ``colors (#V, 3)`` the input's colours (vertex colours or the texture at the vertices) or None."""

    mesh: trimesh.Trimesh
    parent: np.ndarray
    colors: np.ndarray | None
    original: np.ndarray | None = None
    texture: np.ndarray | None = None


def _consistent_winding(V, F) -> tuple[np.ndarray, np.ndarray]:
    """``F`` with faces flipped so each connected piece winds one way (trimesh's ``fix_winding``;
    log maps need it) and the mask of flipped faces."""
    m = trimesh.Trimesh(V, F, process=False)
    trimesh.repair.fix_winding(m)
    G = np.asarray(m.faces, np.int64)
    return G, (G != F).any(axis=1)


def _child_uvs(P: np.ndarray, uv: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Corner UVs ``(n, 3, 2)`` of child triangles ``C (n, 3, 3)`` lying in their parents ``P (n, 3, 3)``
    whose corner UVs are ``uv (n, 3, 2)``: each corner's barycentric coordinates in its parent (exact
    for midpoint subdivision), so a subdivided target keeps its texture (seams included, UVs are per
    corner)."""
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    den = np.where(np.abs(d11 * d22 - d12 * d12) > 1e-300, d11 * d22 - d12 * d12, 1e-300)
    r = C - P[:, :1]
    r1, r2 = np.einsum("nkd,nd->nk", r, e1), np.einsum("nkd,nd->nk", r, e2)
    b1 = (d22[:, None] * r1 - d12[:, None] * r2) / den[:, None]
    b2 = (d11[:, None] * r2 - d12[:, None] * r1) / den[:, None]
    bary = np.stack([1 - b1 - b2, b1, b2], axis=2)  # (n, 3 child corners, 3 parent corners)
    return np.einsum("nkj,njd->nkd", bary, uv)


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
        F, flipped = _consistent_winding(V, F)
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
            original = _child_uvs(V[F[step]], original[step], V2[F2])
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
                source.signal = prefiltered(source, _mean_edge(target) / pair.scale)
            if cfg.transfer.synthesis.orientation == "up":
                target.orient(cfg.transfer.synthesis.up)
                source.orient(pair.source.up)
            out.append(Prepared(target, source, channels, _radius(cfg, k, target, source), key, sharp,
                                pair.scale))
    return out


STEP_KINDS = ("precompute", "precompute_fans", "position", "match", "parameterize", "trim")


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


def _border_vertices(F_full: np.ndarray, region_faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """``(#V,) bool``: vertices of the region that faces outside it use too."""
    inside = np.zeros(len(F_full), bool)
    inside[region_faces] = True
    used_in, used_out = np.zeros(n_vertices, bool), np.zeros(n_vertices, bool)
    used_in[F_full[inside].ravel()] = True
    used_out[F_full[~inside].ravel()] = True
    return used_in & used_out


@dataclass
class Extracted:
    """The target mesh's new ``positions (#V, 3)``, ``colors (#V, 3)`` in [0, 1], ``attributes`` and
    the patch id per face ``patch_ids (#F,)`` (-1 outside the target regions); for texture pairs the
    corner ``uv (#F, 3, 2)``, the ``material (#F,)`` and, when blended, the baked atlas image of
    pair k in ``atlases[k]``."""

    positions: np.ndarray
    colors: np.ndarray
    attributes: dict
    patch_ids: np.ndarray
    uv: np.ndarray | None = None
    material: np.ndarray | None = None
    atlases: dict = field(default_factory=dict)


@dataclass
class Layout:
    """Per face of the work mesh: its ``pair (#F,)`` (-1 outside every target region), ``patch
    (#F,)`` (-1 uncovered), corner domain coordinates ``uv (#F, 3, 2)`` and the face of the
    synthesis mesh it was refined from, ``origin (#F,)``."""

    pair: np.ndarray
    patch: np.ndarray
    uv: np.ndarray
    origin: np.ndarray

    def result(self, k: int, res: Synthesized) -> SimpleNamespace:
        """Pair ``k``'s patches over the whole work mesh, in the form the extract stages read."""
        return SimpleNamespace(patch_of=np.where(self.pair == k, self.patch, -1), corner_uv=self.uv,
                               patches=res.patches)


def _layout(work: WorkMesh, preps, results) -> Layout:
    nF = len(work.mesh.faces)
    out = Layout(np.full(nF, -1, np.int64), np.full(nF, -1, np.int64), np.zeros((nF, 3, 2)), np.arange(nF))
    for k, (prep, (res, _)) in enumerate(zip(preps, results, strict=True)):
        f = prep.target.face_ids
        out.pair[f], out.patch[f], out.uv[f] = k, res.patch_of, res.corner_uv
    return out


def _face_errors(layout: Layout, preps, results) -> tuple[np.ndarray, np.ndarray]:
    """Signal error of the linear reconstruction at edge midpoints ``(#F, 3)`` and centres ``(#F,)``
    (NaN where not covered), in the channels the pair compares."""
    nF = len(layout.pair)
    mid, centre = np.full((nF, 3), np.nan), np.full(nF, np.nan)
    for k, (prep, (res, _)) in enumerate(zip(preps, results, strict=True)):
        for p in np.unique(layout.patch[(layout.pair == k) & (layout.patch >= 0)]):
            faces = np.flatnonzero((layout.pair == k) & (layout.patch == p))
            Q = layout.uv[faces]
            probes = np.concatenate([Q, 0.5 * (Q + np.roll(Q, -1, axis=1)), Q.mean(axis=1, keepdims=True)], axis=1)
            f, b, _ = res.patches[p].to_source(probes.reshape(-1, 2))
            v = prep.source.signal.sample(f, b).reshape(len(faces), 7, -1)
            v = v if prep.channels is None else v[..., prep.channels]
            linear = 0.5 * (v[:, :3] + np.roll(v[:, :3], -1, axis=1))
            mid[faces] = np.linalg.norm(v[:, 3:6] - linear, axis=2)
            centre[faces] = np.linalg.norm(v[:, 6] - v[:, :3].mean(axis=1), axis=1)
    return mid, centre


def _refine(cfg, ctx, work: WorkMesh, layout: Layout, preps, results) -> tuple[WorkMesh, Layout]:
    """Adaptive refinement (:mod:`.refine`) until no edge is marked or ``refine_levels`` steps."""
    ex = cfg.transfer.extraction
    for _ in range(ex.refine_levels if ex.refine_tolerance else 0):
        V, F = np.asarray(work.mesh.vertices), np.asarray(work.mesh.faces)
        edge, edges = refine.edge_index(F)
        marked = refine.mark_edges(V, F, edge, len(edges), *_face_errors(layout, preps, results), ex.refine_tolerance)
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


def _texture_corners(ext: Extracted, work: WorkMesh, k: int, prep: Prepared, res) -> None:
    """Corner UVs into pair ``k``'s source texture (material ``k + 1``) on its covered faces."""
    nF = len(work.mesh.faces)
    if ext.uv is None:
        ext.uv, ext.material = np.full((nF, 3, 2), np.nan), np.zeros(nF, np.int64)
        if work.original is not None:
            ext.uv[:] = work.original
    src, bary = corner_sources(res, nF)
    faces = np.flatnonzero((src >= 0).all(axis=1))
    ext.uv[faces] = prep.source.signal.uv_at(src[faces].ravel(), bary[faces].reshape(-1, 3)).reshape(-1, 3, 2)
    ext.material[faces] = k + 1


def _texture_blend(prep: Prepared, r: Synthesized, ex, *, blend: str | None = None):
    """The :class:`.bake.Blend` of the texture of ``r`` on ``prep.target``: the full-resolution source
    texture through the patches, feathered over ``ex.feather`` patch radii and corrected to the
    vertex values of ``blend`` (default ``ex.blend``; none: neither)."""
    blend = ex.blend if blend is None else blend
    nearest = ex.sampling == "nearest"
    t = prep.target
    sharp = Signal("texture", uv=prep.source.signal.uv, texture=prep.texture)
    read = lambda f, b: sharp.sample(f, b, nearest=nearest)  # noqa: E731
    if blend == "none":
        return feathered(t.V, t.F, r.patch_of, r.corner_uv, r.patches, 0.0, read)
    corner = corner_values(r, prep.source, len(t.F))
    vals = vertex_values(t.F, corner, t.areas, len(t.V), blend=blend, V=t.V)
    return feathered(t.V, t.F, r.patch_of, r.corner_uv, r.patches, ex.feather * prep.radius, read,
                     smooth=prep.source.signal.sample, blended=vals)


def _bake_texture(ext: Extracted, k: int, prep: Prepared, res: Synthesized, layout: Layout, ex) -> None:
    """Pair ``k``'s blended texture (:func:`_texture_blend`) baked into an atlas over the work mesh's
    faces (refined faces read through the synthesis face they came from)."""
    tex = _texture_blend(prep, res, ex)
    local = np.full(int(layout.origin.max()) + 1, -1, np.int64)
    local[prep.target.face_ids] = np.arange(len(prep.target.face_ids))
    mine = layout.result(k, res)

    def colour(faces, bary):
        s = local[layout.origin[faces]]
        uv = np.einsum("nk,nkc->nc", bary, layout.uv[faces])
        return tex.colour(s, barycentric(res.corner_uv[s], uv[:, None])[:, 0])

    atlas = bake(mine.corner_uv, mine.patch_of, colour, texel_size(prep.source) * prep.scale)
    faces = np.flatnonzero(mine.patch_of >= 0)
    ext.uv[faces] = atlas.uv[faces]
    ext.atlases[k] = atlas.image


def _extract(cfg, work: WorkMesh, layout: Layout, preps, results) -> Extracted:
    mesh = work.mesh
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    nV, original = len(V), work.colors
    ext = Extracted(V.copy(), np.full((nV, 3), 0.75) if original is None else original.copy(), {},
                    np.full(len(F), -1, np.int64))
    ex, areas, offset = cfg.transfer.extraction, face_areas(V, F), 0
    for k, (pair, prep, (res, _)) in enumerate(zip(cfg.transfer.pairs, preps, results, strict=True)):
        mine = layout.result(k, res)
        cov = mine.patch_of >= 0
        ext.patch_ids[cov] = mine.patch_of[cov] + offset
        offset += len(res.patches)
        if pair.signal == "texture":
            _texture_corners(ext, work, k, prep, mine)
        if pair.signal == "displacement":
            frame = SimpleNamespace(V=V, F=F, N=face_normals(V, F))
            corner = transfer_displacement(mine, frame, prep.source, prep.source.signal.values[..., :3],
                                           scale=pair.scale)
        else:
            corner = corner_values(mine, prep.source, len(F), nearest=ex.sampling == "nearest")
        vals = vertex_values(F, corner, areas, nV, blend=ex.blend, V=V)
        ids = np.flatnonzero(np.isfinite(vals[:, 0]))
        if pair.signal == "displacement":
            ext.positions[ids] += vals[ids]
        elif pair.signal == "attribute":
            ext.attributes.setdefault(pair.attribute, np.zeros((nV, vals.shape[1])))[ids] = vals[ids]
        else:
            new = np.clip(vals[ids], 0, 1)
            if original is not None and ex.blend != "none":
                border = _border_vertices(F, np.flatnonzero(layout.pair == k), nV)[ids]
                new[border] = 0.5 * (new[border] + original[ids[border]])
            ext.colors[ids] = new
            if pair.signal == "texture" and ex.blend != "none":
                _bake_texture(ext, k, prep, res, layout, ex)
    return ext


def _seam_figures(prep: Prepared, res: Synthesized, base: Synthesized | None, ex) -> dict:
    """``seam_visibility`` of the pair's vertex values (:func:`seam_visibility`, with ``ex.blend``) and,
    with a baseline, ``baseline_seam_visibility`` (the random/no-trim baseline, the same blend);
    colour, texture and attribute signals; texture pairs add the same of their texture
    (:func:`_texture_seam_figures`)."""
    if prep.source.signal.kind == "displacement":
        return {}
    t = prep.target
    out = {}
    for key, r in (("seam_visibility", res), ("baseline_seam_visibility", base)):
        if r is None:
            continue
        corner = corner_values(r, prep.source, len(t.F))
        vals = vertex_values(t.F, corner, t.areas, len(t.V), blend=ex.blend, V=t.V)
        out[key] = _finite(seam_visibility(t.V, t.F, r.patch_of, vals))
        if prep.source.signal.kind == "texture":
            out |= _texture_seam_figures(key, prep, r, ex)
    return out


def _finite(x: float) -> float | None:
    return None if not np.isfinite(x) else float(x)


def _texture_seam_figures(key: str, prep: Prepared, r: Synthesized, ex) -> dict:
    """``<key>_texture`` (and ``..._unblended``): :func:`.bake.texture_seam_visibility` of the texture
    the output shows (:func:`_texture_blend` with ``blend``) and of the source texture read through
    each face's own patch alone, at a step of two source texels."""
    t, step = prep.target, 2.0 * texel_size(prep.source) * prep.scale
    texture = key.replace("seam_visibility", "texture_seam_visibility")
    figure = {}
    for name, how in ((texture, ex.blend), (f"{texture}_unblended", "none")):
        if name == texture or ex.blend != "none":
            tex = _texture_blend(prep, r, ex, blend=how)
            figure[name] = _finite(texture_seam_visibility(t.V, t.F, r.patch_of, tex.colour, step))
    return figure


def _pair_metrics(prep: Prepared, res: Synthesized, base: Synthesized | None) -> dict:
    cov = res.patch_of >= 0
    used = np.unique(res.patch_of[cov])
    src_max = max((float(res.patches[p].src_distortion.max()) for p in used), default=0.0)
    final = float(res.seam_cost[-1]) if res.seam_cost else 0.0
    out = {
        "target_faces": int(len(prep.target.F)), "source_faces": int(len(prep.source.F)),
        "patch_radius": prep.radius, "patches": int(len(res.patches)), "patches_visible": int(len(used)),
        "iterations": res.iterations, "coverage": float(cov.mean()),
        "uncovered_faces": prep.target.face_ids[~cov].tolist(),
        "seam_cost": {"per_iteration": [float(c) for c in res.seam_cost], "final": final},
        "distortion_mean": float(res.distortion[cov].mean()) if cov.any() else 0.0,
        "distortion_max": max(float(res.distortion[cov].max()) if cov.any() else 0.0, src_max),
        "seconds": {k: float(res.timings[k]) for k in STEP_KINDS},
    }
    if base is not None:
        out["baseline_seam_cost"] = float(base.seam_cost[-1]) if base.seam_cost else 0.0
        out["baseline_patches"] = int(len(base.patches))
        out["baseline_coverage"] = float((base.patch_of >= 0).mean())
    return out


def _metrics(cfg, ctx, preps, results) -> None:
    ex = cfg.transfer.extraction
    pairs = [{**_pair_metrics(p, r, b), **_seam_figures(p, r, b, ex)}
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


def _seam_field(preps, results, n_faces: int) -> np.ndarray:
    """Seam cost per face of the full mesh (half of each incident seam), NaN outside the regions."""
    out = np.full(n_faces, np.nan)
    for prep, (res, _) in zip(preps, results, strict=True):
        t = prep.target
        a, b = res.patch_of[t.pairs[:, 0]], res.patch_of[t.pairs[:, 1]]
        on = (a >= 0) & (b >= 0) & (a != b)
        lengths = np.linalg.norm(t.V[t.edges[:, 0]] - t.V[t.edges[:, 1]], axis=1)
        cost = np.zeros(len(a))
        cost[on] = seam_costs(res.samples[on, 0], res.samples[on, 1], lengths[on])
        per = np.zeros(len(t.F))
        np.add.at(per, t.pairs[:, 0], 0.5 * cost)
        np.add.at(per, t.pairs[:, 1], 0.5 * cost)
        out[t.face_ids] = per
    return out


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



def _patch_domains(results) -> list[tuple[np.ndarray, np.ndarray]]:
    """Fig. 4: the source domain ``(n, 3, 2)`` and target domain ``(m, 3, 2)`` of the first patches
    of the first pair."""
    return [(patch.locator.T, patch.corner_uv) for patch in results[0][0].patches[:3]]


def _transfer(cfg, inputs: Inputs, ctx) -> TransferResult:
    with ctx.stage("load"):
        mesh = inputs.mesh(cfg.input)
        work = _work_mesh(cfg, mesh)
    ctx.budget.require("extraction.subdivide", cfg.transfer.extraction.subdivide, len(work.mesh.faces),
                       "faces after refinement", bytes_each=BYTES_PER_FACE)
    preps = _prepare(cfg, ctx, mesh, work, inputs)
    results = _synthesize(cfg, ctx, preps)
    with ctx.stage("extract"):
        layout = _layout(work, preps, results)
        work, layout = _refine(cfg, ctx, work, layout, preps, results)
        ext = _extract(cfg, work, layout, preps, results)
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
        seam_field=_seam_field(preps, results, int(layout.origin.max()) + 1)[layout.origin],
        patch_domains=_patch_domains(results),
    )


def compute(cfg, inputs: Inputs, ctx) -> TransferResult:
    """Run ``cfg`` (mode transfer) over ``inputs`` without writing."""
    try:
        return _transfer(cfg, inputs, ctx)
    except KeyedError as exc:
        raise user_error(exc) from None
