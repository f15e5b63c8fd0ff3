"""Wavefront OBJ and MTL: the one reader and the one writer of these files in synthkit.

Reading (:func:`read_obj`, :func:`read_mtl`)
    ``v`` (with optional ``r g b`` colours), ``vt``, ``vn``, ``f`` (polygons of any size, ``v``,
    ``v/vt``, ``v//vn`` and ``v/vt/vn`` corners, negative indices relative to the line), ``o`` and
    ``g`` (object and group names), ``usemtl`` and ``mtllib``. Polygons are split into triangle
    fans from their first corner, and every triangle remembers its polygon, so a writer gives the
    polygons back. Names (``usemtl``, ``newmtl``, ``o``, ``g``) are the rest of the line, stripped,
    as Blender reads them: a name with a space is one name. An ``mtllib`` line names one file when
    the rest of the line is one existing file, else one file per word. Other statements (``s``,
    ``l``, ``p``, curves) are skipped. A malformed statement or an index out of range is an
    :class:`~synthkit.errors.InputError` naming the file and the line.

Writing (:func:`obj_text`, :func:`mtl_text`)
    Every ``v``, ``vt`` and ``vn`` line comes before the first ``f`` line, so every face names only
    elements defined above it (Blender drops a face whose ``vt`` comes later). Faces keep their
    order, with ``o``/``g`` and ``usemtl`` lines where the object, group or material changes; each
    triangle fan that still forms its polygon is written as that polygon.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from synthkit.errors import InputError

__all__ = ["ObjData", "read_obj", "read_mtl", "resolve_named_file", "map_file_name", "obj_text", "mtl_text",
           "MAP_KEYS"]

MAP_KEYS = ("map_", "bump", "disp", "decal", "norm", "refl")
"""How the MTL statements that name a texture file begin (lower case)."""

_MAX_INDEX = 2**62
"""Larger OBJ indices than this cannot be an element of a file that fits in memory."""


@dataclass
class ObjData:
    """The statements of one OBJ file, 0-based.

    Attributes
    ----------
    positions : (#P, 3) float64 ``v`` coordinates
    colors : (#P, 3) float64 ``v`` colours in the file's range, or None unless every ``v`` has one
    uvs : (#T, 2) float64 ``vt`` coordinates
    normals : (#N, 3) float64 ``vn`` directions
    corners : (#F, 3, 3) int64 ``(v, vt, vn)`` of every triangle corner, -1 where the face gives none
    face_polygon : (#F,) int64 the ``f`` statement (0-based) each triangle comes from
    face_material : (#F,) int64 index into ``material_names`` (-1: before any ``usemtl``)
    face_group : (#F,) int64 index into ``groups``
    groups : ``(object name or None, group name or None)`` pairs in file order
    material_names : ``usemtl`` names in file order
    mtllibs : ``mtllib`` file names as written
    """

    positions: np.ndarray
    colors: np.ndarray | None
    uvs: np.ndarray
    normals: np.ndarray
    corners: np.ndarray
    face_polygon: np.ndarray
    face_material: np.ndarray
    face_group: np.ndarray
    groups: list
    material_names: list
    mtllibs: list


@dataclass
class _Parse:
    """Statements read so far."""

    positions: list = field(default_factory=list)
    colors: list = field(default_factory=list)
    uvs: list = field(default_factory=list)
    normals: list = field(default_factory=list)
    polygons: list = field(default_factory=list)
    polygon_line: list = field(default_factory=list)
    polygon_material: list = field(default_factory=list)
    polygon_group: list = field(default_factory=list)
    groups: list = field(default_factory=lambda: [(None, None)])
    group: int = 0
    material_names: list = field(default_factory=list)
    material: int = -1
    mtllibs: list = field(default_factory=list)


def _floats(tokens: list[str], least: int, most: int, what: str) -> list[float]:
    if len(tokens) < least:
        raise ValueError(f"'{what}' needs {least} numbers, got {len(tokens)}")
    values = [float(t) for t in tokens[:most]]
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"'{what}' has a NaN or infinite number")
    return values


def _index(token: str, count: int, what: str) -> int:
    """0-based index of OBJ index ``token`` among ``count`` elements defined so far (-1: empty)."""
    if token == "":
        return -1
    value = int(token)
    if value == 0 or abs(value) > _MAX_INDEX or count + value < 0:
        raise ValueError(f"{what} index {token} is out of range")
    return value - 1 if value > 0 else count + value


def _face(tokens: list[str], p: _Parse) -> None:
    if len(tokens) < 3:
        raise ValueError(f"'f' needs 3 corners, got {len(tokens)}")
    corners = []
    for tok in tokens:
        fields = (tok.split("/") + ["", ""])[:3]
        if fields[0] == "":
            raise ValueError(f"corner {tok!r} names no vertex")
        corners.append((_index(fields[0], len(p.positions), "vertex"), _index(fields[1], len(p.uvs), "texture"),
                        _index(fields[2], len(p.normals), "normal")))
    p.polygons.append(corners)
    p.polygon_material.append(p.material)
    p.polygon_group.append(p.group)


def _set_group(p: _Parse, obj: str | None, group: str | None) -> None:
    key = (obj, group)
    if key not in p.groups:
        p.groups.append(key)
    p.group = p.groups.index(key)


def _statement(tag: str, tokens: list[str], rest: str, p: _Parse) -> None:
    if tag == "v":
        p.positions.append(_floats(tokens, 3, 3, "v"))
        p.colors.append(_floats(tokens[3:], 3, 3, "v colour") if len(tokens) >= 6 else None)
    elif tag == "vt":
        p.uvs.append((_floats(tokens, 1, 2, "vt") + [0.0])[:2])
    elif tag == "vn":
        p.normals.append(_floats(tokens, 3, 3, "vn"))
    elif tag == "f":
        _face(tokens, p)
    elif tag == "usemtl":
        if rest not in p.material_names:
            p.material_names.append(rest)
        p.material = p.material_names.index(rest)
    elif tag == "o":
        _set_group(p, rest or None, None)
    elif tag == "g":
        _set_group(p, p.groups[p.group][0], rest or None)
    elif tag == "mtllib" and rest:
        p.mtllibs.append(rest)


def _parse(path: Path, text: str) -> _Parse:
    p = _Parse()
    for number, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0] if "#" in line else line
        tokens = body.split()
        if not tokens:
            continue
        try:
            _statement(tokens[0], tokens[1:], body.strip()[len(tokens[0]):].strip(), p)
        except (ValueError, OverflowError) as exc:
            raise InputError(f"{path}: line {number}: malformed OBJ statement: {exc}") from None
        if tokens[0] == "f":
            p.polygon_line.append(number)
    return p


def _check_ranges(path: Path, p: _Parse, corners: np.ndarray, polygon: np.ndarray) -> None:
    counts = (len(p.positions), len(p.uvs), len(p.normals))
    for k, (what, count) in enumerate(zip(("vertex", "texture", "normal"), counts, strict=True)):
        values = corners[..., k]
        bad = (values >= count) | (values < (0 if k == 0 else -1))
        if k > 0:
            bad &= values != -1
        if bad.any():
            f = int(np.flatnonzero(bad.any(axis=1))[0])
            line = p.polygon_line[polygon[f]]
            raise InputError(f"{path}: line {line}: {what} index out of range ({count} defined)")


def read_obj(path: Path | str) -> ObjData:
    """Read the OBJ file ``path`` (module docstring). Raises InputError naming the file (and the
    line) when it is unreadable, malformed, has an index out of range or no faces."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read mesh: {exc}") from None
    p = _parse(path, text)
    if not p.polygons:
        raise InputError(f"{path}: mesh has no faces ({len(p.positions)} vertices, no triangles)")
    tris, polygon = [], []
    for k, poly in enumerate(p.polygons):
        for j in range(1, len(poly) - 1):
            tris.append((poly[0], poly[j], poly[j + 1]))
            polygon.append(k)
    corners = np.asarray(tris, np.int64).reshape(-1, 3, 3)
    polygon = np.asarray(polygon, np.int64)
    _check_ranges(path, p, corners, polygon)
    colors = None
    if p.colors and all(c is not None for c in p.colors):
        colors = np.asarray(p.colors, np.float64)
    return ObjData(
        positions=np.asarray(p.positions, np.float64).reshape(-1, 3), colors=colors,
        uvs=np.asarray(p.uvs, np.float64).reshape(-1, 2), normals=np.asarray(p.normals, np.float64).reshape(-1, 3),
        corners=corners, face_polygon=polygon,
        face_material=np.asarray(p.polygon_material, np.int64)[polygon],
        face_group=np.asarray(p.polygon_group, np.int64)[polygon], groups=p.groups,
        material_names=p.material_names, mtllibs=p.mtllibs,
    )


def mtl_files(names: list[str], folder: Path) -> list[Path]:
    """The MTL files that ``mtllib`` lines ``names`` mean (module docstring), resolved in ``folder``."""
    found = []
    for rest in names:
        whole = resolve_named_file(rest, folder)
        found += [whole] if whole.is_file() or len(rest.split()) == 1 else \
            [resolve_named_file(word, folder) for word in rest.split()]
    return found


_MTL_NUMBERS = {"ka": 3, "kd": 3, "ks": 3, "ke": 3, "tf": 3, "d": 1, "tr": 1, "ns": 1, "ni": 1}
"""MTL statements of numbers and how many they take at least."""


def read_mtl(path: Path) -> dict[str, list[str]]:
    """Material name -> its MTL block's statements (stripped, ``newmtl`` left out), in file order.
    A colour or factor statement whose values are not finite numbers is an InputError naming the
    file and the line."""
    blocks: dict[str, list[str]] = {}
    current = None
    for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), start=1):
        tokens = line.split()
        if tokens and tokens[0] == "newmtl":
            current = line.strip()[len("newmtl"):].strip()
            blocks[current] = []
        elif tokens and not tokens[0].startswith("#") and current is not None:
            key = tokens[0].lower()
            if key in _MTL_NUMBERS:
                try:
                    _floats(tokens[1:], 1, _MTL_NUMBERS[key], tokens[0])
                except ValueError as exc:
                    raise InputError(f"{path}: line {number}: malformed MTL statement: {exc}") from None
            blocks[current].append(line.strip())
    return blocks


def resolve_named_file(name: str, folder: Path) -> Path:
    """The file an OBJ's ``mtllib`` or an MTL's map statement means: absolute as written, else
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


def _number(x: float, digits: int) -> str:
    text = f"{x:.{digits}g}"
    return "0" if text == "-0" else text


def _table(lines: list[str], tag: str, rows: np.ndarray, digits: int) -> None:
    lines += [f"{tag} " + " ".join(_number(x, digits) for x in row) for row in rows.tolist()]


def _polygons(corners: np.ndarray, face_polygon: np.ndarray | None) -> list[np.ndarray]:
    """Corner rows ``(k, 3)`` of the polygons to write: each run of triangles of one polygon that
    still forms its fan (``corners (#F, 3, 3)``), else one row per triangle."""
    if face_polygon is None:
        return list(corners)
    starts = np.flatnonzero(np.diff(face_polygon, prepend=-1) != 0)
    out = []
    for start, stop in zip(starts, [*starts[1:], len(corners)], strict=True):
        run = corners[start:stop]
        fan = (run[:, 0] == run[0, 0]).all() and (run[1:, 1] == run[:-1, 2]).all()
        out += [np.concatenate([run[0], run[1:, 2]])] if fan else list(run)
    return out


def _corner(c: np.ndarray) -> str:
    v, t, n = (int(x) + 1 for x in c)
    if n > 0:
        return f"{v}/{t if t > 0 else ''}/{n}"
    return f"{v}/{t}" if t > 0 else f"{v}"


def _face_lines(lines, corners, face_polygon, face_material, material_names, face_group, groups) -> None:
    """``f`` lines in face order, with ``o``/``g``/``usemtl`` where the group or the material
    changes. Faces without a material come first (a ``usemtl`` holds until the next one)."""
    group = np.zeros(len(corners), np.int64) if face_group is None else face_group
    order = np.argsort(face_material >= 0, kind="stable")
    keys = np.stack([group[order], face_material[order]], axis=1)
    starts = np.flatnonzero(np.concatenate([[True], (keys[1:] != keys[:-1]).any(axis=1)]))
    last_object, last_group, last_material = None, None, None
    for start, stop in zip(starts, [*starts[1:], len(order)], strict=True):
        g, m = (int(x) for x in keys[start])
        obj, name = groups[g] if groups else (None, None)
        if obj is not None and obj != last_object:
            lines.append(f"o {obj}")
            last_object, last_group, last_material = obj, None, None
        if name is not None and g != last_group:
            lines.append(f"g {name}")
        last_group = g
        if m >= 0 and m != last_material:
            lines.append(f"usemtl {material_names[m]}")
            last_material = m
        faces = order[start:stop]
        polygon = None if face_polygon is None else face_polygon[faces]
        lines += ["f " + " ".join(_corner(c) for c in row) for row in _polygons(corners[faces], polygon)]


def obj_text(positions, corners, *, uvs=None, normals=None, colors=None, face_material=None, material_names=(),
             face_polygon=None, face_group=None, groups=None, mtllib: str | None = None, header: str = "") -> str:
    """The text of an OBJ file.

    Parameters
    ----------
    positions : (#P, 3) ``v`` coordinates, written with 17 digits (exact)
    corners : (#F, 3, 3) int ``(v, vt, vn)`` per triangle corner, 0-based, -1 where none
    uvs : (#T, 2) ``vt`` coordinates, or None
    normals : (#N, 3) ``vn`` directions (6 digits), or None
    colors : (#P, 3) ``v`` colours in [0, 1] (4 digits), or None
    face_material : (#F,) int index into ``material_names`` (-1: no ``usemtl``); None: all -1
    face_polygon : (#F,) int polygon of each triangle (triangles of one polygon consecutive), or None
    face_group : (#F,) int index into ``groups`` (``(object, group)`` names, None where absent), or None
    mtllib : the MTL file name for the ``mtllib`` line, or None
    header : a comment line's text
    """
    corners = np.asarray(corners, np.int64)
    face_material = np.full(len(corners), -1, np.int64) if face_material is None else np.asarray(face_material)
    lines = [f"# {header}"] if header else []
    lines += [f"mtllib {mtllib}"] if mtllib else []
    positions = np.asarray(positions, np.float64)
    if colors is not None:
        lines += ["v " + " ".join([_number(x, 17) for x in xyz] + [_number(c, 4) for c in rgb])
                  for xyz, rgb in zip(positions.tolist(), np.asarray(colors).tolist(), strict=True)]
    else:
        _table(lines, "v", positions, 17)
    if uvs is not None:
        _table(lines, "vt", np.asarray(uvs, np.float64), 17)
    if normals is not None:
        _table(lines, "vn", np.asarray(normals, np.float64), 6)
    _face_lines(lines, corners, None if face_polygon is None else np.asarray(face_polygon), face_material,
                list(material_names), None if face_group is None else np.asarray(face_group), groups)
    return "\n".join(lines) + "\n"


def mtl_text(blocks: list[tuple[str, list[str]]]) -> str:
    """The text of an MTL file: ``(material name, statements)`` blocks in order."""
    lines = []
    for name, statements in blocks:
        lines += [f"newmtl {name}", *statements, ""]
    return "\n".join(lines)
