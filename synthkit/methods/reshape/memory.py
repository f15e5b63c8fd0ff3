"""Textured meshes given in memory: an :class:`~synthkit.io.assets.Asset` (or a trimesh, read as
one by :meth:`synthkit.io.inputs.Inputs.asset`) as the :class:`~synthkit.io.textured.TexturedMesh`
the pipeline works on, and back to an Asset once reshaped.

A file's textured mesh is written by re-reading its OBJ (:func:`~synthkit.io.textured.save_textured`);
a mesh given in memory has no file, so it carries its asset and its textures, and is written as
an OBJ by :func:`~synthkit.io.assets.save_asset` (:func:`reshaped_asset`).

Render vertices are the distinct (position, UV) pairs of the asset's face corners, as an OBJ's
distinct ``(v, vt)`` pairs are; ``positions`` are the asset's vertices, so a selection by
``index`` means the asset's (the trimesh's) vertex order.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from synthkit.io.assets import Asset, Material
from synthkit.io.inputs import image_from_array
from synthkit.io.textured import Retexture, TexturedMesh

__all__ = ["MemoryMesh", "textured_from_asset", "reshaped_asset"]


@dataclass
class MemoryMesh(TexturedMesh):
    """A :class:`~synthkit.io.textured.TexturedMesh` given in memory (``source`` is the config key
    it was given for, e.g. ``input``).

    Attributes
    ----------
    asset : the asset read (positions ``asset.V`` are ``positions``; faces ``asset.F`` are ``F``
        over positions, row for row)
    textures : material name -> ``(H, W, 3) float32`` texture in [0, 1] (materials with an image)
    """

    asset: Asset | None = None
    textures: dict[str, np.ndarray] = field(default_factory=dict)


def textured_from_asset(asset: Asset, key: str) -> MemoryMesh:
    """The textured mesh of ``asset`` given for config key ``key``: one render vertex per distinct
    (position, UV) corner, faces without a material on a material named ``""`` (as the OBJ reader
    puts them), textures converted as image files are."""
    n = len(asset.F)
    table = [asset.F.reshape(-1, 1).astype(np.float64)]
    if asset.corner_uv is not None:
        uv = np.asarray(asset.corner_uv, np.float64).reshape(-1, 2)
        has = np.isfinite(uv).all(axis=1)
        table += [has[:, None].astype(np.float64), np.where(has[:, None], uv, 0.0)]
    keys, inverse = np.unique(np.concatenate(table, axis=1), axis=0, return_inverse=True)
    position_index = keys[:, 0].astype(np.int64)
    UV = np.full((len(keys), 2), np.nan)
    if asset.corner_uv is not None:
        has = keys[:, 1] > 0
        UV[has] = keys[has, 2:4]
    names = [m.name for m in asset.materials]
    fm = np.asarray(asset.face_material, np.int64).copy()
    if (fm < 0).any():
        names.append("")
        fm[fm < 0] = len(names) - 1
    textures = {m.name: image_from_array(m.image, f"{key}: material {m.name}")
                for m in asset.materials if m.image is not None}
    V = np.asarray(asset.V, np.float64)
    return MemoryMesh(V=V[position_index], F=inverse.reshape(n, 3).astype(np.int64), UV=UV, face_material=fm,
                      materials=names, position_index=position_index, positions=V, source=Path(key),
                      asset=asset, textures=textures)


def reshaped_asset(mesh: TexturedMesh, positions: np.ndarray, entries: list[Retexture] = (),
                   asset: Asset | None = None) -> Asset:
    """``mesh``'s asset at the new ``positions (#P, 3)``; each :class:`Retexture` entry's faces get
    its UVs and a new material holding its baked image (8-bit, as it is written). ``asset`` is
    ``mesh``'s: by default ``mesh.asset`` (a :class:`MemoryMesh`), for a file the file read by
    :func:`~synthkit.io.assets.load_asset`, whose faces over positions must be ``mesh``'s row for row
    (ValueError otherwise)."""
    asset = mesh.asset if asset is None else asset
    if not np.array_equal(asset.F, mesh.position_index[mesh.F]):
        raise ValueError(f"{mesh.source}: the asset's faces are not the textured mesh's")
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
