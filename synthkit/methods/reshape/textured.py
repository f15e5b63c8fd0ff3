"""The textured meshes reshape works on: an :class:`~synthkit.asset.Asset` (read from a file or
given in memory) seen as its render vertices (:class:`TexturedMesh`), and back to an Asset once
reshaped (:func:`reshaped_asset`), which :func:`~synthkit.io.assets.save_asset` writes.

Render vertices are the distinct (position, UV) pairs of the asset's face corners, as an OBJ's
distinct ``(v, vt)`` pairs are; ``positions`` are the asset's vertices (an OBJ's ``v`` lines), so
a selection by ``index`` means the file's (the trimesh's) vertex order.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from synthkit.asset import Asset, Material, render_vertices

__all__ = ["TexturedMesh", "Retexture", "textured_from_asset", "reshaped_asset", "material_textures"]


@dataclass
class TexturedMesh:
    """A textured indexed face set over an asset's render vertices.

    Attributes
    ----------
    V : (#V, 3) float64 render-vertex positions
    F : (#F, 3) int64 triangles over render vertices, row for row ``asset.F``
    UV : (#V, 2) float64 texture coordinates (NaN where the corner has none)
    face_material : (#F,) int64 index into ``materials``
    materials : material names (faces without a material on one named ``""``)
    position_index : (#V,) int64 the asset vertex (file position) of each render vertex
    positions : (#P, 3) float64 the asset's vertices
    source : the file read, or the config key a mesh given in memory was given for
    asset : the asset read (``asset.V`` are ``positions``)
    in_memory : whether the mesh was given in memory (written as an OBJ, not in a file's format)
    textures : material name -> ``(H, W, 3) float32`` texture in [0, 1] of a mesh given in memory
    """

    V: np.ndarray
    F: np.ndarray
    UV: np.ndarray
    face_material: np.ndarray
    materials: list[str]
    position_index: np.ndarray
    positions: np.ndarray
    source: Path
    asset: Asset
    in_memory: bool = False
    textures: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class Retexture:
    """A reshaped surface: its triangles ``faces (k,) int64``, the new texture coordinates
    ``UV (#V, 2)`` of the render vertices they use (other rows are ignored), the new material's
    name and its baked texture ``image (H, W, 3)``; ``image_name`` is ``<material>.png``, written
    as ``<piece>_<image_name>`` beside the piece."""

    faces: np.ndarray
    UV: np.ndarray
    material: str
    image_name: str
    image: np.ndarray


def textured_from_asset(asset: Asset, key: str | None = None,
                        textures: dict[str, np.ndarray] | None = None) -> TexturedMesh:
    """The textured mesh of ``asset``: given in memory for config key ``key`` with its material
    name -> ``textures (H, W, 3)`` float32 in [0, 1] (converted by the pipeline as image files are),
    else read from ``asset.source``."""
    r = render_vertices(asset.V, asset.F, asset.corner_uv)
    names = [m.name for m in asset.materials]
    fm = np.asarray(asset.face_material, np.int64).copy()
    if (fm < 0).any():
        names.append("")
        fm[fm < 0] = len(names) - 1
    return TexturedMesh(V=r.V, F=r.F, UV=r.UV, face_material=fm, materials=names, position_index=r.position_index,
                        positions=np.asarray(asset.V, np.float64), source=Path(key) if key else asset.source,
                        asset=asset, in_memory=key is not None, textures=dict(textures or {}))


def material_textures(mesh: TexturedMesh) -> dict[str, Path]:
    """Material name -> the ``map_Kd`` image file its MTL names (whether or not it exists), for a
    mesh read from an OBJ; materials without one are left out."""
    return {m.name: path for m in mesh.asset.materials for head, path in m.maps
            if head.split()[0].lower() == "map_kd"}


def reshaped_asset(mesh: TexturedMesh, positions: np.ndarray, entries: list[Retexture] = ()) -> Asset:
    """``mesh``'s asset at the new ``positions (#P, 3)``; each :class:`Retexture` entry's faces get
    its UVs and a new material holding its baked image (8-bit, as it is written)."""
    asset = mesh.asset
    corner_uv = asset.corner_uv
    fm = np.asarray(asset.face_material, np.int64)
    materials = list(asset.materials)
    if entries:
        corner_uv = np.full((len(asset.F), 3, 2), np.nan) if corner_uv is None else corner_uv.copy()
        fm = fm.copy()
        for entry in entries:
            corner_uv[entry.faces] = entry.UV[mesh.F[entry.faces]]
            fm[entry.faces] = len(materials)
            image = np.round(np.clip(np.asarray(entry.image, np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)
            materials.append(Material(entry.material, image=image))
    return replace(asset, V=np.asarray(positions, np.float64).copy(), corner_uv=corner_uv, face_material=fm,
                   materials=materials)
