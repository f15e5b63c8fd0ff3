"""The textured-mesh model every method works on: an :class:`Asset` and its :class:`Material` s.

An asset is a triangle mesh whose face corners carry texture coordinates and colours, whose
faces carry a material, and whose materials carry their base colour and texture images. Methods
move, cut and copy the geometry and carry the per-corner arrays along (UV seams stay seams);
writers (:mod:`synthkit.io.assets`) turn corners back into the file's vertices. What a file says
beyond the geometry (an OBJ's polygons, objects and groups, a glTF's scene, node and mesh names
and its material, texture, sampler and image objects) rides along so that an output opens in a
DCC as its input did.

:func:`render_vertices` gives the indexed face set a renderer sees: one vertex per distinct
(position, texture coordinate) pair of the corners.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Asset", "Material", "GltfInfo", "RenderVertices", "render_vertices"]


@dataclass
class Material:
    """One material of an asset.

    Attributes
    ----------
    name : the material's name as the file gives it
    color : (4,) float64 RGBA base colour in [0, 1] (MTL ``Kd``/``d``, glTF ``baseColorFactor``)
    image : (H, W, C) uint8 base-colour texture (C = 3 or 4), or None
    image_path : the file the base-colour texture was read from (OBJ), or None (embedded, or none)
    mtl_lines : the MTL block's statements other than ``newmtl`` and texture maps (OBJ input)
    maps : the MTL block's texture-map statements: ``(statement without the file name, file)``,
        the file resolved (``map_Kd`` included, whether or not the file exists)
    gltf_index : the material's index among ``Asset.gltf.materials`` (glTF input), or None
    pbr : the trimesh material object of a glTF or of a mesh given in memory (its PBR factors), or None
    """

    name: str
    color: np.ndarray = field(default_factory=lambda: np.ones(4))
    image: np.ndarray | None = None
    image_path: Path | None = None
    mtl_lines: list[str] = field(default_factory=list)
    maps: list[tuple[str, Path]] = field(default_factory=list)
    gltf_index: int | None = None
    pbr: object | None = None


@dataclass
class GltfInfo:
    """What a glTF file says beyond the geometry, kept for a glTF written from it.

    Attributes
    ----------
    scene, node, mesh : names of the default scene, of its mesh node and of that node's mesh (None
        where unnamed, or where the scene has several mesh nodes: ``node`` then is None)
    materials, textures, samplers : the file's JSON objects, as read
    images : ``(JSON object without uri/bufferView, the image file's bytes)`` per image
    tangents : whether some primitive has a ``TANGENT`` attribute
    extensions_used : the file's ``extensionsUsed``
    """

    scene: str | None = None
    node: str | None = None
    mesh: str | None = None
    materials: list[dict] = field(default_factory=list)
    textures: list[dict] = field(default_factory=list)
    samplers: list[dict] = field(default_factory=list)
    images: list[tuple[dict, bytes]] = field(default_factory=list)
    tangents: bool = False
    extensions_used: list[str] = field(default_factory=list)


@dataclass
class Asset:
    """A triangle mesh with its appearance.

    Attributes
    ----------
    V : (#V, 3) float64 positions (a UV or colour seam may repeat a position)
    F : (#F, 3) int64 triangles
    corner_uv : (#F, 3, 2) float64 texture coordinates per face corner (NaN: none), or None
    corner_color : (#F, 3, 4) uint8 RGBA colours per face corner, or None
    face_material : (#F,) int64 index into ``materials`` (-1: none)
    materials : the materials, in file order
    name : the mesh's name (glTF node / OBJ ``o``, else the file stem)
    source : the file read
    face_polygon : (#F,) int64 the file polygon each triangle was cut from (triangles of one polygon
        consecutive, fanned from its first corner), or None (triangles)
    face_group : (#F,) int64 index into ``groups``, or None
    groups : ``(object name or None, group name or None)`` of an OBJ's ``o``/``g`` statements
    gltf : what a glTF input says beyond the geometry, or None
    """

    V: np.ndarray
    F: np.ndarray
    corner_uv: np.ndarray | None
    corner_color: np.ndarray | None
    face_material: np.ndarray
    materials: list[Material]
    name: str
    source: Path
    face_polygon: np.ndarray | None = None
    face_group: np.ndarray | None = None
    groups: list = field(default_factory=list)
    gltf: GltfInfo | None = None

    @property
    def textured(self) -> bool:
        """Whether some face has UVs and a material with a texture image."""
        return self.corner_uv is not None and any(m.image is not None for m in self.materials)


@dataclass
class RenderVertices:
    """The render vertices of an asset's corners.

    Attributes
    ----------
    V : (#R, 3) float64 render-vertex positions
    F : (#F, 3) int64 triangles over render vertices, row for row the asset's
    UV : (#R, 2) float64 texture coordinates (NaN where the corner has none)
    position_index : (#R,) int64 the asset vertex of each render vertex
    """

    V: np.ndarray
    F: np.ndarray
    UV: np.ndarray
    position_index: np.ndarray


def render_vertices(V: np.ndarray, F: np.ndarray, corner_uv: np.ndarray | None) -> RenderVertices:
    """One render vertex per distinct (vertex of ``F (#F, 3)``, ``corner_uv (#F, 3, 2)``) pair, in
    the order of that pair (vertex first); NaN texture coordinates are one value."""
    n = len(F)
    table = [np.asarray(F, np.float64).reshape(-1, 1)]
    if corner_uv is not None:
        uv = np.asarray(corner_uv, np.float64).reshape(-1, 2)
        has = np.isfinite(uv).all(axis=1)
        table += [has[:, None].astype(np.float64), np.where(has[:, None], uv, 0.0)]
    keys, inverse = np.unique(np.concatenate(table, axis=1), axis=0, return_inverse=True)
    position_index = keys[:, 0].astype(np.int64)
    UV = np.full((len(keys), 2), np.nan)
    if corner_uv is not None:
        has = keys[:, 1] > 0
        UV[has] = keys[has, 2:4]
    return RenderVertices(V=np.asarray(V, np.float64)[position_index], F=inverse.reshape(n, 3).astype(np.int64),
                          UV=UV, position_index=position_index)
