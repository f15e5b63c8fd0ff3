"""What both modes of surface-by-numbers read and segment before their own stages: the mesh's
colours, the named views of the painted strokes, the stroke owners and the segmentation of a
mesh into its stroked regions. :mod:`.pipeline` (mode segment) and :mod:`.transfer.pipeline`
(mode transfer, which segments its target and source meshes from strokes) both use it, so that
neither imports the other.

Errors are :class:`~synthkit.errors.KeyedError`: a ValueError whose line starts with the config key it
concerns; the two pipelines raise it as a ConfigError (exit 2).
"""

from __future__ import annotations

import logging

import numpy as np
import trimesh

from synthkit.errors import KeyedError
from synthkit.methods.surfacing import views
from synthkit.methods.surfacing.options import options_of, stroke_colors
from synthkit.methods.surfacing.segment import Segmentation, segment
from synthkit.methods.surfacing.strokes import check_indices, snap_polyline, stroke_sets

log = logging.getLogger(__name__)

__all__ = ["ViewCache", "mesh_colors", "stroke_owners", "segmentation", "BYTES_PER_NODE"]

BYTES_PER_NODE = 1500
"""Peak bytes per graph node over the graph, hierarchy and cuts (docs/findings/surface-by-numbers.md)."""


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


def _image_sets(cfg, cache: ViewCache, inputs) -> tuple[list[np.ndarray], list[set], list[dict]]:
    """Vertices stroked per region by the painted images, the views each region was painted in, and
    per image the pixel counts of :func:`views.image_strokes`."""
    names = [r.name for r in cfg.regions]
    out = [np.zeros(0, np.int64) for _ in names]
    seen: list[set] = [set() for _ in names]
    counts = []
    for k, item in enumerate(cfg.images):
        img = inputs.image(item.image)
        cam, face_at, rendered = cache[item.view]
        if img.shape[:2] != face_at.shape:
            raise KeyedError(f"images[{k}].image", f"{item.image} is {img.shape[1]}x{img.shape[0]} pixels, but "
                             f"view '{item.view}' renders {cam.size}x{cam.size} (views.size)")
        sets, count = views.image_strokes(img, rendered, face_at, cache.V, cache.F, cam, stroke_colors(cfg, k),
                                          tolerance=item.tolerance, opacity=item.opacity)
        counts.append({"image": str(item.image), "view": item.view, **count})
        for r, found in enumerate(sets):
            if len(found):
                seen[r].add(item.view)
        out = [np.union1d(a, b) for a, b in zip(out, sets, strict=True)]
    return out, seen, counts


def _no_strokes(key: str, region, counts: list[dict]) -> KeyedError:
    """The error of a region left without strokes, naming an image's unread paint when there is some."""
    odd = [(k, c) for k, c in enumerate(counts) if c["ignored"]]
    hint = ""
    if odd:
        k, c = max(odd, key=lambda kc: kc[1]["ignored"])
        hint = (f"; images[{k}]: {c['ignored']} painted pixels match no stroke colour (most often "
                f"{c['ignored_rgb']}; check images[{k}].colors)")
    return KeyedError(f"{key} ({region.name})", f"region has no strokes (give vertices, faces, points or "
                      f"images){hint}")


def _say_unnamed_colors(cfg, counts: list[dict], strict: bool) -> None:
    """One warning per painted colour that names no region (``counts[k]["unnamed"]``); with
    ``strict``, the first is a KeyedError of its image."""
    for k, c in enumerate(counts):
        for color in c["unnamed"]:
            line = (f"{cfg.images[k].image}: {color['pixels']} pixels are painted in {color['hex']} (rgb "
                    f"{color['rgb']}), a colour that names no region: farther than {views.STROKE_COLOR_TOLERANCE} "
                    f"from every colour of images[{k}].colors")
            if strict:
                raise KeyedError(f"images[{k}].image", line + " (--strict)")
            log.warning("images[%d].image: %s", k, line)


def _one_view_notes(cfg, seen: list[set], other: list[bool]) -> list[str]:
    """One note per view for the regions whose strokes all come from images of that view alone: the
    faces it does not see (their far side) hold none of their strokes, so there only the cut decides."""
    by_view: dict[str, list[str]] = {}
    for region, views_of, more in zip(cfg.regions, seen, other, strict=True):
        if len(views_of) == 1 and not more:
            by_view.setdefault(next(iter(views_of)), []).append(region.name)
    return [f"strokes of {', '.join(names)} reach only faces seen from view '{view}'; the far side is left to "
            f"the cut (paint over another view too to hold it)" for view, names in by_view.items()]


def _keyed(key: str, call, *args, **kwargs):
    """``call(*args, **kwargs)``, its ValueError raised again as a :class:`KeyedError` of ``key``."""
    try:
        return call(*args, **kwargs)
    except ValueError as exc:
        raise KeyedError(key, str(exc)) from None


def stroke_owners(cfg, mesh: trimesh.Trimesh, cache: ViewCache, inputs,
                  notes: dict | None = None, *, strict: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Owners of stroked vertices ``(#V,)`` and faces ``(#F,)`` of ``cfg.regions`` and ``cfg.images``
    (painted PNGs read through ``inputs``). ``notes`` (when given) receives ``painted_pixels`` (per
    image) and ``stroke_notes``. A painted colour that names no region is a warning, or with
    ``strict`` a KeyedError."""
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    from_images, seen, counts = _image_sets(cfg, cache, inputs)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    vsets, fsets, other = [], [], []
    for k, region in enumerate(cfg.regions):
        key = f"regions[{k}]"
        v = _keyed(f"{key}.vertices", check_indices, region.vertices, len(V), "vertex")
        f = _keyed(f"{key}.faces", check_indices, region.faces, len(F), "face")
        for j, line in enumerate(region.points):
            snapped = _keyed(f"{key}.points[{j}]", snap_polyline, mesh, line, tolerance=cfg.points_tolerance * diag)
            v = np.union1d(v, snapped)
        other.append(bool(len(v) or len(f)))
        v = np.union1d(v, from_images[k])
        if not len(v) and not len(f):
            raise _no_strokes(key, region, counts)
        vsets.append(v)
        fsets.append(f)
    _say_unnamed_colors(cfg, counts, strict)
    if notes is not None:
        notes["painted_pixels"] = counts
        notes["stroke_notes"] = _one_view_notes(cfg, seen, other)
    return _keyed("regions", stroke_sets, len(V), len(F), vsets, fsets, [r.name for r in cfg.regions])


def segmentation(cfg, ctx, mesh: trimesh.Trimesh, vertex_owner, face_owner) -> Segmentation:
    """:func:`~synthkit.methods.surfacing.segment.segment` of ``mesh`` by the stroke owners with the
    config's options; the solver's stage timings are added to ``ctx.timings``."""
    opt = options_of(cfg).segment
    n_nodes = len(mesh.faces) if cfg.graph == "face" else len(mesh.vertices)
    ctx.budget.require("input", cfg.input, n_nodes, "graph nodes", bytes_each=BYTES_PER_NODE)
    colors = mesh_colors(mesh) if opt.region_model == "color" else None
    if opt.region_model == "color" and colors is None:
        raise KeyedError("region_term.model", f"color: {cfg.input} has no vertex colours and no texture")
    seg = _keyed("regions", segment, np.asarray(mesh.vertices), np.asarray(mesh.faces), vertex_owner, face_owner,
                 len(cfg.regions), opt, colors=colors, rng=ctx.rng)
    for name, seconds in seg.timings.items():
        ctx.timings[name] = ctx.timings.get(name, 0.0) + seconds
    return seg
