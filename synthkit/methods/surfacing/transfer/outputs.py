"""What ``synthkit surface-by-numbers`` (mode transfer) gives back and writes.

Outputs: ``transferred.ply`` (the target mesh with vertex colours, displaced positions and, for
``signal: attribute``, the transferred property), ``transferred<suffix>`` in the input's format
for displacement when the input is not PLY, ``transferred.obj`` + ``.mtl`` for texture signals
(the target's material ``original`` with ``transferred_original.png`` when it has a texture, no
material where it has none, and one material ``transfer_<k>`` per texture pair whose faces have
UVs into ``transferred_transfer_<k>.png``: the source image with ``blend: none``, else the blended
texture baked into an atlas; with ``output.mesh_format`` usd/usda,
``transferred.usdc``/``.usda`` and its textures instead of both), ``patches.ply``
(int32 ``label`` = patch id per face, -1 outside every target region; ids count on over the
pairs), and the previews ``transfer.png`` (before and after from three views: the summary),
``patches.png``, ``seams.png`` (seam cost per edge on its faces) and ``params.png`` (the first
patches' source and target domains, Fig. 4).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import trimesh

from synthkit import preview
from synthkit.asset import Asset, Material
from synthkit.io.assets import save_asset
from synthkit.io.meshes import save_mesh
from synthkit.io.signals import write_signal_ply
from synthkit.io.usd import mesh_suffix
from synthkit.result import Result

__all__ = ["TransferResult", "transferred_asset", "PALETTE"]

PALETTE = np.vstack([preview.SET1, np.array([[141, 160, 203], [231, 138, 195]], np.uint8)])
"""Patch colours of ``patches.ply`` and ``patches.png`` (grey: no patch): the region palette and two more."""


def _u8(values: np.ndarray) -> np.ndarray:
    return np.round(np.clip(values, 0, 1) * 255).astype(np.uint8)


def transferred_asset(V, F, colors, corner_uv, face_material, textures) -> Asset:
    """The transferred mesh as an :class:`~synthkit.asset.Asset`: ``V (#V, 3)``, ``F (#F, 3)``,
    corner colours from ``colors (#V, 3)`` in [0, 1]; with ``corner_uv (#F, 3, 2)``, the materials
    ``original`` (the target's own texture, ``textures[0]``; left out, and its faces without a
    material, when the target has none) and ``transfer_<k>`` (``textures[k + 1]``) chosen by
    ``face_material (#F,)``."""
    F = np.asarray(F, np.int64)
    rgba = np.concatenate([_u8(colors), np.full((len(colors), 1), 255, np.uint8)], axis=1)[F]
    if corner_uv is None:
        return Asset(np.asarray(V, np.float64), F, None, rgba, np.full(len(F), -1, np.int64), [], "transferred",
                     Path("transferred.ply"))
    names = ["original"] + [f"transfer_{k}" for k in range(len(textures) - 1)]
    materials = [Material(name, image=None if img is None else _u8(np.asarray(img)[..., :3]))
                 for name, img in zip(names, textures, strict=True)]
    fm = np.asarray(face_material, np.int64)
    if textures[0] is None:  # the target had no texture: its faces keep no material, none is invented
        materials, fm = materials[1:], fm - 1
    return Asset(np.asarray(V, np.float64), F, np.asarray(corner_uv, np.float64), rgba, fm, materials,
                 "transferred", Path("transferred.obj"))


@dataclass(kw_only=True)
class TransferResult(Result):
    """Detail synthesized over the target regions (``synthkit.transfer``; mode transfer).

    Attributes
    ----------
    positions : (#V, 3) float64 vertex positions (displaced by a ``displacement`` pair)
    faces : (#F, 3) int64 triangles of the target, welded and refined as the transfer worked on it
    colors : (#V, 3) float64 vertex colours in [0, 1] (``color`` and ``texture`` pairs; the target's own
        elsewhere, grey without)
    attributes : property name -> (#V, C) float64 values of ``attribute`` pairs
    patch_ids : (#F,) int64 patch of each face (-1 outside every target region; ids count on over the pairs)
    corner_uv : (#F, 3, 2) float64 texture coordinates per face corner, or None (no texture anywhere)
    face_material : (#F,) int64 0 = the target's own material, k + 1 = pair k's source texture; or None
    textures : the (H, W, 3) float images of those materials (None: no texture): ``textures[0]`` the
        target's own, ``textures[k + 1]`` pair k's source image, or its baked atlas when pair k is in ``baked``
    baked : the texture pairs whose blended texture was baked into an atlas (``blend`` not ``none``)
    seam_field : (#F,) float64 seam cost per face (half of each incident seam; NaN outside the regions)
    patch_domains : the source and target domains ``(n, 3, 2)`` of the first patches (Fig. 4)
    before_positions, before_colors : the target before the transfer (colours None: it had none)
    input_suffix : the input file's suffix (``""`` for a mesh given in memory)
    """

    method: ClassVar[str] = "surface-by-numbers"
    positions: np.ndarray
    faces: np.ndarray
    colors: np.ndarray
    attributes: dict[str, np.ndarray] = field(default_factory=dict)
    patch_ids: np.ndarray
    corner_uv: np.ndarray | None = None
    face_material: np.ndarray | None = None
    textures: list[np.ndarray | None] = field(default_factory=list)
    baked: list[int] = field(default_factory=list)
    seam_field: np.ndarray
    patch_domains: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    before_positions: np.ndarray
    before_colors: np.ndarray | None = None
    input_suffix: str = ""

    @property
    def asset(self) -> Asset:
        """The textured result as an :class:`~synthkit.asset.Asset` (``transferred.obj``: corner UVs
        into ``textures`` by ``face_material``; the vertex colours per corner)."""
        return transferred_asset(self.positions, self.faces, self.colors, self.corner_uv, self.face_material,
                                 self.textures)

    @property
    def mesh(self) -> trimesh.Trimesh:
        """The transferred mesh with its vertex colours (``transferred.ply``, without the attributes)."""
        return trimesh.Trimesh(self.positions, self.faces, vertex_colors=_u8(self.colors), process=False)

    def write(self, ctx) -> None:
        """Write the transferred meshes, the patches and the previews."""
        with ctx.stage("export"):
            self._export(ctx)
        with ctx.stage("previews"):
            self._previews(ctx)

    def _export_obj(self, ctx) -> None:
        """``transferred.obj`` + ``.mtl`` (:attr:`asset`): the target's own material where it has a
        texture, and one material per texture pair with its source texture or, blended, its baked
        atlas; the textures beside it as ``transferred_<material>.png``."""
        asset = self.asset
        target = ctx.path("transferred_obj", "transferred.obj")
        for extra in save_asset(target, asset.V, asset.F, like=asset, corner_uv=asset.corner_uv,
                                face_material=asset.face_material)[1:]:
            ctx.path(f"file_{extra}", extra)

    def _export_usd(self, ctx) -> None:
        """``transferred.usdc`` (``.usda``): :attr:`asset` (displaced positions, colours, UVs and the
        materials of ``transferred.obj``) with its textures beside it."""
        a = self.asset
        target = ctx.path("transferred_usd", f"transferred{mesh_suffix(self.config.output.mesh_format)}")
        for extra in save_asset(target, a.V, a.F, like=a, corner_uv=a.corner_uv, face_material=a.face_material,
                                corner_color=a.corner_color)[1:]:
            ctx.path(f"file_{extra}", extra)

    def _export(self, ctx) -> None:
        F = self.faces
        write_signal_ply(ctx.path("transferred", "transferred.ply"), self.positions, F, _u8(self.colors),
                         self.attributes)
        suffix = self.input_suffix
        textured_obj = self.corner_uv is not None and suffix == ".obj"  # that OBJ carries the displaced positions
        usd = self.config.output.mesh_format != "input"
        if usd:
            self._export_usd(ctx)
        elif any(p.signal == "displacement" for p in self.config.transfer.pairs) \
                and suffix in (".obj", ".off", ".stl") and not textured_obj:
            displaced = trimesh.Trimesh(self.positions, F, process=False)
            save_mesh(displaced, ctx.path("transferred_mesh", f"transferred{suffix}"))
        if self.corner_uv is not None and not usd:
            self._export_obj(ctx)
        pal = np.vstack([PALETTE, [[90, 90, 90]]])
        fc = pal[np.where(self.patch_ids >= 0, self.patch_ids % len(PALETTE), len(PALETTE))]
        save_mesh(trimesh.Trimesh(self.positions, F, process=False), ctx.path("patches", "patches.ply"),
                  face_labels=self.patch_ids.astype(np.int32), face_colors=fc)

    def _textured_look(self) -> preview.Appearance | None:
        """How ``transferred.obj`` looks (its corner UVs into the target's own texture and the pairs'
        source textures), or None when the result has no UVs (it is then drawn in its vertex colours)."""
        if self.corner_uv is None:
            return None
        images = [None if img is None else np.asarray(img, np.float32)[..., :3] for img in self.textures]
        material = np.asarray(self.face_material, np.int64)
        has = np.array([img is not None for img in images])
        face_image = np.where(has[material], material, -1)
        return preview.Appearance(corner_uv=self.corner_uv, face_image=face_image, images=images,
                                  face_tint=np.ones((len(material), 3)))

    def summary_image(self) -> np.ndarray:
        """``transfer.png`` as an ``(H, W, 3) float32`` image in [0, 1]: the target before and after
        (textured as ``transferred.obj`` when it has UVs) from three views."""
        V0, F = self.before_positions, self.faces
        size = self.config.preview_size
        before = np.full((len(V0), 3), 0.75) if self.before_colors is None else self.before_colors
        views = ("front", "side", "iso")
        imgs = [preview.rasterize_mesh(V0, F, face_colors=_face_colors(F, before), view=v, size=size) for v in views]
        look = self._textured_look()
        imgs += [preview.rasterize_mesh(self.positions, F, face_colors=_face_colors(F, self.colors), view=v,
                                        size=size, appearance=look) for v in views]
        titles = [f"before {v}" for v in views] + [f"after {v}" for v in views]
        return preview.montage_png(None, imgs, titles=titles, height=size)

    def _previews(self, ctx) -> None:
        """``transfer.png`` (the summary, :meth:`summary_image`), ``patches.png``, ``seams.png`` and
        ``params.png``."""
        if not ctx.wants_preview("summary"):
            return
        preview.image_png(ctx.path("preview_transfer", "transfer.png"), self.summary_image())
        if not ctx.wants_preview("all"):
            return
        F, size, views = self.faces, self.config.preview_size, ("front", "side", "iso")
        pal = np.vstack([PALETTE, [[90, 90, 90]]]).astype(np.float64) / 255.0
        pc = pal[np.where(self.patch_ids >= 0, self.patch_ids % len(PALETTE), len(PALETTE))]
        imgs = [preview.rasterize_mesh(self.positions, F, face_colors=pc, view=v, size=size) for v in views]
        preview.montage_png(ctx.path("preview_patches", "patches.png"), imgs, titles=list(views), height=size)
        sc = preview.colorize(self.seam_field[None, :])[0]
        imgs = [preview.rasterize_mesh(self.positions, F, face_colors=sc, view=v, size=size) for v in views]
        preview.montage_png(ctx.path("preview_seams", "seams.png"), imgs, titles=[f"seam cost {v}" for v in views],
                            height=size)
        tiles = _param_tiles(self.patch_domains, size)
        if tiles:
            preview.montage_png(ctx.path("preview_params", "params.png"), tiles,
                                titles=[f"patch {k}: source grey, target blue" for k in range(len(tiles))],
                                height=size)


def _face_colors(F: np.ndarray, vertex_rgb: np.ndarray) -> np.ndarray:
    return np.clip(vertex_rgb[F].mean(axis=1), 0, 1)


def _param_tiles(domains, size: int) -> list[np.ndarray]:
    """Fig. 4: for each (source, target) domain pair, the source domain (grey) under the target
    domain (blue), rendered flat."""
    tiles = []
    for S, T in domains:
        P = np.concatenate([S.reshape(-1, 2), T.reshape(-1, 2)])
        V = np.c_[P, np.r_[np.zeros(S.size // 2), np.full(T.size // 2, 1e-3)]]
        F = np.arange(len(V)).reshape(-1, 3)
        col = np.r_[np.tile([[0.8, 0.8, 0.8]], (len(S), 1)), np.tile([[0.25, 0.45, 0.9]], (len(T), 1))]
        tiles.append(preview.rasterize_mesh(V, F, face_colors=col, view="front", size=size))
    return tiles
