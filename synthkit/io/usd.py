"""USD output: a triangle mesh with its texture coordinates, normals, colours and UsdPreviewSurface
materials, written with usd-core (the optional extra ``usd``: ``pip install 'synthkit[usd]'``).

A written stage (``upAxis`` Y and ``metersPerUnit`` 1: the inputs are glTF-like, Y up; one model
unit is written as one metre)::

    /<name>                    Xform, kind component, the stage's defaultPrim
        <name>                 Mesh: points, faceVertexCounts (all 3) / faceVertexIndices, extent,
                               normals (faceVarying), primvars:st (texCoord2f, faceVarying, indexed),
                               primvars:displayColor / displayOpacity (faceVarying, indexed)
            <material>         GeomSubset (familyName materialBind) of the faces of one material
        Looks                  Scope
            <material>         Material <- PreviewSurface (UsdPreviewSurface)
                                           <- DiffuseTexture (UsdUVTexture, file ``./<stem>_<image>.png``)
                                              <- STReader (UsdPrimvarReader_float2, varname ``st``)

One mesh with a GeomSubset per material, not one mesh per material (as a GLB needs): a position
on a border between materials stays one point, so the surface stays welded (the same open edges
as the input, no cracks under subdivision or displacement), a DCC shows one object with one
material slot per material, as it does for the OBJ, and the mesh's face count is the result's. A
mesh whose faces all have one material binds it on the mesh, without subsets.

Prim names are the mesh and material names made valid identifiers (``Tf.MakeValidIdentifier``,
made unique among siblings); a prim whose name differs from the original keeps that as its
``displayName``. Textures are PNG (or the source's own PNG/JPEG bytes) files written beside the
USD file and named relative to it (``./<file>``), so the folder can be moved whole. Colours are
stored as their 8-bit values / 255, not converted from sRGB (as OBJ and PLY give them). Only the
vertices faces use are written (no loose points).
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from synthkit.asset import Asset, Material
from synthkit.errors import ConfigError
from synthkit.io.atomic import replacing_atomically, write_bytes_atomic

__all__ = ["UsdMaterial", "write_usd", "load_usd", "usd_material", "usd_installed", "require_usd", "mesh_suffix",
           "USD_SUFFIXES", "USD_MISSING"]

USD_SUFFIXES = (".usdc", ".usda")
"""What :func:`write_usd` writes: ``.usdc`` binary (crate), ``.usda`` text."""

USD_MISSING = "USD output needs usd-core, which is not installed: pip install 'synthkit[usd]'"
"""The one line a run asking for USD without usd-core stops with."""

_FORMAT_SUFFIX = {"usd": ".usdc", "usda": ".usda"}
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


class UsdMaterial(NamedTuple):
    """One material of a USD file.

    Attributes
    ----------
    name : the material's name (its prim is named after it)
    color : (4,) float RGBA base colour in [0, 1] (multiplies the texture)
    image : (H, W, C) uint8 base-colour texture (C = 3 or 4; alpha drives opacity), or None
    image_file : (file name, bytes) of the file the texture was read from: a PNG or JPEG is written
        as these bytes under that name's stem, another format is written as ``image`` in PNG; or None
    metallic, roughness : the PBR factors in [0, 1]
    """

    name: str
    color: np.ndarray
    image: np.ndarray | None = None
    image_file: tuple[str, bytes] | None = None
    metallic: float = 0.0
    roughness: float = 1.0


def usd_installed() -> bool:
    """Whether usd-core (the ``pxr`` package) is installed; found without importing it."""
    return importlib.util.find_spec("pxr") is not None


def mesh_suffix(mesh_format: str) -> str:
    """The file suffix of a config's ``mesh_format`` (``usd`` -> ``.usdc``, ``obj`` -> ``.obj``)."""
    return _FORMAT_SUFFIX.get(mesh_format, f".{mesh_format}")


def require_usd() -> None:
    """ConfigError (:data:`USD_MISSING`) when usd-core is not installed. The public functions call
    it first; the helpers they call import ``pxr`` themselves."""
    if not usd_installed():
        raise ConfigError(USD_MISSING)


def _unique_identifier(name: str, taken: set[str]) -> str:
    """``name`` as a valid USD prim name not in ``taken`` (added to it)."""
    from pxr import Tf

    base = Tf.MakeValidIdentifier(name)
    out, k = base, 2
    while out in taken:
        out, k = f"{base}_{k}", k + 1
    taken.add(out)
    return out


def _define(stage, parent: str, kind: str, name: str, taken: set[str]):
    """A prim of type ``kind`` named after ``name`` under ``parent``, with ``name`` as its
    displayName when the identifier differs."""
    prim = stage.DefinePrim(f"{parent}/{_unique_identifier(name, taken)}", kind)
    if prim.GetName() != name:
        prim.SetDisplayName(name)
    return prim


def _indexed_primvar(primvars, name: str, type_name, values: np.ndarray, vt_array) -> None:
    """A faceVarying primvar ``name`` holding the distinct rows of ``values (#corners, k)`` (as a
    ``vt_array``; one column as scalars) and their indices."""
    from pxr import Vt

    table, index = np.unique(values, axis=0, return_inverse=True)
    primvar = primvars.CreatePrimvar(name, type_name, "faceVarying")
    primvar.Set(vt_array.FromNumpy(np.ascontiguousarray(table[:, 0] if table.shape[1] == 1 else table)))
    primvar.SetIndices(Vt.IntArray.FromNumpy(index.reshape(-1).astype(np.int32)))


def _write_mesh(stage, root: str, name: str, V, F, corner_uv, corner_normals, corner_color, taken: set[str]):
    """The Mesh prim of ``V (#V, 3)``, ``F (#F, 3)`` and its per-corner arrays (module docstring)."""
    from pxr import Sdf, UsdGeom, Vt

    used, F = np.unique(F.reshape(-1), return_inverse=True)
    points = np.ascontiguousarray(V[used], np.float32)
    mesh = UsdGeom.Mesh(_define(stage, root, "Mesh", name, taken))
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(F) // 3, 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(F.astype(np.int32)))
    mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(np.stack([points.min(axis=0), points.max(axis=0)])))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    primvars = UsdGeom.PrimvarsAPI(mesh)
    if corner_normals is not None:
        mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(corner_normals.reshape(-1, 3),
                                                                             np.float32)))
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    if corner_uv is not None:
        uv = np.nan_to_num(np.asarray(corner_uv, np.float64).reshape(-1, 2), nan=0.0).astype(np.float32)
        _indexed_primvar(primvars, "st", Sdf.ValueTypeNames.TexCoord2fArray, uv, Vt.Vec2fArray)
    if corner_color is not None:
        rgba = np.asarray(corner_color, np.float32).reshape(-1, 4) / 255.0
        _indexed_primvar(primvars, "displayColor", Sdf.ValueTypeNames.Color3fArray, rgba[:, :3], Vt.Vec3fArray)
        if (rgba[:, 3] < 1).any():
            _indexed_primvar(primvars, "displayOpacity", Sdf.ValueTypeNames.FloatArray, rgba[:, 3:], Vt.FloatArray)
    return mesh


def _texture_file(folder: Path, stem: str, mat: UsdMaterial, written: dict, taken: set[str]) -> str:
    """Write ``mat``'s texture beside the USD file once per distinct source (``written``: source
    key -> file name) and return its file name ``<stem>_<image>.<png|jpg>``."""
    from synthkit.io.images import save_image

    source = mat.image_file
    keep = source is not None and Path(source[0]).suffix.lower() in _IMAGE_SUFFIXES
    key = (source[0], source[1]) if keep else id(mat.image)
    if key in written:
        return written[key]
    base = Path(_SAFE.sub("_", Path(source[0]).name if source is not None else mat.name))
    ext = base.suffix.lower() if keep else ".png"
    name, k = f"{stem}_{base.stem}{ext}", 2
    while name in taken:
        name, k = f"{stem}_{base.stem}_{k}{ext}", k + 1
    taken.add(name)
    if keep:
        write_bytes_atomic(folder / name, source[1])
    else:
        save_image(folder / name, mat.image)
    written[key] = name
    return name


def _write_material(stage, looks: str, mat: UsdMaterial, texture: str | None, taken: set[str]):
    """The Material prim of ``mat`` (UsdPreviewSurface, fed by a UsdUVTexture of ``texture``, the
    file name beside the stage, when it has one)."""
    from pxr import Gf, Sdf, UsdShade

    material = UsdShade.Material(_define(stage, looks, "Material", mat.name, taken))
    path = material.GetPath()
    surface = UsdShade.Shader.Define(stage, path.AppendChild("PreviewSurface"))
    surface.CreateIdAttr("UsdPreviewSurface")
    color = np.asarray(mat.color, np.float64).reshape(-1)
    surface.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(float(mat.metallic))
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(mat.roughness))
    diffuse = surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    opacity = surface.CreateInput("opacity", Sdf.ValueTypeNames.Float)
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    if texture is None:
        diffuse.Set(Gf.Vec3f(*color[:3].tolist()))
        opacity.Set(float(color[3]))
        return material
    reader = UsdShade.Shader.Define(stage, path.AppendChild("STReader"))
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex = UsdShade.Shader.Define(stage, path.AppendChild("DiffuseTexture"))
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{texture}"))
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    for wrap in ("wrapS", "wrapT"):
        tex.CreateInput(wrap, Sdf.ValueTypeNames.Token).Set("repeat")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.CreateOutput("result", Sdf.ValueTypeNames.Float2))
    if not np.allclose(color, 1.0):
        tex.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(*color.tolist()))
    diffuse.ConnectToSource(tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3))
    if mat.image.ndim == 3 and mat.image.shape[2] == 4 and (mat.image[..., 3] < 255).any():
        opacity.ConnectToSource(tex.CreateOutput("a", Sdf.ValueTypeNames.Float))
    else:
        opacity.Set(float(color[3]))
    return material


def _bind(mesh, materials: list, face_material: np.ndarray) -> None:
    """Bind ``materials`` (Material prims by index, None where unused) to the faces of
    ``face_material (#F,)``: on the mesh when one material has every face, else one materialBind
    GeomSubset per material (a partition when every face has one)."""
    from pxr import UsdGeom, UsdShade, Vt

    used = np.unique(face_material[face_material >= 0])
    api = UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim())
    if len(used) == 1 and (face_material >= 0).all():
        api.Bind(materials[used[0]])
        return
    for index in used:
        faces = np.flatnonzero(face_material == index).astype(np.int32)
        subset = api.CreateMaterialBindSubset(materials[index].GetPrim().GetName(), Vt.IntArray.FromNumpy(faces))
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(materials[index])
    api.SetMaterialBindSubsetsFamilyType(UsdGeom.Tokens.partition if (face_material >= 0).all()
                                         else UsdGeom.Tokens.nonOverlapping)


def write_usd(path: Path | str, V, F, *, corner_uv=None, corner_normals=None, corner_color=None,
              face_material=None, materials: list[UsdMaterial] = (), name: str = "mesh") -> list[str]:
    """Write a ``.usdc`` (or ``.usda``) stage of ``V (#V, 3)``, ``F (#F, 3)`` with the materials'
    textures beside it, atomically (textures first; the stage through a temporary file in the same
    folder and a rename), laid out as the module docstring says.

    Parameters
    ----------
    corner_uv : (#F, 3, 2) float texture coordinates per face corner (NaN written as 0), or None
    corner_normals : (#F, 3, 3) float unit normals per face corner, or None
    corner_color : (#F, 3, 4) uint8 RGBA colours per face corner, or None
    face_material : (#F,) int64 index into ``materials`` (-1: none); None: all -1
    materials : the materials; only those faces use are written
    name : the mesh's name (the root and mesh prims are named after it)

    Returns the names of the files written, relative to ``path.parent``: the stage first, then the
    textures. Raises ValueError on arrays of the wrong shape or another suffix, ConfigError
    (:data:`USD_MISSING`) without usd-core.
    """
    path = Path(path)
    if path.suffix.lower() not in USD_SUFFIXES:
        raise ValueError(f"unsupported USD format {path.suffix!r} (use {', '.join(USD_SUFFIXES)})")
    V, F = np.asarray(V, np.float64), np.asarray(F, np.int64)
    face_material = np.full(len(F), -1, np.int64) if face_material is None else np.asarray(face_material, np.int64)
    _check_arrays(V, F, corner_uv, corner_normals, corner_color, face_material, len(materials))
    require_usd()
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = _define(stage, "", "Xform", name, set())
    Usd.ModelAPI(root).SetKind("component")
    stage.SetDefaultPrim(root)
    children: set[str] = set()
    mesh = _write_mesh(stage, str(root.GetPath()), name, V, F, corner_uv, corner_normals, corner_color, children)
    written, files, prims = [path.name], {}, [None] * len(materials)
    used = np.unique(face_material[face_material >= 0])
    if len(used):
        looks = str(_define(stage, str(root.GetPath()), "Scope", "Looks", children).GetPath())
        names: set[str] = set()
        taken = {path.name}
        for index in used:
            mat = materials[index]
            texture = None
            if mat.image is not None and corner_uv is not None:
                texture = _texture_file(path.parent, path.stem, mat, files, taken)
            prims[index] = _write_material(stage, looks, mat, texture, names)
        _bind(mesh, prims, face_material)
        written += sorted(set(files.values()))
    with replacing_atomically(path) as tmp:
        if not stage.GetRootLayer().Export(str(tmp)):
            raise OSError(f"{path}: usd-core could not write the stage")
    return written


def _check_arrays(V, F, corner_uv, corner_normals, corner_color, face_material, n_materials: int) -> None:
    """ValueError naming the first array of :func:`write_usd` of the wrong shape or range."""
    m = len(F)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or m == 0:
        raise ValueError(f"V must be (n, 3) and F (m, 3) with m > 0, got {V.shape} and {F.shape}")
    if F.min() < 0 or F.max() >= len(V):
        raise ValueError(f"F indexes {len(V)} vertices")
    for key, value, shape in (("corner_uv", corner_uv, (m, 3, 2)), ("corner_normals", corner_normals, (m, 3, 3)),
                              ("corner_color", corner_color, (m, 3, 4)), ("face_material", face_material, (m,))):
        if value is not None and np.shape(value) != shape:
            raise ValueError(f"{key} must have shape {shape}, got {np.shape(value)}")
    if face_material.max() >= n_materials or face_material.min() < -1:
        raise ValueError(f"face_material indexes {n_materials} materials")


def usd_material(mat) -> UsdMaterial:
    """The :class:`UsdMaterial` of an asset's :class:`~synthkit.asset.Material` (its PBR
    factors from a GLB's material; its texture file's bytes from an OBJ's). Read by attribute:
    this module does not import :mod:`synthkit.io.assets`, so that one can call :func:`write_usd`."""
    pbr = mat.pbr
    metallic = getattr(pbr, "metallicFactor", None)
    roughness = getattr(pbr, "roughnessFactor", None)
    source = None
    if mat.image is not None and mat.image_path is not None and mat.image_path.is_file():
        source = (mat.image_path.name, mat.image_path.read_bytes())
    return UsdMaterial(mat.name, np.asarray(mat.color, np.float64), mat.image, source,
                       0.0 if metallic is None else float(metallic), 1.0 if roughness is None else float(roughness))


def load_usd(path: Path | str) -> Asset:
    """Read back a stage :func:`~synthkit.io.usd.write_usd` wrote as an :class:`~synthkit.asset.Asset`: the
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
    from synthkit.io.images import load_image

    file = folder / texture.GetInput("file").Get().path
    image = load_image(file, mode="any")
    image = np.round(np.clip(image, 0, 1) * 255).astype(np.uint8) if image.dtype != np.uint8 else image
    return Material(name, color=color, image=image, image_path=file)
