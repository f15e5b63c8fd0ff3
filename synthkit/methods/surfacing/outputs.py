"""What ``synthkit surface-by-numbers`` (mode segment and mode views) gives back and writes.

Outputs: ``labels.ply`` (int32 ``label`` and a region colour on every face and vertex),
``labels.seg`` (one face label per line), ``regions/<name><suffix>`` (one mesh per region in the
input's format), ``cut.obj`` (the boundary as OBJ ``l`` polylines; ``cut_smooth.obj`` the same
curves smoothed over the surface with ``smooth_cut``), ``regions.png`` (four views, strokes
darker, cut in red, a legend in the region colours) and ``level_<k>.png`` (free band of each level
in grey, Fig. 3); with ``views.render`` (``--render-views``) or ``mode: views``,
``views/<view>.png`` renders to paint strokes on and ``views/<view>.json`` their cameras.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np
import trimesh

from synthkit import preview
from synthkit.io.assets import asset_from_trimesh, save_asset
from synthkit.io.images import save_image
from synthkit.io.segmentation import write_labels_ply, write_point_polylines_obj, write_polylines_obj, write_seg
from synthkit.methods.surfacing.views import Camera
from synthkit.result import Result

__all__ = ["SegmentResult", "legend", "write_region", "REGION_SUFFIXES"]

REGION_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".glb")
"""Formats a region mesh is written in (the input's; others, and a mesh given in memory: PLY)."""


@dataclass(kw_only=True)
class SegmentResult(Result):
    """The segmentation of a mesh into its stroked regions (``synthkit.segment``; mode segment).

    Attributes
    ----------
    mesh : trimesh.Trimesh, the input mesh as read (``V (#V, 3)``, ``F (#F, 3)``)
    face_labels : (#F,) int32 region index of each face (into ``region_names``)
    vertex_labels : (#V,) int32 region of each vertex (-1: a vertex of no face)
    region_names : the L region names, in config order
    region_colors : (L, 3) uint8 colour of each region (its ``color``, its paint, or the palette's)
    cut_edges : (E, 2) int64 vertex pairs of the mesh edges between two regions
    cut_chains : the cut as polylines, each an array of vertex indices (``cut.obj``)
    cut_curves : with ``smooth_cut``, the same polylines smoothed over the surface, each ``(n, 3)``
        float64 (``cut_smooth.obj``); else None
    stroked_faces : (#F,) bool faces holding a stroke (darker in ``regions.png``)
    levels : per level of detail (finest first) its ``nodes``, ``free_nodes`` and ``free_faces
        (#F,) bool`` band (``level_<k>.png``)
    view_images : view name -> (S, S, 3) float32 render to paint strokes on (``views.render`` or mode
        views; else empty)
    cameras : view name -> the :class:`~synthkit.methods.surfacing.views.Camera` of that render
    region_suffix : the format region meshes are written in (``.ply`` for a mesh given in memory)
    bare_obj : region OBJs are written without a material (the input OBJ's UVs had none)

    In mode views only the views are filled (the mesh and labels are None).
    """

    method: ClassVar[str] = "surface-by-numbers"
    mesh: trimesh.Trimesh | None = None
    face_labels: np.ndarray | None = None
    vertex_labels: np.ndarray | None = None
    region_names: list[str] = field(default_factory=list)
    region_colors: np.ndarray | None = None
    cut_edges: np.ndarray | None = None
    cut_chains: list[np.ndarray] = field(default_factory=list)
    cut_curves: list[np.ndarray] | None = None
    stroked_faces: np.ndarray | None = None
    levels: list[dict] = field(default_factory=list)
    view_images: dict[str, np.ndarray] = field(default_factory=dict)
    cameras: dict[str, Camera] = field(default_factory=dict)
    region_suffix: str = ".ply"
    bare_obj: bool = False

    def region_mesh(self, name: str) -> trimesh.Trimesh | None:
        """The faces of region ``name`` as a mesh (``regions/<name><suffix>``); None when it is empty."""
        sel = np.flatnonzero(self.face_labels == self.region_names.index(name))
        return self.mesh.submesh([sel], append=True, repair=False) if len(sel) else None

    def write(self, ctx) -> None:
        """Write the views, the labels, the cut, the region meshes and the previews."""
        if self.view_images:
            with ctx.stage("views"):
                self._write_views(ctx)
        if self.mesh is None:
            return
        with ctx.stage("export"):
            self._export(ctx)
        with ctx.stage("previews"):
            self._previews(ctx)

    def _write_views(self, ctx) -> None:
        for name, rendered in self.view_images.items():
            save_image(ctx.path(f"view_{name}", f"views/{name}.png"), rendered)
            text = json.dumps(self.cameras[name].to_json(), indent=1) + "\n"
            ctx.path(f"camera_{name}", f"views/{name}.json").write_text(text)

    def _export(self, ctx) -> None:
        V, F = np.asarray(self.mesh.vertices), np.asarray(self.mesh.faces)
        colors, vl = self.region_colors, self.vertex_labels
        vcol = np.where(vl[:, None] >= 0, colors[np.maximum(vl, 0)], 0).astype(np.uint8)
        write_labels_ply(ctx.path("labels_ply", "labels.ply"), V, F, self.face_labels, vl,
                         colors[self.face_labels], vcol)
        write_seg(ctx.path("labels_seg", "labels.seg"), self.face_labels)
        write_polylines_obj(ctx.path("cut", "cut.obj"), V, self.cut_chains)
        for name in self.region_names:
            part = self.region_mesh(name)
            if part is None:
                continue
            path = ctx.path(f"region_{name}", f"regions/{name}{self.region_suffix}")
            for extra in write_region(part, path, name, bare=self.bare_obj)[1:]:
                ctx.path(f"file_regions/{extra}", f"regions/{extra}")
        if self.cut_curves is not None:
            write_point_polylines_obj(ctx.path("cut_smooth", "cut_smooth.obj"), self.cut_curves)

    def summary_image(self) -> np.ndarray:
        """``regions.png`` as an ``(H, W, 3) float32`` image in [0, 1]: four views in the region
        colours, stroked faces darker, the cut in red (the smoothed curves when there are), a legend."""
        V, F = np.asarray(self.mesh.vertices), np.asarray(self.mesh.faces)
        base = self.region_colors.astype(np.float64)[self.face_labels] / 255.0
        base[self.stroked_faces] *= 0.45
        lines = V[self.cut_edges] if len(self.cut_edges) else None
        if self.cut_curves is not None and len(self.cut_curves):
            lines = np.concatenate([np.stack([c[:-1], c[1:]], axis=1) for c in self.cut_curves])
        names = ("front", "side", "top", "iso")
        size = self.config.preview_size
        imgs = [preview.rasterize_mesh(V, F, face_colors=base, view=v, size=size, lines=lines) for v in names]
        montage = preview.montage_png(None, imgs, titles=list(names), height=size)
        band = legend(self.region_names, self.region_colors, montage.shape[1])
        return np.concatenate([montage, band], axis=0)

    def _previews(self, ctx) -> None:
        """``regions.png`` (the summary preview, :meth:`summary_image`) and one ``level_<k>.png`` per
        level with its free band (Fig. 3)."""
        if not ctx.wants_preview("summary"):
            return
        preview.image_png(ctx.path("preview_regions", "regions.png"), self.summary_image())
        if not ctx.wants_preview("all"):
            return
        V, F, size = np.asarray(self.mesh.vertices), np.asarray(self.mesh.faces), self.config.preview_size
        for k, st in enumerate(self.levels):
            col = self.region_colors.astype(np.float64)[self.face_labels] / 255.0
            col[st["free_faces"]] = 0.75
            img = preview.rasterize_mesh(V, F, face_colors=col, view="iso", size=size)
            title = f"level {k}: {st['free_nodes']} of {st['nodes']} nodes free"
            preview.montage_png(ctx.path(f"preview_level_{k}", f"level_{k}.png"), [img], titles=[title], height=size)


def legend(names: list[str], colors: np.ndarray, width: int) -> np.ndarray:
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


def write_region(part: trimesh.Trimesh, path: Path, name: str, *, bare: bool) -> list[str]:
    """Write the region mesh ``part`` named ``name`` with its appearance (:func:`save_asset`; with
    ``bare``, its UVs but no material: the input had none); returns the files written."""
    asset = asset_from_trimesh(part, name)
    if bare:
        asset = replace(asset, materials=[], face_material=np.full(len(asset.F), -1, np.int64))
    return save_asset(path, asset.V, asset.F, like=asset, corner_uv=asset.corner_uv,
                      face_material=asset.face_material, corner_color=asset.corner_color)
