"""``synthkit surface-by-numbers`` run (mode: segment): load, strokes, segmentation, outputs.

Stages (``report.json`` ``timings``): ``load``, ``strokes``, ``graph`` (graph, costs, region term),
``hierarchy`` (LOD maps and the static coarse graphs), ``cut`` (all levels), ``single_level`` (with
``compare_single_level``), ``views``, ``export``, ``previews``.

Outputs: ``labels.ply`` (int32 ``label`` and a region colour on every face and vertex),
``labels.seg`` (one face label per line), ``regions/<name><suffix>`` (one mesh per region in the
input's format), ``cut.obj`` (the boundary as OBJ ``l`` polylines; ``cut_smooth.obj`` the same
curves smoothed over the surface with ``smooth_cut``), ``regions.png`` (four views,
strokes darker, cut in red) and ``level_<k>.png`` (free band of each level in grey, Fig. 3); with
``views.render`` (``--render-views``) or ``mode: views``, ``views/<view>.png`` renders to paint
strokes on and ``views/<view>.json`` their cameras (``mode: views`` stops there).

Errors: a stroke index out of range, a stroke point off the surface, a vertex or face stroked for
two regions, a region without strokes, a painted PNG of the wrong size or with a colour that maps
to no region, and ``region_term.model: color`` on a mesh without colours are config errors (exit 2)
naming the key and value; a mesh without faces or an unreadable PNG is an input error (exit 3).
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import cv2
import numpy as np
import trimesh
from trimesh.exchange.obj import export_obj

from synthkit import preview
from synthkit.errors import ConfigError
from synthkit.io.atomic import write_text_atomic
from synthkit.io.images import load_image, save_image
from synthkit.io.meshes import load_mesh, save_mesh
from synthkit.io.segmentation import write_labels_ply, write_point_polylines_obj, write_polylines_obj, write_seg
from synthkit.methods.surfacing import views
from synthkit.methods.surfacing.config import SurfacingConfig
from synthkit.methods.surfacing.segment import Options, Segmentation, chain_edges, cut_edges, segment
from synthkit.methods.surfacing.smoothing import polyline_length, smooth_chains
from synthkit.methods.surfacing.strokes import check_indices, snap_polyline, stroke_sets

__all__ = ["run", "options_of", "region_colors", "mesh_colors", "resolve_strokes"]

PALETTE = np.array(
    [[228, 26, 28], [55, 126, 184], [77, 175, 74], [152, 78, 163], [255, 127, 0], [255, 255, 51],
     [166, 86, 40], [247, 129, 191], [153, 153, 153], [102, 194, 165]], dtype=np.uint8
)
log = logging.getLogger("synthkit")
BYTES_PER_NODE = 1500
"""Peak bytes per graph node over the graph, hierarchy and cuts (measured about 1 kB at 1M faces)."""


def options_of(cfg: SurfacingConfig) -> Options:
    """Solver options from the config."""
    m, r = cfg.multires, cfg.region_term
    return Options(
        graph=cfg.graph, eta=cfg.boundary.eta, gamma=cfg.boundary.gamma, region_model=r.model,
        region_weight=r.weight, concavity=r.concavity, trust=r.trust, wall_deg=r.wall_deg, clusters=r.clusters,
        multires=m.enabled,
        coarsest_nodes=m.coarsest_nodes, ratio=m.ratio, max_levels=m.max_levels, band_rings=m.band_rings,
        crease_deg=m.crease_deg, compare_single_level=cfg.compare_single_level,
    )


def region_colors(cfg: SurfacingConfig) -> np.ndarray:
    """``(L, 3) uint8`` colour of each region: its ``color``, else the colour it is painted in (the first
    image that lists it), else the palette's."""
    painted = {}
    for item in cfg.images:
        for name, rgb in item.colors.items():
            painted.setdefault(name, rgb)
    return np.array([r.color if r.color is not None else painted.get(r.name, PALETTE[k % len(PALETTE)])
                     for k, r in enumerate(cfg.regions)], dtype=np.uint8)


def mesh_colors(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """``(#V, 3)`` float RGB in [0, 1] from vertex colours or the texture at the UVs; None without."""
    visual = mesh.visual
    if visual.kind == "texture":
        visual = visual.to_color()
    if visual.kind != "vertex":
        return None
    return np.asarray(visual.vertex_colors, np.float64)[:, :3] / 255.0


class ViewCache:
    """Camera, face-ID buffer and render of each named view of one mesh, made on first use."""

    def __init__(self, mesh: trimesh.Trimesh, size: int):
        self.V, self.F, self.size = np.asarray(mesh.vertices), np.asarray(mesh.faces), size
        self._views: dict = {}

    def __getitem__(self, name: str):
        if name not in self._views:
            cam = views.camera(self.V, name, self.size)
            face_at = views.face_id_buffer(self.V, self.F, cam)
            self._views[name] = (cam, face_at, views.render(self.V, self.F, face_at, cam))
        return self._views[name]


def _image_sets(cfg: SurfacingConfig, cache: ViewCache) -> tuple[list[np.ndarray], list[set], list[dict]]:
    """Vertices stroked per region by the painted images, the views each region was painted in, and
    per image the pixel counts of :func:`views.image_strokes`."""
    names = [r.name for r in cfg.regions]
    out = [np.zeros(0, np.int64) for _ in names]
    seen: list[set] = [set() for _ in names]
    counts = []
    for k, item in enumerate(cfg.images):
        img = load_image(item.image)
        cam, face_at, rendered = cache[item.view]
        if img.shape[:2] != face_at.shape:
            raise ConfigError(f"images[{k}].image: {item.image} is {img.shape[1]}x{img.shape[0]} pixels, but view "
                              f"'{item.view}' renders {cam.size}x{cam.size} (views.size)")
        colors = np.full((len(names), 3), np.nan)
        for name, rgb in item.colors.items():
            colors[names.index(name)] = np.asarray(rgb) / 255.0
        sets, count = views.image_strokes(img, rendered, face_at, cache.V, cache.F, cam, colors,
                                          tolerance=item.tolerance, opacity=item.opacity)
        counts.append({"image": str(item.image), "view": item.view, **count})
        for r, found in enumerate(sets):
            if len(found):
                seen[r].add(item.view)
        out = [np.union1d(a, b) for a, b in zip(out, sets, strict=True)]
    return out, seen, counts


def _no_strokes(key: str, region, counts: list[dict]) -> ConfigError:
    """The error of a region left without strokes, naming an image's unread paint when there is some."""
    odd = [(k, c) for k, c in enumerate(counts) if c["ignored"]]
    hint = ""
    if odd:
        k, c = max(odd, key=lambda kc: kc[1]["ignored"])
        hint = (f"; images[{k}]: {c['ignored']} painted pixels match no stroke colour (most often "
                f"{c['ignored_rgb']}; check images[{k}].colors)")
    return ConfigError(f"{key} ({region.name}): region has no strokes (give vertices, faces, points or images){hint}")


def _one_view_notes(cfg: SurfacingConfig, seen: list[set], other: list[bool]) -> list[str]:
    """One note per view for the regions whose strokes all come from images of that view alone: the
    faces it does not see (their far side) hold none of their strokes, so there only the cut decides."""
    by_view: dict[str, list[str]] = {}
    for region, views_of, more in zip(cfg.regions, seen, other, strict=True):
        if len(views_of) == 1 and not more:
            by_view.setdefault(next(iter(views_of)), []).append(region.name)
    return [f"strokes of {', '.join(names)} reach only faces seen from view '{view}'; the far side is left to "
            f"the cut (paint over another view too to hold it)" for view, names in by_view.items()]


def resolve_strokes(cfg: SurfacingConfig, mesh: trimesh.Trimesh, cache: ViewCache,
                    notes: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Owners of stroked vertices ``(#V,)`` and faces ``(#F,)``; ConfigError naming the key. ``notes``
    (when given) receives ``painted_pixels`` (per image) and ``stroke_notes``."""
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    from_images, seen, counts = _image_sets(cfg, cache)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    vsets, fsets, other = [], [], []
    for k, region in enumerate(cfg.regions):
        key = f"regions[{k}]"
        try:
            v = check_indices(region.vertices, len(V), "vertex")
        except ValueError as exc:
            raise ConfigError(f"{key}.vertices: {exc}") from None
        try:
            f = check_indices(region.faces, len(F), "face")
        except ValueError as exc:
            raise ConfigError(f"{key}.faces: {exc}") from None
        for j, line in enumerate(region.points):
            try:
                v = np.union1d(v, snap_polyline(mesh, line, tolerance=cfg.points_tolerance * diag))
            except ValueError as exc:
                raise ConfigError(f"{key}.points[{j}]: {exc}") from None
        other.append(bool(len(v) or len(f)))
        v = np.union1d(v, from_images[k])
        if not len(v) and not len(f):
            raise _no_strokes(key, region, counts)
        vsets.append(v)
        fsets.append(f)
    if notes is not None:
        notes["painted_pixels"] = counts
        notes["stroke_notes"] = _one_view_notes(cfg, seen, other)
    try:
        return stroke_sets(len(V), len(F), vsets, fsets, [r.name for r in cfg.regions])
    except ValueError as exc:
        raise ConfigError(f"regions: {exc}") from None


def _segment(cfg: SurfacingConfig, ctx, mesh, vertex_owner, face_owner) -> Segmentation:
    opt = options_of(cfg)
    n_nodes = len(mesh.faces) if cfg.graph == "face" else len(mesh.vertices)
    ctx.budget.require("input", cfg.input, n_nodes, "graph nodes", bytes_each=BYTES_PER_NODE)
    colors = mesh_colors(mesh) if opt.region_model == "color" else None
    if opt.region_model == "color" and colors is None:
        raise ConfigError(f"region_term.model: color: {cfg.input} has no vertex colours and no texture")
    try:
        return segment(np.asarray(mesh.vertices), np.asarray(mesh.faces), vertex_owner, face_owner,
                       len(cfg.regions), opt, colors=colors, rng=ctx.rng)
    except ValueError as exc:
        raise ConfigError(f"regions: {exc}") from None


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


def _export(cfg: SurfacingConfig, ctx, mesh, seg: Segmentation, cut: np.ndarray) -> None:
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    colors = region_colors(cfg)
    vl = seg.vertex_labels
    vcol = np.where(vl[:, None] >= 0, colors[np.maximum(vl, 0)], 0).astype(np.uint8)
    write_labels_ply(ctx.path("labels_ply", "labels.ply"), V, F, seg.face_labels, vl, colors[seg.face_labels], vcol)
    write_seg(ctx.path("labels_seg", "labels.seg"), seg.face_labels)
    write_polylines_obj(ctx.path("cut", "cut.obj"), V, chain_edges(cut))
    suffix = cfg.input.suffix.lower()
    suffix = suffix if suffix in (".obj", ".ply", ".off", ".stl", ".glb") else ".ply"
    bare = suffix == ".obj" and _invented_material(cfg.input, mesh)
    for k, region in enumerate(cfg.regions):
        sel = np.flatnonzero(seg.face_labels == k)
        if not len(sel):
            continue
        part = mesh.submesh([sel], append=True, repair=False)
        path = ctx.path(f"region_{region.name}", f"regions/{region.name}{suffix}")
        if bare:
            _write_obj_without_material(part, path)
        else:
            save_mesh(part, path)


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


def _write_obj_without_material(part: trimesh.Trimesh, path: Path) -> None:
    """Write ``part`` as OBJ with its UVs but no ``mtllib``/``usemtl`` and no material files."""
    text, _ = export_obj(part, include_texture=True, return_texture=True, write_texture=False)
    lines = [line for line in text.splitlines() if not line.startswith(("mtllib ", "usemtl "))]
    write_text_atomic(path, "\n".join(lines) + "\n")


def _stroked_faces(F, seg: Segmentation) -> np.ndarray:
    if seg.graph.kind == "face":
        return seg.seeds >= 0
    return (seg.seeds[F] >= 0).any(axis=1)


def _previews(cfg: SurfacingConfig, ctx, mesh, seg: Segmentation, cut: np.ndarray, curves=None) -> None:
    """``regions.png`` (the summary preview: four views, strokes darker, the cut in red: the smoothed
    ``curves`` when there are) and one ``level_<k>.png`` per level with its free band (Fig. 3)."""
    if not ctx.wants_preview("summary"):
        return
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    base = region_colors(cfg).astype(np.float64)[seg.face_labels] / 255.0
    base[_stroked_faces(F, seg)] *= 0.45
    lines = V[cut] if len(cut) else None
    if curves is not None and len(curves):
        lines = np.concatenate([np.stack([c[:-1], c[1:]], axis=1) for c in curves])
    views = ("front", "side", "top", "iso")
    size = cfg.preview_size
    imgs = [preview.rasterize_mesh(V, F, face_colors=base, view=v, size=size, lines=lines) for v in views]
    montage = preview.montage_png(None, imgs, titles=list(views), height=size)
    legend = _legend([r.name for r in cfg.regions], region_colors(cfg), montage.shape[1])
    preview.image_png(ctx.path("preview_regions", "regions.png"), np.concatenate([montage, legend], axis=0))
    if not ctx.wants_preview("all"):
        return
    for k, st in enumerate(seg.levels):
        col = region_colors(cfg).astype(np.float64)[seg.face_labels] / 255.0
        col[st["free_faces"]] = 0.75
        img = preview.rasterize_mesh(V, F, face_colors=col, view="iso", size=size)
        title = f"level {k}: {st['free_nodes']} of {st['nodes']} nodes free"
        preview.montage_png(ctx.path(f"preview_level_{k}", f"level_{k}.png"), [img], titles=[title], height=size)


def _legend(names: list[str], colors: np.ndarray, width: int) -> np.ndarray:
    """A white band ``(h, width, 3) float32`` with a swatch in each region's colour ``colors (L, 3)
    uint8`` (the stroke colours) and its name, in rows as wide as ``width`` allows."""
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.5
    items = [(name, 24 + cv2.getTextSize(name, font, scale, 1)[0][0] + 16) for name in names]
    rows, x = [[]], 0
    for name, w in items:
        if x + w > width and rows[-1]:
            rows.append([])
            x = 0
        rows[-1].append((name, x))
        x += w
    band = np.full((22 * len(rows) + 4, width, 3), 255, np.uint8)
    for r, row in enumerate(rows):
        for name, x0 in row:
            y = 4 + 22 * r
            rgb = tuple(int(c) for c in colors[names.index(name)])
            cv2.rectangle(band, (x0 + 4, y), (x0 + 20, y + 16), rgb, -1)
            cv2.rectangle(band, (x0 + 4, y), (x0 + 20, y + 16), (0, 0, 0), 1)
            cv2.putText(band, name, (x0 + 24, y + 13), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return band.astype(np.float32) / 255.0


def _write_views(cfg: SurfacingConfig, ctx, cache: ViewCache) -> None:
    for name in cfg.views.names:
        cam, _, rendered = cache[name]
        save_image(ctx.path(f"view_{name}", f"views/{name}.png"), rendered)
        ctx.path(f"camera_{name}", f"views/{name}.json").write_text(json.dumps(cam.to_json(), indent=1) + "\n")
    ctx.metrics["views"] = list(cfg.views.names)


def run(cfg: SurfacingConfig, ctx) -> None:
    """Run ``cfg`` (mode segment; mode views: only the view renders; mode transfer:
    :func:`synthkit.methods.surfacing.transfer.pipeline.run_transfer`) into ``ctx.out_dir``."""
    if cfg.mode == "transfer":
        from synthkit.methods.surfacing.transfer.pipeline import run_transfer

        return run_transfer(cfg, ctx)
    with ctx.stage("load"):
        mesh = load_mesh(cfg.input)
    cache = ViewCache(mesh, cfg.views.size)
    if cfg.mode == "views" or cfg.views.render:
        with ctx.stage("views"):
            _write_views(cfg, ctx, cache)
        if cfg.mode == "views":
            return
    with ctx.stage("strokes"):
        notes: dict = {}
        vertex_owner, face_owner = resolve_strokes(cfg, mesh, cache, notes)
    if cfg.images:
        ctx.metrics.update(notes)
        ignored = sum(c["ignored"] for c in notes["painted_pixels"])
        if ignored:
            log.warning("%d painted pixels match no stroke colour and were ignored (report.json "
                        "metrics.painted_pixels)", ignored)
        for note in notes["stroke_notes"]:
            log.warning("%s", note)
    seg = _segment(cfg, ctx, mesh, vertex_owner, face_owner)
    for name, seconds in seg.timings.items():
        ctx.timings[name] = ctx.timings.get(name, 0.0) + seconds
    if seg.single_level is not None:
        ctx.timings["single_level"] = seg.single_level["seconds"]
    cut = cut_edges(np.asarray(mesh.vertices), np.asarray(mesh.faces), seg.face_labels)
    ctx.metrics.update(_metrics(cfg, mesh, seg, cut))
    curves = None
    if cfg.smooth_cut:
        with ctx.stage("smoothing"):
            curves = smooth_chains(mesh.vertices, mesh.faces, chain_edges(cut), cfg.smooth_cut)
        ctx.metrics["cut_length_smoothed"] = float(sum(polyline_length(c) for c in curves))
    with ctx.stage("export"):
        _export(cfg, ctx, mesh, seg, cut)
        if curves is not None:
            write_point_polylines_obj(ctx.path("cut_smooth", "cut_smooth.obj"), curves)
    with ctx.stage("previews"):
        _previews(cfg, ctx, mesh, seg, cut, curves)
