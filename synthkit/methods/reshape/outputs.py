"""What ``synthkit reshape`` gives back (:class:`ReshapeResult`) and the files it writes.

Files: each piece in its input's format (an OBJ with its MTL and textures copied beside it, or a
GLB; a piece given in memory as an OBJ with a new MTL) or, with ``output.mesh_format`` usd/usda, as
``<piece>.usdc``/``.usda`` with its textures beside it, with UVs and materials unchanged except
the reshaped surfaces' (new materials in the piece's MTL, their PNGs beside it); ``before.png``, ``after.png``
(elongated edges blue, compressed red, handles green), ``baseline.png``, ``comparison.png``, the
textured ``before_after.png`` of a single piece and the texture previews of Figs. 7-8 under
``texture/``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
import trimesh

from synthkit.asset import Asset
from synthkit.io.assets import load_asset, save_asset
from synthkit.io.images import save_image
from synthkit.io.usd import USD_SUFFIXES, load_usd, mesh_suffix
from synthkit.methods.reshape import previews as P
from synthkit.methods.reshape.retexture import safe_name
from synthkit.methods.reshape.textured import Retexture, TexturedMesh, reshaped_asset
from synthkit.preview import Appearance, before_after_png, montage_png
from synthkit.result import Result

__all__ = ["ReshapeResult", "PreviewData", "reshaped", "write_piece", "write_previews", "write_texture_previews",
           "write_textured_summary"]


@dataclass
class PreviewData:
    """What the previews are drawn from: the scene's render triangles ``F (#F, 3)``, the constraint
    graph (``X0 (n, 3)``, ``edges (E, 2)``, ``node_of_vertex (#V,)``), the node positions after the
    reshape ``X (n, 3)`` and of the baseline ``Xb (n, 3)`` (or None), the ``handles (k,)`` and the
    texture reshape's per-surface ``(job, result, analysis)``."""

    F: np.ndarray
    graph: Any
    X: np.ndarray
    Xb: np.ndarray | None
    handles: np.ndarray
    surfaces: dict = field(default_factory=dict)


@dataclass(kw_only=True)
class ReshapeResult(Result):
    """The outcome of :func:`synthkit.reshape` (``synthkit reshape``).

    Attributes
    ----------
    meshes : piece name -> the reshaped ``trimesh.Trimesh`` (the input's positions ``(#P, 3)``
        moved, faces ``(#F, 3)`` over them; geometry only)
    textured : piece name -> the reshaped :class:`~synthkit.methods.reshape.textured.TexturedMesh` (render
        vertices ``V (#V, 3)`` and file ``positions (#P, 3)`` moved; UVs and materials as read)
    retexture : piece name -> the reshaped surfaces' :class:`~synthkit.methods.reshape.textured.Retexture`
        entries (faces, new UVs ``(#V, 2)``, material, baked ``image (H, W, 3) float32``); empty
        lists with ``texture: stretch``
    X : ``(n, 3)`` node positions of the constraint graph after the reshape
    """

    method: ClassVar[str] = "reshape"
    meshes: dict[str, trimesh.Trimesh]
    textured: dict[str, TexturedMesh]
    retexture: dict[str, list[Retexture]]
    X: np.ndarray
    previews: PreviewData = field(repr=False)

    @property
    def mesh(self) -> trimesh.Trimesh:
        """The reshaped mesh of the first (for ``input``, the only) piece."""
        return next(iter(self.meshes.values()))

    @property
    def images(self) -> dict[str, np.ndarray]:
        """Image file name -> baked texture ``(H, W, 3) float32`` of every reshaped surface."""
        return {e.image_name: e.image for entries in self.retexture.values() for e in entries}

    def asset(self, name: str | None = None) -> Asset | None:
        """The reshaped piece ``name`` (default the first) as an :class:`~synthkit.asset.Asset`
        with its new materials, for a piece given in memory; None for a piece read from a file
        (its written file is the asset)."""
        name = next(iter(self.textured)) if name is None else name
        mesh = self.textured[name]
        if not mesh.in_memory:
            return None
        return reshaped_asset(mesh, mesh.positions, self.retexture[name])

    def write(self, ctx) -> None:
        """Write the meshes, their textures and the previews (module docstring)."""
        cfg = self.config
        if cfg.texture != "stretch":
            with ctx.stage("texture_previews"):
                write_texture_previews(ctx, cfg, self.previews.surfaces)
        with ctx.stage("outputs"):
            for name, mesh in self.textured.items():
                write_piece(ctx, name, mesh, self.retexture[name], mesh_format=cfg.output.mesh_format)
            textured = write_textured_summary(ctx, cfg, self.textured)
            write_previews(ctx, cfg, self.previews, level="all" if textured else "summary")


def reshaped(mesh: TexturedMesh, positions: np.ndarray) -> TexturedMesh:
    """``mesh`` with its file positions replaced by ``positions (#P, 3)``."""
    return replace(mesh, V=positions[mesh.position_index], positions=positions)


def write_piece(ctx, name: str, mesh: TexturedMesh, entries: list[Retexture], *, mesh_format: str = "input") -> None:
    """One piece in its input's format (``mesh_format`` input: a glTF as a GLB, a piece given in
    memory as an OBJ) or as USD, with its MTL and textures beside an OBJ and, with ``entries``, its
    reshaped surfaces' materials and textures (:func:`reshaped_asset`)."""
    asset = reshaped_asset(mesh, mesh.positions, entries)
    suffix = ".obj" if mesh.in_memory else {".gltf": ".glb"}.get(mesh.source.suffix.lower(), mesh.source.suffix.lower())
    if mesh_format != "input":
        suffix = mesh_suffix(mesh_format)
    target = ctx.path(f"mesh_{name}", f"{name}{suffix}")
    for extra in save_asset(target, asset.V, asset.F, like=asset, corner_uv=asset.corner_uv,
                            face_material=asset.face_material, corner_color=asset.corner_color,
                            face_polygon=asset.face_polygon, face_group=asset.face_group)[1:]:
        ctx.path(f"file_{extra}", extra)


def write_textured_summary(ctx, cfg, meshes: dict[str, TexturedMesh]) -> bool:
    """``before_after.png`` (the summary): the input above the written result, textured as a DCC
    shows them (read back from the files), from three views framed alike. For a single textured
    input; chains of pieces keep ``comparison.png`` as their summary."""
    if len(meshes) != 1 or not ctx.wants_preview("summary"):
        return False
    (name, mesh), = meshes.items()
    before = mesh.asset
    if not before.textured and before.corner_color is None:
        return False
    written = ctx.out_dir / ctx.outputs[f"mesh_{name}"]
    after = (load_usd if written.suffix in USD_SUFFIXES else load_asset)(written)
    before_after_png(ctx.path("before_after", "before_after.png"),
                     *[(a.V, a.F, Appearance.of(a, like_input=True)) for a in (before, after)],
                     size=cfg.preview_size)
    return True


def write_previews(ctx, cfg, data: PreviewData, level: str = "summary") -> None:
    """before.png, after.png, baseline.png and comparison.png (the summary preview unless ``level``
    is "all": a textured before_after.png is the summary then)."""
    if not ctx.wants_preview(level):
        return
    graph = data.graph

    def image(Xn, key, name):
        Vn = Xn[graph.node_of_vertex]
        seg = np.stack([Xn[graph.edges[:, 0]], Xn[graph.edges[:, 1]]], axis=1)
        rest = np.linalg.norm(graph.X0[graph.edges[:, 1]] - graph.X0[graph.edges[:, 0]], axis=1)
        ratio = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) / rest
        img = P.reshape_image(Vn, data.F, seg, P.edge_colours(ratio), Xn[data.handles], view=cfg.view,
                            size=cfg.preview_size)
        if ctx.wants_preview("all"):
            save_image(ctx.path(key, name), img)
        return img

    imgs = [image(graph.X0, "before", "before.png"), image(data.X, "after", "after.png")]
    titles = ["before", "after (reshape)"]
    if data.Xb is not None:
        imgs.append(image(data.Xb, "baseline_preview", "baseline.png"))
        titles.append("Laplacian baseline")
    montage_png(ctx.path("comparison", "comparison.png"), imgs, titles=titles, height=cfg.preview_size)


def write_texture_previews(ctx, cfg, surfaces: dict) -> None:
    """Figs. 7-8 per surface, for the ``texture_reshape.previews`` surfaces the naive stretch would
    distort most (largest ``baseline_rigid_scale_error`` times baked texels)."""
    if not ctx.wants_preview("all"):
        return
    tau = cfg.texture_reshape.tau

    def distortion(item):
        res = item[1][1]
        return -(res.metrics["baseline_rigid_scale_error"] or 0.0) * res.texture.size

    paper = {k: v for k, v in surfaces.items() if v[2] is not None}
    order = sorted(paper.items(), key=distortion)[: cfg.texture_reshape.previews]
    for name, (job, res, tex) in order:
        rows, cols, off = P.source_window(job.C, tex.img.shape[:2], job.toroidal)
        stem = f"texture/{safe_name(name)}"
        montage_png(ctx.path(f"autosim_{name}", f"{stem}_autosimilarity.png"),
                    [tex.img[rows, cols], P.autosimilarity_image(tex.T[:, rows, cols], tau)],
                    titles=["texture", "autosimilarity x red, y green"], height=cfg.preview_size // 2)
        montage_png(ctx.path(f"grid_{name}", f"{stem}_grid.png"),
                    [P.grid_image(tex.img[rows, cols], res.grid.X, res.grid.edges, offset=off),
                     P.grid_image(res.texture, res.Y, res.grid.edges)],
                    titles=["grid before", "grid after"], height=cfg.preview_size)
        montage_png(ctx.path(f"segmentation_{name}", f"{stem}_segmentation.png"),
                    [tex.img[rows, cols], P.segmentation_image(tex.rigid, res.tiles)[rows, cols]],
                    titles=["texture", "rigid (light), stochastic, tiles"], height=cfg.preview_size // 2)
        montage_png(ctx.path(f"stretch_{name}", f"{stem}_comparison.png"), [res.naive, res.texture],
                    titles=["naive stretch", "texture reshape"], height=cfg.preview_size // 2)
