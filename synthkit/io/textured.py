"""Textured meshes that keep their UVs and materials per surface: OBJ (+MTL) and GLB.

``load_textured`` reads an indexed face set whose triangles carry a material and texture
coordinates; ``save_textured`` writes the same file with new vertex positions and nothing else
changed (OBJ: the ``v`` lines are rewritten in place, every other line is kept, and the MTL and
the texture images it names are copied beside the output; GLB: the scene is written again with
each geometry's visuals and embedded textures, its node transforms applied to the vertices, so
positions are in world coordinates and stored as float32). ``companion_files`` lists the files an
OBJ needs beside it; ``material_textures`` maps each material to the ``map_Kd`` image its MTL names.

A texture reshape gives an OBJ output :class:`Retexture` entries: the faces of a reshaped surface
then name a new material (in ``<stem>.retex.mtl``, written beside the OBJ and named by a second
``mtllib`` line) whose ``map_Kd`` is the surface's baked texture, and their corners use new ``vt``
lines appended at the end of the file; every other line is kept.

Render vertices: an OBJ corner is a ``(v, vt)`` pair; each distinct pair is one render vertex, so
two triangles share a render vertex exactly when they share 3-D and UV coordinates. A GLB's
vertices are its render vertices (geometries concatenated in scene order, in world coordinates).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from synthkit.errors import InputError
from synthkit.io.assets import map_file_name, resolve_named_file
from synthkit.io.atomic import write_bytes_atomic, write_text_atomic
from synthkit.io.meshes import check_mesh

__all__ = [
    "TexturedMesh", "Retexture", "load_textured", "save_textured", "companion_files", "material_textures",
    "TEXTURED_SUFFIXES",
]

log = logging.getLogger(__name__)

TEXTURED_SUFFIXES = (".obj", ".glb")
_MAP_KEY = re.compile(r"^\s*(map_\w+|bump|disp|decal|norm)\s+", re.IGNORECASE)
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


@dataclass
class TexturedMesh:
    """A textured indexed face set.

    Attributes
    ----------
    V : (#V, 3) float64 render-vertex positions
    F : (#F, 3) int64 triangles over render vertices
    UV : (#V, 2) float64 texture coordinates (NaN where the file has none)
    face_material : (#F,) int64 index into ``materials``
    materials : material names
    position_index : (#V,) int64 the file position (OBJ ``v`` line, 0-based; GLB vertex) of each render vertex
    positions : (#P, 3) float64 the file's positions (OBJ ``v`` lines; for GLB equal to ``V``)
    source : the file read
    """

    V: np.ndarray
    F: np.ndarray
    UV: np.ndarray
    face_material: np.ndarray
    materials: list[str]
    position_index: np.ndarray
    positions: np.ndarray
    source: Path
    _meshes: list = field(default_factory=list, repr=False)


@dataclass
class Retexture:
    """A reshaped surface of an OBJ output: its triangles ``faces (k,) int64``, the new texture
    coordinates ``UV (#V, 2)`` of the render vertices they use (other rows are ignored), the new
    material's name and its baked texture ``image (H, W, 3)`` written as ``image_name``."""

    faces: np.ndarray
    UV: np.ndarray
    material: str
    image_name: str
    image: np.ndarray


def load_textured(path: Path | str) -> TexturedMesh:
    """Read an OBJ (with its ``usemtl`` materials and ``vt`` coordinates) or a GLB scene.

    Polygons are split into triangle fans. Raises InputError naming the file when it is missing,
    unreadable, of another format, or has no faces.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: mesh file not found")
    suffix = path.suffix.lower()
    if suffix not in TEXTURED_SUFFIXES:
        raise InputError(f"{path}: unsupported textured mesh format {suffix!r} (use .obj or .glb)")
    mesh = _load_obj(path) if suffix == ".obj" else _load_glb(path)
    check_mesh(mesh.V, mesh.F, source=path)
    if suffix == ".obj":
        _warn_missing_companions(path)
    return mesh


def _warn_missing_companions(obj: Path) -> None:
    """One warning line per MTL or texture image the OBJ names that is missing (the mesh is read
    and written without it)."""
    for name in _mtl_files(obj):
        mtl = resolve_named_file(name, obj.parent)
        if not mtl.is_file():
            log.warning("%s: material file %s named by the mesh is missing; written without it", obj, name)
            continue
        for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
            if _MAP_KEY.match(line) and not resolve_named_file(map_file_name(line), mtl.parent).is_file():
                log.warning("%s: texture file %s is missing; written without it", mtl, map_file_name(line))


def _parse_index(token: str, count: int) -> int:
    value = int(token)
    return value - 1 if value > 0 else count + value


def _load_obj(path: Path) -> TexturedMesh:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read mesh: {exc}") from None
    positions, uvs, corners, face_mat, materials = [], [], [], [], []
    current = -1
    try:
        for line in text.splitlines():
            parts = line.split()
            if not parts:
                continue
            tag = parts[0]
            if tag == "v":
                positions.append([float(x) for x in parts[1:4]])
            elif tag == "vt":
                uvs.append([float(x) for x in (parts[1:3] + ["0"])[:2]])
            elif tag == "usemtl":
                name = parts[1] if len(parts) > 1 else ""
                if name not in materials:
                    materials.append(name)
                current = materials.index(name)
            elif tag == "f":
                poly = []
                for tok in parts[1:]:
                    fields = tok.split("/")
                    p = _parse_index(fields[0], len(positions))
                    t = _parse_index(fields[1], len(uvs)) if len(fields) > 1 and fields[1] else -1
                    poly.append((p, t))
                for j in range(1, len(poly) - 1):
                    corners.append([poly[0], poly[j], poly[j + 1]])
                    face_mat.append(current)
    except (ValueError, IndexError) as exc:
        raise InputError(f"{path}: cannot read mesh: malformed OBJ line: {exc}") from None
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if not corners:
        raise InputError(f"{path}: mesh has no faces ({len(P)} vertices, no triangles)")
    C = np.asarray(corners, dtype=np.int64).reshape(-1, 2)
    if C[:, 0].min() < 0 or C[:, 0].max() >= len(P) or (C[:, 1] < -1).any() or (C[:, 1] >= len(uvs)).any():
        raise InputError(f"{path}: face indices out of range")
    keys, inverse = np.unique(C, axis=0, return_inverse=True)
    UVall = np.asarray(uvs, dtype=np.float64).reshape(-1, 2)
    UV = np.full((len(keys), 2), np.nan)
    has_uv = keys[:, 1] >= 0
    UV[has_uv] = UVall[keys[has_uv, 1]]
    fm = np.asarray(face_mat, dtype=np.int64)
    if (fm < 0).any():
        materials.append("")
        fm[fm < 0] = len(materials) - 1
    return TexturedMesh(
        V=P[keys[:, 0]], F=inverse.reshape(-1, 3).astype(np.int64), UV=UV, face_material=fm,
        materials=materials, position_index=keys[:, 0].astype(np.int64), positions=P, source=path,
    )


def _load_glb(path: Path) -> TexturedMesh:
    try:
        loaded = trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise InputError(f"{path}: cannot read mesh: {type(exc).__name__}: {exc}".splitlines()[0]) from None
    geoms = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
    geoms = [g for g in geoms if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    if not geoms:
        raise InputError(f"{path}: mesh has no faces")
    Vs, Fs, UVs, fms, materials = [], [], [], [], []
    base = 0
    for g in geoms:
        Vs.append(np.asarray(g.vertices, np.float64))
        Fs.append(np.asarray(g.faces, np.int64) + base)
        uv = getattr(g.visual, "uv", None)
        UVs.append(np.asarray(uv, np.float64) if uv is not None else np.full((len(g.vertices), 2), np.nan))
        name = getattr(getattr(g.visual, "material", None), "name", None) or f"material_{len(materials)}"
        if name not in materials:
            materials.append(name)
        fms.append(np.full(len(g.faces), materials.index(name), np.int64))
        base += len(g.vertices)
    V = np.vstack(Vs)
    return TexturedMesh(
        V=V, F=np.vstack(Fs), UV=np.vstack(UVs), face_material=np.concatenate(fms), materials=materials,
        position_index=np.arange(len(V), dtype=np.int64), positions=V, source=path, _meshes=geoms,
    )


def _mtl_files(obj_path: Path) -> list[str]:
    """The MTL files an OBJ names (as written)."""
    names = []
    for line in obj_path.read_text(encoding="utf-8", errors="replace").splitlines():
        if line.startswith("mtllib"):
            names.extend(line.split()[1:])
    return names


@dataclass
class _Companion:
    """A file an OBJ needs beside it: where it is read from, the safe name it gets in the output
    folder, and for an MTL the (texture name as written -> safe name) rewrites of its maps."""

    source: Path
    name: str
    rewrites: dict = field(default_factory=dict)
    keep: set | None = None  # an MTL's materials to write (None: all)


def _safe_name(name: str, taken: set[str]) -> str:
    """``name``'s base name with unsafe characters replaced, unique among ``taken`` (added to it)."""
    stem, suffix = Path(_UNSAFE.sub("_", Path(name.replace("\\", "/")).name)).stem, Path(name).suffix.lower()
    safe, k = f"{stem}{suffix}", 2
    while safe in taken:
        safe, k = f"{stem}_{k}{suffix}", k + 1
    taken.add(safe)
    return safe


def _used_materials(mesh: TexturedMesh, retexture=()) -> set[str]:
    """Names of the input's materials that faces still use once ``retexture`` entries moved theirs."""
    moved = np.zeros(len(mesh.F), bool)
    for entry in retexture:
        moved[entry.faces] = True
    return {mesh.materials[k] for k in np.unique(mesh.face_material[~moved])}


def _mtl_blocks(mtl: Path) -> list[tuple[str | None, str]]:
    """``(material the line belongs to, line)`` for every line of an MTL (None before any newmtl)."""
    current, out = None, []
    for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
        parts = line.split()
        if parts and parts[0] == "newmtl":
            current = " ".join(parts[1:])
        out.append((current, line))
    return out


def _companions(mesh: TexturedMesh, used: set[str] | None = None) -> list[_Companion]:
    """The MTL files and existing texture images an OBJ names, resolved as DCC tools do (relative to
    the OBJ / MTL folder, in sibling or parent folders, or absolute), each with a safe output name.
    With ``used`` (material names), only the materials faces use and the images they name: an MTL
    none of whose materials is used is left out. Raises InputError naming the MTL when a texture it
    names is not an image file."""
    import cv2

    if mesh.source.suffix.lower() != ".obj":
        return []
    taken: set[str] = set()
    found, images = [], {}
    for name in _mtl_files(mesh.source):
        mtl = resolve_named_file(name, mesh.source.parent)
        if not mtl.is_file():
            continue
        blocks = _mtl_blocks(mtl)
        if used is not None and not {b for b, _ in blocks} & used:
            continue
        entry = _Companion(mtl, _safe_name(name, taken), keep=used)
        found.append(entry)
        for block, line in blocks:
            if not _MAP_KEY.match(line) or (used is not None and block is not None and block not in used):
                continue
            written = map_file_name(line)
            image = resolve_named_file(written, mtl.parent)
            if not image.is_file():
                continue
            if not cv2.haveImageReader(str(image)):
                raise InputError(f"{mtl}: texture {written} is not an image file")
            if image not in images:
                images[image] = _Companion(image, _safe_name(written, taken))
                found.append(images[image])
            entry.rewrites[written] = images[image].name
    return found


def companion_files(mesh: TexturedMesh, retexture=()) -> list[str]:
    """Names (plain file names, safe, unique) under which the files an OBJ needs -- its MTL files
    and the images they name that exist, for the materials its faces still use once ``retexture``
    entries moved theirs -- are written beside the output; empty for a GLB (textures are embedded)."""
    return [c.name for c in _companions(mesh, _used_materials(mesh, retexture))]


def material_textures(mesh: TexturedMesh) -> dict[str, Path]:
    """Material name -> the ``map_Kd`` image path its OBJ's MTL names (resolved as
    :func:`resolve_named_file` does; whether or not the file exists); materials without one are
    left out. Empty for a GLB (textures are embedded). Raises InputError when an MTL the OBJ names
    is missing."""
    if mesh.source.suffix.lower() != ".obj":
        return {}
    found = {}
    for name in _mtl_files(mesh.source):
        mtl = resolve_named_file(name, mesh.source.parent)
        if not mtl.is_file():
            raise InputError(f"{mtl}: material library named by {mesh.source.name} not found")
        current = None
        for line in mtl.read_text(encoding="utf-8", errors="replace").splitlines():
            parts = line.split()
            if parts and parts[0] == "newmtl":
                current = parts[1] if len(parts) > 1 else ""
            elif parts and parts[0].lower() == "map_kd" and current is not None and map_file_name(line):
                found[current] = resolve_named_file(map_file_name(line), mtl.parent)
    return found


def _copy_companions(companions: list[_Companion], folder: Path) -> None:
    """Write ``companions`` into ``folder`` under their safe names: images as they are, MTLs with
    their texture names rewritten and only the materials they ``keep``."""
    for c in companions:
        if not c.rewrites and c.source.suffix.lower() != ".mtl":
            write_bytes_atomic(folder / c.name, c.source.read_bytes())
            continue
        lines = []
        for block, line in _mtl_blocks(c.source):
            if c.keep is not None and block is not None and block not in c.keep:
                continue
            if _MAP_KEY.match(line) and map_file_name(line) in c.rewrites:
                head = line.rstrip()[: len(line.rstrip()) - len(map_file_name(line))]
                line = head + c.rewrites[map_file_name(line)]
            lines.append(line)
        write_text_atomic(folder / c.name, "\n".join(lines) + "\n")


def save_textured(mesh: TexturedMesh, positions: np.ndarray, path: Path | str, *, retexture=()) -> None:
    """Write ``mesh`` with its file positions replaced by ``positions (#P, 3)``, in the input's
    format (by ``path``'s suffix, which must match the input's), atomically; an OBJ also gets its
    :func:`companion_files` copied beside it and, with ``retexture`` (:class:`Retexture` entries,
    OBJ only), the reshaped surfaces' materials, textures and UVs."""
    path = Path(path)
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != mesh.positions.shape:
        raise ValueError(f"positions must have shape {mesh.positions.shape}, got {positions.shape}")
    suffix = mesh.source.suffix.lower()
    if path.suffix.lower() != suffix:
        raise ValueError(f"output {path.name} must keep the input's format {suffix}")
    if retexture and suffix != ".obj":
        raise ValueError("retextured surfaces can only be written to an OBJ")
    if suffix == ".obj":
        companions = _companions(mesh, _used_materials(mesh, retexture))
        mtl_names = {c.source: c.name for c in companions if c.source.suffix.lower() == ".mtl"}
        mtllibs = {}
        for name in _mtl_files(mesh.source):
            resolved = resolve_named_file(name, mesh.source.parent)
            mtllibs[name] = mtl_names.get(resolved) if resolved.is_file() else name  # None: no face uses it
        _write_obj(mesh.source, positions, path, _retexture_plan(mesh, list(retexture), path), mtllibs)
        _copy_companions(companions, path.parent)
    else:
        scene = trimesh.Scene()
        start = 0
        for i, g in enumerate(mesh._meshes):
            copy = g.copy()
            copy.vertices = positions[start:start + len(g.vertices)]
            start += len(g.vertices)
            scene.add_geometry(copy, geom_name=f"geometry_{i}")
        write_bytes_atomic(path, scene.export(file_type="glb"))


@dataclass
class _Plan:
    """How the OBJ writer retextures: entry per triangle ``(#F,)`` (-1 none), new vt index (1-based)
    per (entry, render vertex), the vt lines to append and the MTL line to add."""

    F: np.ndarray
    entry_of_face: np.ndarray
    vt_index: dict
    vt_lines: list
    materials: list
    mtllib: str | None


def _retexture_plan(mesh: TexturedMesh, entries: list, path: Path) -> _Plan:
    """Write the entries' textures and MTL beside ``path`` and plan the OBJ's new lines."""
    entry_of_face = np.full(len(mesh.F), -1, np.int64)
    vt_index, vt_lines = {}, []
    n_vt = sum(1 for line in mesh.source.read_text(encoding="utf-8", errors="replace").splitlines()
               if line.startswith("vt ") or line.startswith("vt\t"))
    for e, entry in enumerate(entries):
        entry_of_face[entry.faces] = e
        for v in np.unique(mesh.F[entry.faces]):
            vt_index[(e, int(v))] = n_vt + len(vt_lines) + 1
            u, w = entry.UV[v]
            vt_lines.append(f"vt {u:.17g} {w:.17g}")
    mtllib = None
    if entries:
        from synthkit.io.images import save_image

        mtllib = f"{path.stem}.retex.mtl"
        lines = []
        for entry in entries:
            save_image(path.parent / entry.image_name, entry.image)
            lines += [f"newmtl {entry.material}", "Ka 1 1 1", "Kd 1 1 1", f"map_Kd {entry.image_name}"]
        write_text_atomic(path.parent / mtllib, "\n".join(lines) + "\n")
    return _Plan(mesh.F, entry_of_face, vt_index, vt_lines, [e.material for e in entries], mtllib)


def _face_line(parts, tri: int, plan: _Plan) -> str:
    """An ``f`` line whose corners use the new vt indices of the plan's entry for triangle ``tri``
    (the line's fan triangles are ``tri, tri + 1, ...``)."""
    e = int(plan.entry_of_face[tri])
    n = len(parts) - 1
    F = plan.F
    rv = [F[tri, 0]] + [F[tri + j - 1, 1] for j in range(1, n - 1)] + [F[tri + n - 3, 2]]
    tokens = []
    for tok, v in zip(parts[1:], rv, strict=True):
        fields = tok.split("/")
        normal = fields[2] if len(fields) > 2 else ""
        tokens.append(f"{fields[0]}/{plan.vt_index[(e, int(v))]}" + (f"/{normal}" if normal else ""))
    return "f " + " ".join(tokens)


def _write_obj(source: Path, positions: np.ndarray, target: Path, plan: _Plan | None = None,
               mtllibs: dict | None = None) -> None:
    """Copy ``source`` to ``target`` with the i-th ``v`` line holding ``positions[i]`` (17 digits:
    exact), ``mtllib`` names replaced by ``mtllibs`` (as written -> output name) and, with a
    ``plan``, the retextured faces rewritten (see :func:`_retexture_plan`)."""
    out, i, tri, current, active = [], 0, 0, None, None
    retex = plan is not None and len(plan.materials) > 0
    for line in source.read_text(encoding="utf-8", errors="replace").splitlines():
        parts = line.split()
        if parts and parts[0] == "v":
            x, y, z = positions[i]
            extra = " ".join(parts[4:])
            out.append(f"v {x:.17g} {y:.17g} {z:.17g}" + (f" {extra}" if extra else ""))
            i += 1
        elif parts and parts[0] == "mtllib":
            names = [(mtllibs or {}).get(name, name) for name in parts[1:]]
            if any(names):
                out.append("mtllib " + " ".join(n for n in names if n))
            if retex and plan.mtllib:
                out.append(f"mtllib {plan.mtllib}")
                plan.mtllib = None
        elif retex and parts and parts[0] == "usemtl":
            current = parts[1] if len(parts) > 1 else ""  # emitted before the next face that uses it
        elif retex and parts and parts[0] == "f":
            e = int(plan.entry_of_face[tri])
            wanted = plan.materials[e] if e >= 0 else current
            if wanted != active and wanted is not None:
                out.append(f"usemtl {wanted}")
                active = wanted
            out.append(_face_line(parts, tri, plan) if e >= 0 else line)
            tri += len(parts) - 3
        else:
            out.append(line)
    if retex:
        if plan.mtllib:
            out.insert(0, f"mtllib {plan.mtllib}")
        out += plan.vt_lines
    write_text_atomic(target, "\n".join(out) + "\n")
