"""Meshes with their appearance: read any mesh file as an :class:`~synthkit.asset.Asset`, write a
new mesh that looks like it.

Formats (:func:`load_asset`, :func:`save_asset`):

- **OBJ + MTL** (:mod:`synthkit.io.obj`): positions with optional colours, texture coordinates,
  polygons (fanned into triangles, written back as the same polygons while their triangles stay
  together), objects and groups, materials. ``mtllib`` and map names are resolved the way DCC
  tools do: relative to the OBJ (MTL) folder, in sibling or parent folders
  (``../textures/a.png``), or absolute; backslashes are read as folder separators. A missing MTL
  or texture is one warning line naming the file; the mesh is read without it (its faces keep
  their material name, with no texture). A file named as a texture that is not an image is an
  :class:`InputError`. ``vt`` lines without any material give one warning: UVs are kept, no
  material is invented. Written OBJs get a new MTL beside them (``<stem>.mtl``) holding each
  used material's statements as read, with every texture map rewritten to a copy of its image
  placed *inside* the output folder under a safe name (``<stem>_<image>``), and per-corner
  normals (averaged over faces within :data:`CREASE_DEG` of each other, so hard edges stay hard).
- **GLB / glTF** (:mod:`synthkit.io.gltf`): every geometry of the scene in world coordinates,
  its UVs and material or vertex colours; written GLBs keep the input's scene, node, mesh,
  material, texture, sampler and image objects and names, with normals (and tangents where the
  input had them).
- **USD** (``.usdc``, ``.usda``; :mod:`synthkit.io.usd`, the ``usd`` extra): written with
  UsdPreviewSurface materials and the textures beside the stage.
- **PLY**: vertex (or face) colours as corner colours; written PLYs keep colours.
- **OFF, STL**: geometry only (written without appearance; a warning says what was not kept).

Every writer writes only the vertices some face uses.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import trimesh

from synthkit.asset import Asset, Material
from synthkit.errors import InputError
from synthkit.io import obj as objfile
from synthkit.io._capture import check_readable
from synthkit.io.atomic import write_bytes_atomic, write_text_atomic
from synthkit.io.gltf import glb_bytes, read_gltf_info
from synthkit.io.meshes import check_mesh, trimesh_load
from synthkit.io.usd import USD_SUFFIXES, usd_material, write_usd

log = logging.getLogger(__name__)

__all__ = ["load_asset", "asset_from_trimesh", "save_asset", "corner_normals", "corner_tangents", "CREASE_DEG",
           "ASSET_SUFFIXES"]

ASSET_SUFFIXES = (".obj", ".glb", ".gltf", ".ply", ".off", ".stl")
WRITE_SUFFIXES = (".obj", ".glb", ".ply", ".off", ".stl", *USD_SUFFIXES)
CREASE_DEG = 30.0
"""Faces meeting at a vertex share its normal in a written mesh when their normals differ by less."""

_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


def load_asset(path: Path | str) -> Asset:
    """Read a mesh file with its appearance (see the module docstring for the formats).

    Raises InputError naming the file when it is missing, unreadable, corrupt (an OBJ: with the
    line), has no faces or non-finite positions, or names a texture that is not an image.
    """
    path = Path(path)
    check_readable(path, "mesh")
    suffix = path.suffix.lower()
    if suffix not in ASSET_SUFFIXES:
        raise InputError(f"{path}: unsupported mesh format {suffix!r} (use {', '.join(ASSET_SUFFIXES)})")
    asset = _read_obj(path) if suffix == ".obj" else _read_trimesh(path)
    check_mesh(asset.V, asset.F, source=path)
    return asset


# ---------------------------------------------------------------- OBJ reading


def _read_obj(path: Path) -> Asset:
    d = objfile.read_obj(path)
    F = d.corners[..., 0]
    corner_uv = None
    if (d.corners[..., 1] >= 0).any():
        corner_uv = np.where((d.corners[..., 1] >= 0)[..., None], d.uvs[np.maximum(d.corners[..., 1], 0)], np.nan)
    corner_color = None
    if d.colors is not None:
        rgb = np.clip(d.colors, 0, 1)
        corner_color = np.concatenate([np.round(rgb * 255), np.full((len(rgb), 1), 255.0)], axis=1)[F].astype(np.uint8)
    materials = _obj_materials(path, d.mtllibs, d.material_names)
    if corner_uv is not None and not d.material_names:
        log.warning("%s: has texture coordinates but no material; UVs kept, no texture applied", path)
    named = [obj for obj, _ in d.groups if obj is not None]
    return Asset(V=d.positions, F=F, corner_uv=corner_uv, corner_color=corner_color, face_material=d.face_material,
                 materials=materials, name=named[0] if named else path.stem, source=path,
                 face_polygon=d.face_polygon, face_group=d.face_group, groups=d.groups)


def _obj_materials(obj: Path, mtllibs: list[str], names: list[str]) -> list[Material]:
    """The materials ``names`` (in ``usemtl`` order) from the MTL files ``mtllibs`` names."""
    blocks: dict[str, tuple[Path, list[str]]] = {}
    for mtl in objfile.mtl_files(mtllibs, obj.parent):
        if not mtl.is_file():
            log.warning("%s: material file %s named by the mesh is missing; loading without its materials",
                        obj, mtl.name)
            continue
        for name, lines in objfile.read_mtl(mtl).items():
            blocks.setdefault(name, (mtl, lines))
    return [_mtl_material(name, *blocks[name]) if name in blocks else Material(name=name) for name in names]


def _mtl_material(name: str, mtl: Path, lines: list[str]) -> Material:
    """A material from its MTL block ``lines`` (base-colour texture read from ``map_Kd``)."""
    mat = Material(name=name)
    for line in lines:
        parts = line.split()
        key = parts[0].lower()
        if key == "kd" and len(parts) >= 4:
            mat.color[:3] = np.clip([float(x) for x in parts[1:4]], 0, 1)
        elif key == "d" and len(parts) >= 2:
            mat.color[3] = float(np.clip(float(parts[1]), 0, 1))
        if not key.startswith(objfile.MAP_KEYS):
            mat.mtl_lines.append(line)
            continue
        written = objfile.map_file_name(line)
        if not written:
            continue
        image = objfile.resolve_named_file(written, mtl.parent)
        mat.maps.append((line[: len(line) - len(written)].rstrip(), image))
        if not image.is_file():
            log.warning("%s: texture file %s of material %s is missing; loading without texture", mtl, written, name)
        elif key == "map_kd":
            _read_base_color(mat, image, mtl, written)
    return mat


def _read_base_color(mat: Material, image: Path, mtl: Path, written: str) -> None:
    import cv2

    from synthkit.io.images import load_image

    if not cv2.haveImageReader(str(image)):
        raise InputError(f"{mtl}: texture {written} is not an image file")
    mat.image = _as_uint8_rgb(load_image(image, mode="any"))
    mat.image_path = image


def _as_uint8_rgb(img: np.ndarray) -> np.ndarray:
    """An image ``(H, W[, C])`` float in [0, 1] as ``(H, W, 3|4) uint8``."""
    img = np.asarray(img)
    if img.ndim == 2:
        img = img[..., None]
    if img.shape[2] in (1, 2):
        img = np.concatenate([np.repeat(img[..., :1], 3, axis=2), img[..., 1:]], axis=2)
    if img.dtype != np.uint8:
        img = np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)
    return np.ascontiguousarray(img)


# ---------------------------------------------------------------- other formats (through trimesh)


def _read_trimesh(path: Path) -> Asset:
    loaded = trimesh_load(path)
    if isinstance(loaded, trimesh.Scene):
        names = list(loaded.graph.nodes_geometry)
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        name = names[0] if len(names) == 1 else path.stem
    elif isinstance(loaded, trimesh.Trimesh):
        geoms, name = [loaded], path.stem
    else:
        raise InputError(f"{path}: file holds no triangle mesh")
    if not geoms:
        raise InputError(f"{path}: mesh has no faces")
    asset = _assemble(path, geoms, name)
    if path.suffix.lower() in (".glb", ".gltf"):
        asset.gltf = read_gltf_info(path)
        asset.name = asset.gltf.node or asset.name
        _link_gltf_materials(asset)
    return asset


def _link_gltf_materials(asset: Asset) -> None:
    """Give each material the index of the glTF material of its name, where that name is one
    material's only (a material without one is written from its colour and texture)."""
    names = [m.get("name") for m in asset.gltf.materials]
    for mat in asset.materials:
        if mat.name is not None and names.count(mat.name) == 1:
            mat.gltf_index = names.index(mat.name)
    if len(asset.materials) == 1 and len(names) == 1:
        asset.materials[0].gltf_index = 0


def _geometry_appearance(g: trimesh.Trimesh):
    """(uv (#v, 2) or None, colours (#v, 4) uint8 or None, material object or None) of a geometry."""
    visual = g.visual
    uv = getattr(visual, "uv", None)
    material = getattr(visual, "material", None)
    colors = None
    if getattr(visual, "kind", None) == "vertex":
        colors = np.asarray(visual.vertex_colors, np.uint8)
    elif getattr(visual, "kind", None) == "face":
        colors = np.asarray(visual.vertex_colors, np.uint8)  # trimesh spreads face colours to vertices
    uv = None if uv is None or len(uv) != len(g.vertices) else np.asarray(uv, np.float64)
    return uv, colors, material


def _trimesh_material(obj) -> Material:
    """A :class:`Material` from a trimesh PBR or simple material (texture and colour read out)."""
    name = getattr(obj, "name", None) or "material"
    image = getattr(obj, "baseColorTexture", None)
    if image is None:
        image = getattr(obj, "image", None)
    color = getattr(obj, "baseColorFactor", None)
    if color is None:
        color = getattr(obj, "diffuse", None)
    color = np.ones(4) if color is None else np.asarray(color, np.float64).reshape(-1)[:4] / (
        255.0 if np.asarray(color).dtype == np.uint8 else 1.0)
    if len(color) == 3:
        color = np.append(color, 1.0)
    return Material(name=name, color=color, image=None if image is None else _as_uint8_rgb(np.asarray(image)),
                    pbr=obj)


def asset_from_trimesh(mesh: trimesh.Trimesh | trimesh.Scene, name: str = "mesh") -> Asset:
    """An :class:`Asset` from a mesh or scene in memory: its UVs, vertex colours, materials and
    textures read out as :func:`load_asset` reads them from a file (``source`` is ``Path(name)``).

    Raises
    ------
    ValueError : the scene holds no triangle mesh with faces.
    """
    if isinstance(mesh, trimesh.Scene):
        names = list(mesh.graph.nodes_geometry)
        geoms = [g for g in mesh.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        name = names[0] if len(names) == 1 else name
    else:
        geoms = [mesh] if len(mesh.faces) else []
    if not geoms:
        raise ValueError(f"{name}: mesh has no faces")
    return _assemble(Path(name), geoms, name)


def _assemble(path: Path, geoms: list, name: str) -> Asset:
    Vs, Fs, uvs, cols, fms, materials, objs = [], [], [], [], [], [], []
    base = 0
    for g in geoms:
        F = np.asarray(g.faces, np.int64)
        uv, colors, obj = _geometry_appearance(g)
        Vs.append(np.asarray(g.vertices, np.float64))
        Fs.append(F + base)
        uvs.append(None if uv is None else uv[F])
        cols.append(None if colors is None else colors[F])
        index = -1
        if obj is not None:
            if not any(obj is o for o in objs):
                objs.append(obj)
                materials.append(_trimesh_material(obj))
            index = next(i for i, o in enumerate(objs) if o is obj)
        fms.append(np.full(len(F), index, np.int64))
        base += len(g.vertices)
    corner_uv = None
    if any(u is not None for u in uvs):
        corner_uv = np.concatenate([u if u is not None else np.full((len(f), 3, 2), np.nan)
                                    for u, f in zip(uvs, Fs, strict=True)])
    corner_color = None
    if any(c is not None for c in cols):
        corner_color = np.concatenate([c if c is not None else np.full((len(f), 3, 4), 255, np.uint8)
                                       for c, f in zip(cols, Fs, strict=True)])
    return Asset(V=np.vstack(Vs), F=np.vstack(Fs), corner_uv=corner_uv, corner_color=corner_color,
                 face_material=np.concatenate(fms), materials=materials, name=name, source=path)



# ---------------------------------------------------------------- writing


def _check_shapes(V, F, corner_uv, face_material, corner_color, like: Asset):
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"V must be (n, 3) and F (m, 3), got {V.shape} and {F.shape}")
    m = len(F)
    if corner_uv is not None and np.shape(corner_uv) != (m, 3, 2):
        raise ValueError(f"corner_uv must have shape ({m}, 3, 2), got {np.shape(corner_uv)}")
    if corner_color is not None and np.shape(corner_color) != (m, 3, 4):
        raise ValueError(f"corner_color must have shape ({m}, 3, 4), got {np.shape(corner_color)}")
    if face_material is None:
        face_material = np.full(m, 0 if like.materials else -1, np.int64)
    face_material = np.asarray(face_material, np.int64).reshape(-1)
    if face_material.shape != (m,):
        raise ValueError(f"face_material must have shape ({m},), got {face_material.shape}")
    if m and (face_material.max() >= len(like.materials) or face_material.min() < -1):
        raise ValueError(f"face_material indexes {len(like.materials)} materials")
    return V, F, corner_uv, face_material, corner_color


def _used_vertices(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(V', F', used)``: only the vertices ``F`` names (in their order), ``used`` their indices in ``V``."""
    used, inverse = np.unique(F, return_inverse=True)
    return V[used], inverse.reshape(F.shape).astype(np.int64), used


def save_asset(path: Path | str, V, F, *, like: Asset, corner_uv=None, face_material=None,
               corner_color=None, face_polygon=None, face_group=None) -> list[str]:
    """Write ``V (#V, 3)``, ``F (#F, 3)`` with the appearance of ``like`` to ``path``, atomically.

    ``corner_uv (#F, 3, 2)``, ``corner_color (#F, 3, 4) uint8`` and ``face_material (#F,)``
    (indices into ``like.materials``; default: the first material) describe the new faces;
    ``face_polygon (#F,)`` and ``face_group (#F,)`` (indices into ``like.groups``) the OBJ
    polygons and groups they belong to (None: triangles, one group named ``like.name``). Only the
    vertices the faces use are written. The format follows ``path``'s suffix (module docstring).
    Returns the names of the files written, relative to ``path.parent`` (the mesh first, then its
    MTL and textures). Raises ValueError on arrays of the wrong shape or an unsupported suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_SUFFIXES:
        raise ValueError(f"unsupported mesh format {suffix!r} (use {', '.join(WRITE_SUFFIXES)})")
    V, F, corner_uv, face_material, corner_color = _check_shapes(V, F, corner_uv, face_material, corner_color, like)
    for key, value in (("face_polygon", face_polygon), ("face_group", face_group)):
        if value is not None and np.shape(value) != (len(F),):
            raise ValueError(f"{key} must have shape ({len(F)},), got {np.shape(value)}")
    if face_group is not None and len(F) and not 0 <= np.min(face_group) <= np.max(face_group) < len(like.groups):
        raise ValueError(f"face_group indexes {len(like.groups)} groups")
    V, F, _ = _used_vertices(V, F)
    if suffix == ".obj":
        return _write_obj(path, V, F, corner_uv, face_material, corner_color, like, face_polygon, face_group)
    if suffix in USD_SUFFIXES:
        return write_usd(path, V, F, corner_uv=corner_uv, corner_normals=corner_normals(V, F),
                         corner_color=corner_color, face_material=face_material,
                         materials=[usd_material(m) for m in like.materials], name=like.name)
    if suffix == ".glb":
        normals = corner_normals(V, F)
        tangents = corner_tangents(V, F, corner_uv, normals) if like.gltf and like.gltf.tangents else None
        write_bytes_atomic(path, glb_bytes(V, F, corner_uv, face_material, corner_color, like, normals, tangents))
        return [path.name]
    if suffix == ".ply" and corner_color is not None:
        Vr, Fr, keys = _render_vertices(V, F, None, corner_color)
        mesh = trimesh.Trimesh(Vr, Fr, vertex_colors=keys["color"], process=False)
    else:
        mesh = trimesh.Trimesh(V, F, process=False)
    if corner_uv is not None or (suffix != ".ply" and corner_color is not None):
        log.warning("%s: %s keeps no texture coordinates or materials; written as geometry%s", path,
                    suffix.upper().lstrip("."), " and colours" if suffix == ".ply" and corner_color is not None else "")
    data = mesh.export(file_type=suffix.lstrip("."))
    write_bytes_atomic(path, data.encode() if isinstance(data, str) else data)
    return [path.name]


def _render_vertices(V, F, corner_uv, corner_color):
    """Render vertices: one per distinct (position index, UV, colour) over the corners.

    Returns ``(Vr (#R, 3), Fr (#F, 3), keys)`` with ``keys["uv"] (#R, 2)`` / ``keys["color"] (#R, 4)``
    (present when given)."""
    cols = [F.reshape(-1, 1).astype(np.float64)]
    if corner_uv is not None:
        cols.append(np.nan_to_num(np.asarray(corner_uv, np.float64).reshape(-1, 2), nan=0.0))
    if corner_color is not None:
        cols.append(np.asarray(corner_color, np.float64).reshape(-1, 4))
    table = np.concatenate(cols, axis=1)
    uniq, inverse = np.unique(table, axis=0, return_inverse=True)
    keys = {}
    at = 1
    if corner_uv is not None:
        keys["uv"] = uniq[:, at:at + 2]
        at += 2
    if corner_color is not None:
        keys["color"] = uniq[:, at:at + 4].astype(np.uint8)
    return V[uniq[:, 0].astype(np.int64)], inverse.reshape(-1, 3).astype(np.int64), keys


def _unit_rows(raw: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(raw, axis=-1, keepdims=True)
    return np.divide(raw, norm, out=np.broadcast_to(fallback, raw.shape).copy(), where=norm > 1e-12)


def corner_normals(V, F, *, crease_deg: float = CREASE_DEG) -> np.ndarray:
    """``(#F, 3, 3)`` unit normals per face corner: the area-weighted mean of the normals of the
    faces around the corner's position that are within ``crease_deg`` of the corner's face (a
    corner of a face without area: its neighbours' mean, else +z)."""
    T = V[F]
    raw = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    length = np.linalg.norm(raw, axis=1, keepdims=True)
    unit = np.divide(raw, length, out=np.zeros_like(raw), where=length > 0)
    corner_vertex = F.reshape(-1)
    corner_face = np.repeat(np.arange(len(F)), 3)
    order = np.argsort(corner_vertex, kind="stable")
    counts = np.bincount(corner_vertex, minlength=len(V))
    starts = np.concatenate([[0], np.cumsum(counts)])
    # every (corner, face around the same vertex) pair
    reps = counts[corner_vertex]
    pair_corner = np.repeat(np.arange(len(corner_vertex)), reps)
    offsets = np.arange(len(pair_corner)) - np.repeat(np.cumsum(reps) - reps, reps)
    pair_face = corner_face[order[starts[corner_vertex[pair_corner]] + offsets]]
    flat = (length[:, 0] == 0)[corner_face[pair_corner]]
    near = flat | (np.einsum("ij,ij->i", unit[corner_face[pair_corner]], unit[pair_face])
                   >= np.cos(np.radians(crease_deg)))
    summed = np.zeros((len(corner_vertex), 3))
    np.add.at(summed, pair_corner[near], raw[pair_face[near]])
    return _unit_rows(summed, np.array([0.0, 0.0, 1.0])).reshape(-1, 3, 3)


def corner_tangents(V, F, corner_uv, corner_normal) -> np.ndarray | None:
    """``(#F, 3, 4)`` glTF tangents per corner: the direction of increasing u in each face
    (Lengyel's per-triangle frame), made orthogonal to the corner's normal, and ``w`` = +-1 the
    handedness of the (normal, tangent, v) frame; None without ``corner_uv``. Faces without UVs, or
    whose UVs have no area, get a unit vector orthogonal to the normal and ``w`` = 1."""
    if corner_uv is None:
        return None
    T = V[F]
    uv = np.nan_to_num(np.asarray(corner_uv, np.float64))
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    r = np.divide(1.0, det, out=np.zeros_like(det), where=np.abs(det) > 1e-20)[:, None]
    tangent = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r
    bitangent = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r
    N = corner_normal
    t = tangent[:, None, :] - np.einsum("fkj,fj->fk", N, tangent)[..., None] * N
    helper = np.where(np.abs(N[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    other = np.cross(N, helper)
    t = _unit_rows(np.where((np.linalg.norm(t, axis=-1, keepdims=True) > 1e-12), t, other), np.array([1.0, 0, 0]))
    w = np.where(np.einsum("fkj,fj->fk", np.cross(N, t), bitangent) < 0, -1.0, 1.0)
    return np.concatenate([t, w[..., None]], axis=-1)


def _texture_files(path: Path, materials: list[Material], used) -> tuple[dict, dict[str, bytes | np.ndarray]]:
    """Texture statements and files of the ``used`` materials written beside ``path``: material
    index -> ``[(statement head, file name)]``, and file name -> the source file's bytes or an image
    to encode as PNG. Names are ``<stem>_<image name>``, made safe and unique; a source file used
    twice is written once."""
    from_source: dict[Path, str] = {}
    files: dict[str, bytes | np.ndarray] = {}
    statements: dict[int, list] = {}

    def name_for(base: str) -> str:
        stem, ext = Path(_SAFE.sub("_", base)).stem, Path(base).suffix.lower() or ".png"
        name, k = f"{path.stem}_{stem}{ext}", 2
        while name in files:
            name, k = f"{path.stem}_{stem}_{k}{ext}", k + 1
        return name

    for i in used:
        mat = materials[i]
        statements[i] = []
        for head, source in mat.maps:
            if not source.is_file():
                continue
            if source not in from_source:
                from_source[source] = name_for(source.name)
                files[from_source[source]] = source.read_bytes()
            statements[i].append((head, from_source[source]))
        if mat.image is not None and not any(h.split()[0].lower() == "map_kd" for h, _ in mat.maps):
            name = name_for(f"{mat.name}.png")
            files[name] = mat.image
            statements[i].append(("map_Kd", name))
    return statements, files


def _mtl_blocks(materials: list[Material], used, statements: dict) -> list[tuple[str, list[str]]]:
    blocks = []
    for i in used:
        mat = materials[i]
        kept = mat.mtl_lines or [f"Kd {mat.color[0]:.6g} {mat.color[1]:.6g} {mat.color[2]:.6g}",
                                 *([f"d {mat.color[3]:.6g}"] if mat.color[3] < 1 else [])]
        blocks.append((mat.name, kept + [f"{head} {name}" for head, name in statements[i]]))
    return blocks


def _write_obj(path: Path, V, F, corner_uv, face_material, corner_color, like: Asset, face_polygon,
               face_group) -> list[str]:
    from synthkit.io.images import save_image

    used = np.unique(face_material[face_material >= 0])
    statements, files = _texture_files(path, like.materials, used)
    mtl = f"{path.stem}.mtl" if len(used) else None
    Vr, Fr, keys = _render_vertices(V, F, None, corner_color)
    corners = np.full((len(F), 3, 3), -1, np.int64)
    corners[..., 0] = Fr
    uv_table = None
    if corner_uv is not None:
        has = np.isfinite(corner_uv).all(axis=-1)
        uv_table, vt_of = np.unique(corner_uv[has], axis=0, return_inverse=True)
        corners[..., 1][has] = vt_of.reshape(-1)
    n_table, vn_of = np.unique(np.round(corner_normals(V, F), 6).reshape(-1, 3), axis=0, return_inverse=True)
    corners[..., 2] = vn_of.reshape(-1, 3)
    groups = like.groups if face_group is not None else [(like.name, None)]
    text = objfile.obj_text(Vr, corners, uvs=uv_table, normals=n_table,
                            colors=None if corner_color is None else keys["color"][:, :3] / 255.0,
                            face_material=face_material, material_names=[m.name for m in like.materials],
                            face_polygon=face_polygon, face_group=face_group, groups=groups, mtllib=mtl,
                            header=f"written by synthkit from {like.source.name}")
    for name, data in files.items():
        if isinstance(data, bytes):
            write_bytes_atomic(path.parent / name, data)
        else:
            save_image(path.parent / name, data)
    if mtl:
        write_text_atomic(path.parent / mtl, objfile.mtl_text(_mtl_blocks(like.materials, used, statements)))
    write_text_atomic(path, text)
    return [path.name, *([mtl] if mtl else []), *files]
