"""Assets as USD: :func:`save_asset_usd` writes an :class:`~synthkit.io.assets.Asset`'s arrays as
:func:`~synthkit.io.assets.save_asset` takes them, :func:`load_usd` reads back a stage
:func:`~synthkit.io.usd.write_usd` wrote. Kept apart from :mod:`synthkit.io.usd`, the writer, which
imports nothing of :mod:`synthkit.io.assets`, so that ``save_asset`` can call it without an import
cycle."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from synthkit.io.assets import Asset, Material, corner_normals
from synthkit.io.images import load_image
from synthkit.io.usd import require_usd, usd_material, write_usd

__all__ = ["save_asset_usd", "load_usd"]


def save_asset_usd(path: Path | str, V, F, *, like: Asset, corner_uv=None, face_material=None,
                   corner_color=None) -> list[str]:
    """:func:`~synthkit.io.assets.save_asset` for a ``.usdc`` / ``.usda`` path: ``V (#V, 3)``,
    ``F (#F, 3)`` with ``corner_uv (#F, 3, 2)``, ``corner_color (#F, 3, 4) uint8`` and
    ``face_material (#F,)`` (indices into ``like.materials``; default: the first material, as
    save_asset), named after ``like``, with per-corner normals that keep hard edges
    (:func:`~synthkit.io.assets.corner_normals`). Returns the file names written (the stage first)."""
    V, F = np.asarray(V, np.float64), np.asarray(F, np.int64)
    if face_material is None:
        face_material = np.full(len(F), 0 if like.materials else -1, np.int64)
    normals = corner_normals(V, F) if F.ndim == 2 and len(F) else None
    return write_usd(path, V, F, corner_uv=corner_uv, corner_normals=normals, corner_color=corner_color,
                     face_material=face_material, materials=[usd_material(m) for m in like.materials],
                     name=like.name)


def load_usd(path: Path | str) -> Asset:
    """Read back a stage :func:`~synthkit.io.usd.write_usd` wrote as an :class:`~synthkit.io.assets.Asset`: the
    defaultPrim's first Mesh (triangles), its ``st`` and ``displayColor`` per corner, its materials
    (in prim order) with their base colour and texture image. Raises ValueError on a stage of
    another layout."""
    require_usd()
    from pxr import Usd, UsdGeom, UsdShade

    path = Path(path)
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    meshes = [p for p in Usd.PrimRange(root) if p.IsA(UsdGeom.Mesh)] if root else []
    if not meshes:
        raise ValueError(f"{path}: no mesh under the default prim")
    mesh = UsdGeom.Mesh(meshes[0])
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    if (counts != 3).any():
        raise ValueError(f"{path}: the mesh is not all triangles")
    F = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), np.int64).reshape(-1, 3)
    primvars = UsdGeom.PrimvarsAPI(mesh)
    st, color = primvars.GetPrimvar("st"), primvars.GetPrimvar("displayColor")
    corner_uv = np.asarray(st.ComputeFlattened(), np.float64).reshape(-1, 3, 2) if st.HasValue() else None
    corner_color = None
    if color.HasValue():
        rgb = np.round(np.asarray(color.ComputeFlattened(), np.float64) * 255).reshape(-1, 3, 3)
        opacity = primvars.GetPrimvar("displayOpacity")
        alpha = np.round(np.asarray(opacity.ComputeFlattened(), np.float64) * 255).reshape(-1, 3, 1) \
            if opacity.HasValue() else np.full((len(F), 3, 1), 255.0)
        corner_color = np.concatenate([rgb, alpha], axis=2).astype(np.uint8)
    materials, face_material = [], np.full(len(F), -1, np.int64)
    binding = UsdShade.MaterialBindingAPI(mesh.GetPrim())
    subsets = binding.GetMaterialBindSubsets()
    bound = [(s.GetPrim(), np.asarray(s.GetIndicesAttr().Get(), np.int64)) for s in subsets] or \
        [(mesh.GetPrim(), np.arange(len(F)))]
    for prim, faces in bound:
        material = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        if not material:
            continue
        face_material[faces] = len(materials)
        materials.append(_read_material(material, path.parent))
    return Asset(V=np.asarray(mesh.GetPointsAttr().Get(), np.float64), F=F, corner_uv=corner_uv,
                 corner_color=corner_color, face_material=face_material, materials=materials,
                 name=root.GetDisplayName() or root.GetName(), source=path)


def _read_material(material, folder: Path) -> Material:
    """An asset Material from a Material prim :func:`write_usd` wrote (its UsdPreviewSurface's
    diffuse colour or its UsdUVTexture's image and scale)."""
    prim = material.GetPrim()
    surface = material.ComputeSurfaceSource()[0]
    diffuse = surface.GetInput("diffuseColor")
    color = np.ones(4)
    name = prim.GetDisplayName() or prim.GetName()
    if not diffuse.HasConnectedSource():
        color[:3] = diffuse.Get()
        color[3] = surface.GetInput("opacity").Get()
        return Material(name, color=color)
    texture = diffuse.GetConnectedSource()[0]
    scale = texture.GetInput("scale")
    if scale and scale.Get() is not None:
        color = np.asarray(scale.Get(), np.float64)
    file = folder / texture.GetInput("file").Get().path
    image = load_image(file, mode="any")
    image = np.round(np.clip(image, 0, 1) * 255).astype(np.uint8) if image.dtype != np.uint8 else image
    return Material(name, color=color, image=image, image_path=file)
