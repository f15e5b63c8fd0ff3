"""Meshes with their appearance: read any mesh file as an :class:`Asset`, write a new mesh that
looks like it.

An asset is a triangle mesh whose face corners carry texture coordinates and colours, whose
faces carry a material, and whose materials carry their base colour and texture image. Methods
move, cut and copy the geometry and carry the per-corner arrays along (UV seams stay seams); the
writer turns corners back into render vertices (one per distinct position, UV and colour).

Formats (:func:`load_asset`, :func:`save_asset`):

- **OBJ + MTL**: ``v`` (with optional ``r g b`` colours), ``vt``, ``usemtl``, polygon ``f``
  lines (fanned into triangles). ``mtllib`` and ``map_Kd`` names are resolved the way DCC tools
  do: relative to the OBJ (MTL) folder, in sibling or parent folders (``../textures/a.png``), or
  absolute; backslashes are read as folder separators. A missing MTL or texture is one warning
  line naming the file; the mesh is read without it (its faces keep their material name, with no
  texture). A file named as a texture that is not an image is an :class:`InputError`. ``vt``
  lines without any material give one warning: UVs are kept, no material is invented. Written
  OBJs get a new MTL beside them (``<stem>.mtl``) holding each material's lines as read, with
  texture names rewritten to copies of the images placed *inside* the output folder under safe
  names (``<stem>_<image>``), and per-corner normals (averaged over faces within
  :data:`CREASE_DEG` of each other, so hard edges stay hard).
- **GLB / glTF**: every geometry of the scene in world coordinates, its UVs and material (PBR,
  kept whole, with its embedded base-colour texture) or vertex colours. Written GLBs hold one
  geometry per material, named after the input mesh (``<name>`` for one material,
  ``<name>_<material>`` for several), with the same PBR material objects.
- **PLY**: vertex (or face) colours as corner colours; written PLYs keep colours.
- **OFF, STL**: geometry only (written without appearance; a warning says what was not kept).
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from synthkit.errors import InputError
from synthkit.io._capture import check_readable
from synthkit.io.atomic import write_bytes_atomic, write_text_atomic
from synthkit.io.meshes import check_mesh, trimesh_load

log = logging.getLogger(__name__)

__all__ = ["Asset", "Material", "load_asset", "asset_from_trimesh", "save_asset", "resolve_named_file",
           "map_file_name", "corner_normals", "CREASE_DEG", "ASSET_SUFFIXES"]

ASSET_SUFFIXES = (".obj", ".glb", ".gltf", ".ply", ".off", ".stl")
WRITE_SUFFIXES = (".obj", ".glb", ".ply", ".off", ".stl")
CREASE_DEG = 30.0
"""Faces meeting at a vertex share its normal in a written OBJ when their normals differ by less."""

_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


@dataclass
class Material:
    """One material of an asset.

    Attributes
    ----------
    name : the material's name as the file gives it
    color : (4,) float64 RGBA base colour in [0, 1] (MTL ``Kd``/``d``, glTF ``baseColorFactor``)
    image : (H, W, C) uint8 base-colour texture (C = 3 or 4), or None
    image_path : the file the texture was read from (OBJ), or None (embedded, or none)
    mtl_lines : the MTL block's lines other than ``newmtl`` and texture maps (OBJ input)
    pbr : the trimesh material object read from a GLB (kept whole for GLB output), or None
    """

    name: str
    color: np.ndarray = field(default_factory=lambda: np.ones(4))
    image: np.ndarray | None = None
    image_path: Path | None = None
    mtl_lines: list[str] = field(default_factory=list)
    pbr: object | None = None


@dataclass
class Asset:
    """A triangle mesh with its appearance.

    Attributes
    ----------
    V : (#V, 3) float64 positions (a UV or colour seam may repeat a position)
    F : (#F, 3) int64 triangles
    corner_uv : (#F, 3, 2) float64 texture coordinates per face corner, or None
    corner_color : (#F, 3, 4) uint8 RGBA colours per face corner, or None
    face_material : (#F,) int64 index into ``materials`` (-1: none)
    materials : the materials, in file order
    name : the mesh's name (GLB node / OBJ ``o``, else the file stem)
    source : the file read
    """

    V: np.ndarray
    F: np.ndarray
    corner_uv: np.ndarray | None
    corner_color: np.ndarray | None
    face_material: np.ndarray
    materials: list[Material]
    name: str
    source: Path

    @property
    def textured(self) -> bool:
        """Whether some face has UVs and a material with a texture image."""
        return self.corner_uv is not None and any(m.image is not None for m in self.materials)


def load_asset(path: Path | str) -> Asset:
    """Read a mesh file with its appearance (see the module docstring for the formats).

    Raises InputError naming the file when it is missing, unreadable, corrupt, has no faces or
    non-finite positions, or names a texture that is not an image.
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


def resolve_named_file(name: str, folder: Path) -> Path:
    """The file an OBJ's ``mtllib`` or an MTL's ``map_Kd`` name means: absolute as written, else
    relative to ``folder`` (``..`` allowed: textures in sibling or parent folders); backslashes
    are folder separators."""
    candidate = Path(name.replace("\\", "/"))
    return Path(os.path.normpath(candidate if candidate.is_absolute() else folder / candidate))


_MAP_OPTION_ARGS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
                    "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}
"""MTL texture-map options and how many values each takes (the file name follows them)."""


def map_file_name(line: str) -> str:
    """The file name of an MTL texture-map line (``map_Kd -s 1 1 1 my bricks.png`` ->
    ``my bricks.png``): options and their values skipped, the rest (spaces included) is the name."""
    tokens = line.split()[1:]
    i = 0
    while i < len(tokens) and tokens[i].lower() in _MAP_OPTION_ARGS:
        i += 1 + _MAP_OPTION_ARGS[tokens[i].lower()]
    return " ".join(tokens[i:])


def _obj_index(token: str, count: int) -> int:
    value = int(token)
    return value - 1 if value > 0 else count + value


@dataclass
class _ObjData:
    positions: list = field(default_factory=list)
    colors: list = field(default_factory=list)
    uvs: list = field(default_factory=list)
    corners: list = field(default_factory=list)
    face_mat: list = field(default_factory=list)
    material_names: list = field(default_factory=list)
    mtllibs: list = field(default_factory=list)
    name: str | None = None


def _parse_obj_line(parts: list[str], d: _ObjData, current: int) -> int:
    tag = parts[0]
    if tag == "v":
        d.positions.append([float(x) for x in parts[1:4]])
        d.colors.append([float(x) for x in parts[4:7]] if len(parts) >= 7 else None)
    elif tag == "vt":
        d.uvs.append([float(x) for x in (parts[1:3] + ["0"])[:2]])
    elif tag == "usemtl":
        name = " ".join(parts[1:])
        if name not in d.material_names:
            d.material_names.append(name)
        current = d.material_names.index(name)
    elif tag == "mtllib":
        d.mtllibs.append(" ".join(parts[1:]))
    elif tag in ("o", "g") and d.name is None and len(parts) > 1:
        d.name = " ".join(parts[1:])
    elif tag == "f":
        poly = []
        for tok in parts[1:]:
            fields = tok.split("/")
            p = _obj_index(fields[0], len(d.positions))
            t = _obj_index(fields[1], len(d.uvs)) if len(fields) > 1 and fields[1] else -1
            poly.append((p, t))
        for j in range(1, len(poly) - 1):
            d.corners.append([poly[0], poly[j], poly[j + 1]])
            d.face_mat.append(current)
    return current


def _read_obj(path: Path) -> Asset:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read mesh: {exc}") from None
    d, current = _ObjData(), -1
    try:
        for line in text.splitlines():
            parts = line.split()
            if parts:
                current = _parse_obj_line(parts, d, current)
    except (ValueError, IndexError) as exc:
        raise InputError(f"{path}: cannot read mesh: malformed OBJ line: {exc}") from None
    P = np.asarray(d.positions, dtype=np.float64).reshape(-1, 3)
    if not d.corners:
        raise InputError(f"{path}: mesh has no faces ({len(P)} vertices, no triangles)")
    C = np.asarray(d.corners, dtype=np.int64).reshape(-1, 3, 2)
    if C[..., 0].min() < 0 or C[..., 0].max() >= len(P) or (C[..., 1] < -1).any() or (C[..., 1] >= len(d.uvs)).any():
        raise InputError(f"{path}: face indices out of range")
    F = C[..., 0]
    corner_uv = None
    if (C[..., 1] >= 0).any():
        UV = np.asarray(d.uvs, dtype=np.float64).reshape(-1, 2)
        corner_uv = np.where((C[..., 1] >= 0)[..., None], UV[np.maximum(C[..., 1], 0)], np.nan)
    corner_color = None
    if d.colors and all(c is not None for c in d.colors):
        rgb = np.clip(np.asarray(d.colors, np.float64), 0, 1)
        corner_color = np.concatenate([np.round(rgb * 255), np.full((len(rgb), 1), 255.0)], axis=1)[F].astype(np.uint8)
    materials = _obj_materials(path, d.mtllibs, d.material_names)
    if corner_uv is not None and not d.material_names:
        log.warning("%s: has texture coordinates but no material; UVs kept, no texture applied", path)
    return Asset(V=P, F=F, corner_uv=corner_uv, corner_color=corner_color,
                 face_material=np.asarray(d.face_mat, np.int64), materials=materials,
                 name=d.name or path.stem, source=path)


def _obj_materials(obj: Path, mtllibs: list[str], names: list[str]) -> list[Material]:
    """The materials ``names`` (in ``usemtl`` order) from the MTL files ``mtllibs`` names."""
    blocks: dict[str, tuple[Path, list[str]]] = {}
    for lib in mtllibs:
        mtl = resolve_named_file(lib, obj.parent)
        if not mtl.is_file():
            log.warning("%s: material file %s named by the mesh is missing; loading without its materials", obj, lib)
            continue
        current = None
        for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
            parts = line.split()
            if parts and parts[0] == "newmtl":
                current = " ".join(parts[1:])
                blocks[current] = (mtl, [])
            elif parts and current is not None:
                blocks[current][1].append(line.strip())
    return [_mtl_material(name, *blocks[name]) if name in blocks else Material(name=name) for name in names]


def _mtl_material(name: str, mtl: Path, lines: list[str]) -> Material:
    """A material from its MTL block ``lines`` (texture read from ``map_Kd``)."""
    from synthkit.io.images import load_image

    mat = Material(name=name)
    for line in lines:
        parts = line.split()
        key = parts[0].lower()
        if key == "kd" and len(parts) >= 4:
            mat.color[:3] = np.clip([float(x) for x in parts[1:4]], 0, 1)
        elif key == "d" and len(parts) >= 2:
            mat.color[3] = float(np.clip(float(parts[1]), 0, 1))
        if key.startswith("map_") or key in ("bump", "disp", "decal", "norm", "refl"):
            if key == "map_kd" and map_file_name(line):
                image = resolve_named_file(map_file_name(line), mtl.parent)
                if not image.is_file():
                    log.warning("%s: texture file %s of material %s is missing; loading without texture",
                                mtl, map_file_name(line), name)
                    continue
                img = load_image(image, mode="any")
                mat.image = _as_uint8_rgb(img)
                mat.image_path = image
            continue
        mat.mtl_lines.append(line)
    return mat


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
    return _assemble(path, geoms, name)


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


def save_asset(path: Path | str, V, F, *, like: Asset, corner_uv=None, face_material=None,
               corner_color=None) -> list[str]:
    """Write ``V (#V, 3)``, ``F (#F, 3)`` with the appearance of ``like`` to ``path``, atomically.

    ``corner_uv (#F, 3, 2)``, ``corner_color (#F, 3, 4) uint8`` and ``face_material (#F,)``
    (indices into ``like.materials``; default: the first material) describe the new faces. The
    format follows ``path``'s suffix (module docstring). Returns the names of the files written,
    relative to ``path.parent`` (the mesh first, then its MTL and textures). Raises ValueError on
    arrays of the wrong shape or an unsupported suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_SUFFIXES:
        raise ValueError(f"unsupported mesh format {suffix!r} (use {', '.join(WRITE_SUFFIXES)})")
    V, F, corner_uv, face_material, corner_color = _check_shapes(V, F, corner_uv, face_material, corner_color, like)
    if suffix == ".obj":
        return _write_obj(path, V, F, corner_uv, face_material, corner_color, like)
    if suffix == ".glb":
        write_bytes_atomic(path, _glb_bytes(V, F, corner_uv, face_material, corner_color, like))
        return [path.name]
    if suffix == ".ply" and corner_color is not None:
        Vr, Fr, keys = _render_vertices(V, F, None, corner_color)
        mesh = trimesh.Trimesh(Vr, Fr, vertex_colors=keys["color"], process=False)
    else:
        mesh = trimesh.Trimesh(V, F, process=False)
    if corner_uv is not None or (suffix != ".ply" and corner_color is not None):
        log.warning("%s: %s keeps no texture coordinates or materials; written as geometry%s", path,
                    suffix.upper().lstrip("."), " and colours" if suffix == ".ply" and corner_color is not None else "")
    write_bytes_atomic(path, mesh.export(file_type=suffix.lstrip(".")))
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


def _glb_material(mat: Material):
    """The trimesh material to write for ``mat`` (a GLB's own PBR object, else one built from it)."""
    from PIL import Image
    from trimesh.visual.material import PBRMaterial

    if isinstance(mat.pbr, PBRMaterial):
        return mat.pbr
    texture = None if mat.image is None else Image.fromarray(mat.image)
    return PBRMaterial(name=mat.name, baseColorFactor=np.round(mat.color * 255).astype(np.uint8),
                       baseColorTexture=texture, metallicFactor=0.0, roughnessFactor=1.0)


def _glb_bytes(V, F, corner_uv, face_material, corner_color, like: Asset) -> bytes:
    scene = trimesh.Scene()
    groups = np.unique(face_material)
    for index in groups:
        faces = np.flatnonzero(face_material == index)
        uv = None if corner_uv is None or index < 0 else corner_uv[faces]
        col = None if corner_color is None else corner_color[faces]
        Vr, Fr, keys = _render_vertices(V, F[faces], uv, col)
        if uv is not None:
            visual = trimesh.visual.TextureVisuals(uv=keys["uv"], material=_glb_material(like.materials[index]))
        elif col is not None:
            visual = trimesh.visual.ColorVisuals(vertex_colors=keys["color"])
        else:
            visual = None
        geom = trimesh.Trimesh(Vr, Fr, visual=visual, process=False)
        name = like.name if len(groups) == 1 or index < 0 else f"{like.name}_{like.materials[index].name}"
        scene.add_geometry(geom, geom_name=name, node_name=name)
    return scene.export(file_type="glb")


def corner_normals(V, F, *, crease_deg: float = CREASE_DEG) -> np.ndarray:
    """``(#F, 3, 3)`` unit normals per face corner: the area-weighted mean of the normals of the
    faces around the corner's position that are within ``crease_deg`` of the corner's face."""
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
    near = np.einsum("ij,ij->i", unit[corner_face[pair_corner]], unit[pair_face]) >= np.cos(np.radians(crease_deg))
    summed = np.zeros((len(corner_vertex), 3))
    np.add.at(summed, pair_corner[near], raw[pair_face[near]])
    norm = np.linalg.norm(summed, axis=1, keepdims=True)
    out = np.divide(summed, norm, out=np.repeat(unit, 3, axis=0), where=norm > 0)
    return out.reshape(-1, 3, 3)


def _texture_files(path: Path, materials: list[Material]) -> dict[int, tuple[str, bytes | np.ndarray]]:
    """Material index -> (file name inside ``path.parent``, the source file's bytes or an image
    to encode as PNG). Names are ``<stem>_<image name>``, made safe and unique."""
    from_source: dict[Path, str] = {}
    taken: set[str] = set()
    files = {}
    for i, mat in enumerate(materials):
        if mat.image is None:
            continue
        if mat.image_path is not None and mat.image_path in from_source:
            files[i] = (from_source[mat.image_path], b"")
            continue
        base = mat.image_path.name if mat.image_path is not None else f"{mat.name}.png"
        stem, ext = Path(_SAFE.sub("_", base)).stem, Path(base).suffix.lower() or ".png"
        name, k = f"{path.stem}_{stem}{ext}", 2
        while name in taken:
            name, k = f"{path.stem}_{stem}_{k}{ext}", k + 1
        taken.add(name)
        if mat.image_path is not None:
            from_source[mat.image_path] = name
            files[i] = (name, mat.image_path.read_bytes())
        else:
            files[i] = (name, mat.image)
    return files


def _mtl_text(materials: list[Material], used: np.ndarray, textures: dict) -> str:
    lines = []
    for i in used:
        mat = materials[i]
        lines.append(f"newmtl {mat.name}")
        kept = mat.mtl_lines or [f"Kd {mat.color[0]:.6g} {mat.color[1]:.6g} {mat.color[2]:.6g}",
                                 *([f"d {mat.color[3]:.6g}"] if mat.color[3] < 1 else [])]
        lines += kept
        if i in textures:
            lines.append(f"map_Kd {textures[i][0]}")
        lines.append("")
    return "\n".join(lines)


def _obj_text(path: Path, V, F, corner_uv, face_material, corner_color, like: Asset, mtl: str | None) -> str:
    Vr, Fr, keys = _render_vertices(V, F, None, corner_color)
    out = [f"# written by synthkit from {like.source.name}"] + ([f"mtllib {mtl}"] if mtl else [])
    out.append(f"o {like.name}")
    if corner_color is not None:
        rgb = keys["color"][:, :3] / 255.0
        out += [f"v {x:.17g} {y:.17g} {z:.17g} {r:.4g} {g:.4g} {b:.4g}"
                for (x, y, z), (r, g, b) in zip(Vr, rgb, strict=True)]
    else:
        out += [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in Vr]
    vt_of = None
    if corner_uv is not None:
        uv_table, vt_of = np.unique(np.nan_to_num(corner_uv.reshape(-1, 2)), axis=0, return_inverse=True)
        out += [f"vt {u:.17g} {w:.17g}" for u, w in uv_table]
        vt_of = vt_of.reshape(-1, 3) + 1
    normals = np.round(corner_normals(V, F), 6).reshape(-1, 3)
    n_table, vn_of = np.unique(normals, axis=0, return_inverse=True)
    out += [f"vn {a:.6g} {b:.6g} {c:.6g}" for a, b, c in n_table]
    vn_of = vn_of.reshape(-1, 3) + 1
    order = np.argsort(face_material, kind="stable")
    current = None
    for f in order:
        if face_material[f] != current and face_material[f] >= 0:
            current = face_material[f]
            out.append(f"usemtl {like.materials[current].name}")
        v = Fr[f] + 1
        corners = [f"{v[k]}/{vt_of[f, k] if vt_of is not None else ''}/{vn_of[f, k]}" for k in range(3)]
        out.append("f " + " ".join(corners))
    return "\n".join(out) + "\n"


def _write_obj(path: Path, V, F, corner_uv, face_material, corner_color, like: Asset) -> list[str]:
    from synthkit.io.images import save_image

    used = np.unique(face_material[face_material >= 0])
    textures = _texture_files(path, [m if i in used else Material(m.name) for i, m in enumerate(like.materials)])
    written = [path.name]
    mtl = None
    if len(used):
        mtl = f"{path.stem}.mtl"
        unique = {name: data for name, data in textures.values() if not isinstance(data, bytes) or data}
        for name, data in unique.items():
            if isinstance(data, bytes):
                write_bytes_atomic(path.parent / name, data)
            else:
                save_image(path.parent / name, data)
            written.append(name)
        write_text_atomic(path.parent / mtl, _mtl_text(like.materials, used, textures))
        written.insert(1, mtl)
    write_text_atomic(path, _obj_text(path, V, F, corner_uv, face_material, corner_color, like, mtl))
    return written
