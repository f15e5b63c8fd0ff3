"""Binary PLY with per-vertex and per-face properties: the one writer and reader synthkit uses for
labelled and attributed meshes (``labels.ply``, ``transferred.ply``, label PLYs of ``save_mesh``).

Files are ``binary_little_endian 1.0``: float32 ``x y z``, then the vertex properties in the
order given; faces as ``list uchar int vertex_indices`` (always 3), then the face properties.
Property types are PLY's ``float`` (``<f4``), ``int`` (``<i4``) and ``uchar`` (``u1``).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from synthkit.errors import InputError

__all__ = ["ply_bytes", "read_face_property", "PLY_TYPES"]

PLY_TYPES = {"float": "<f4", "int": "<i4", "uchar": "u1", "double": "<f8", "short": "<i2", "ushort": "<u2",
             "uint": "<u4", "char": "i1", "float32": "<f4", "int32": "<i4", "uint8": "u1"}
"""PLY scalar type -> little-endian numpy dtype."""

Property = tuple[str, str, np.ndarray]
"""``(name, PLY type, values (N,))`` of one property."""


def _records(count: int, head: list, props: Sequence[Property]) -> np.ndarray:
    """Structured array of ``count`` records: the ``head`` fields, then one field per property."""
    dtype = np.dtype([*head, *[(name, PLY_TYPES[kind]) for name, kind, _ in props]])
    rec = np.empty(count, dtype=dtype)
    for name, _, values in props:
        rec[name] = np.asarray(values).reshape(count)
    return rec


def ply_bytes(V: np.ndarray, F: np.ndarray, *, vertex: Sequence[Property] = (),
              face: Sequence[Property] = ()) -> bytes:
    """A binary PLY of ``V (#V, 3)`` (stored float32) and triangles ``F (#F, 3)`` with the
    ``vertex`` and ``face`` properties, in order (module docstring)."""
    V = np.asarray(V)
    F = np.asarray(F)
    vrec = _records(len(V), [("xyz", "<f4", (3,))], vertex)
    vrec["xyz"] = V
    frec = _records(len(F), [("n", "u1"), ("idx", "<i4", (3,))], face)
    frec["n"] = 3
    frec["idx"] = F
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(V)}\nproperty float x\nproperty float y\nproperty float z\n"
        + "".join(f"property {kind} {name}\n" for name, kind, _ in vertex)
        + f"element face {len(F)}\nproperty list uchar int vertex_indices\n"
        + "".join(f"property {kind} {name}\n" for name, kind, _ in face)
        + "end_header\n"
    )
    return header.encode("ascii") + vrec.tobytes() + frec.tobytes()


def _header(path: Path) -> tuple[list[str], bytes]:
    """The header lines of a PLY file and the bytes after ``end_header``."""
    with open(path, "rb") as fh:
        if fh.readline().strip() != b"ply":
            raise InputError(f"{path}: not a PLY file")
        lines = []
        while True:
            line = fh.readline()
            if not line:
                raise InputError(f"{path}: truncated PLY header")
            lines.append(line.decode("ascii", "replace").strip())
            if lines[-1] == "end_header":
                return lines, fh.read()


def _elements(lines: list[str], path: Path) -> list[tuple[str, int, list[list[str]]]]:
    """``(name, count, property lines split)`` of each element of a header; a malformed ``element``
    or ``property`` line, or a property declared twice, is an InputError naming its line."""
    elements: list[tuple[str, int, list[list[str]]]] = []
    for number, line in enumerate(lines, start=2):  # line 1 is "ply"
        parts = line.split()
        if parts[:1] == ["element"]:
            if len(parts) != 3 or not (parts[2].isascii() and parts[2].isdigit()):
                raise InputError(f"{path}: PLY header line {number}: expected 'element <name> <count>', got {line!r}")
            elements.append((parts[1], int(parts[2]), []))
        elif parts[:1] == ["property"] and elements:
            if len(parts) != (5 if parts[1:2] == ["list"] else 3):
                raise InputError(f"{path}: PLY header line {number}: malformed property line {line!r}")
            if any(prop[-1] == parts[-1] for prop in elements[-1][2]):
                raise InputError(f"{path}: PLY header line {number}: property '{parts[-1]}' of element "
                                 f"'{elements[-1][0]}' is declared twice")
            elements[-1][2].append(parts[1:])
    return elements


def _fixed_dtype(props: list[list[str]]) -> np.dtype | None:
    """The record dtype of an element whose lists are triangles (``list uchar int``, read as 3),
    or None for a layout this reader does not take (other list types, unknown scalars)."""
    fields = []
    if sum(prop[0] == "list" for prop in props) > 1:
        return None
    for prop in props:
        if prop[0] == "list":
            if prop[1:3] not in (["uchar", "int"], ["uint8", "int32"]):
                return None
            fields += [("__count", "u1"), (prop[3], "<i4", (3,))]
        elif prop[0] in PLY_TYPES and len(prop) == 2:
            fields.append((prop[1], PLY_TYPES[prop[0]]))
        else:
            return None
    return np.dtype(fields)


def read_face_property(path: Path | str, name: str) -> np.ndarray:
    """Per-face property ``name`` ``(#F,)`` of a binary little-endian PLY with triangle faces (as
    :func:`ply_bytes` writes; the dtype is the file's). Other PLYs (ASCII, polygons, other list
    types) are read through trimesh.

    Raises
    ------
    InputError : not a PLY, a malformed header line, truncated, no face property ``name``, a value
        that is not one finite number per face.
    """
    path = Path(path)
    values = _face_property(path, name)
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        k = int(np.flatnonzero(~np.isfinite(values))[0])
        raise InputError(f"{path}: PLY face {k} has {name} {values[k]}; expected a finite number")
    return values


def _face_property(path: Path, name: str) -> np.ndarray:
    lines, body = _header(path)
    elements = _elements(lines, path)
    face_props = next((props for element, _, props in elements if element == "face"), [])
    if not any(prop[-1] == name and prop[0] != "list" for prop in face_props):
        raise InputError(f"{path}: PLY has no per-face '{name}' property")
    dtypes = [_fixed_dtype(props) for _, _, props in elements]
    if "format binary_little_endian 1.0" not in lines or any(d is None for d in dtypes):
        return _read_with_trimesh(path, name)
    offset = 0
    for (element, count, _), dtype in zip(elements, dtypes, strict=True):
        if count and not dtype.itemsize:
            raise InputError(f"{path}: PLY element '{element}' has {count} records but no properties")
        if element == "face":
            return _binary_faces(path, body, offset, count, dtype, name)
        offset += count * dtype.itemsize
    raise InputError(f"{path}: PLY has no faces")


def _binary_faces(path: Path, body: bytes, offset: int, count: int, dtype: np.dtype, name: str) -> np.ndarray:
    """Property ``name`` of the ``count`` face records of ``dtype`` at ``offset`` of a binary body."""
    if "__count" not in dtype.names:
        raise InputError(f"{path}: PLY element 'face' has no vertex_indices list")
    if len(body) < offset + count * dtype.itemsize:
        raise InputError(f"{path}: truncated PLY ({len(body)} bytes of data, "
                         f"{offset + count * dtype.itemsize} expected)")
    records = np.frombuffer(body, dtype=dtype, count=count, offset=offset)
    if count and not (records["__count"] == 3).all():
        return _read_with_trimesh(path, name)
    return records[name].copy()


def _read_with_trimesh(path: Path, name: str) -> np.ndarray:
    import trimesh

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # trimesh casts NaN and huge numbers with a RuntimeWarning; checked below
        try:
            loaded = trimesh.load(path, process=False)
        except Exception as exc:  # trimesh raises many types for corrupt files
            raise InputError(f"{path}: cannot read PLY: {type(exc).__name__}: {exc}".splitlines()[0]) from None
    raw = getattr(loaded, "metadata", {}).get("_ply_raw", {}).get("face", {}).get("data", {})
    if not isinstance(raw, dict) or name not in raw:
        raise InputError(f"{path}: PLY has no per-face '{name}' property")
    values = np.asarray(raw[name])
    if values.dtype == object or values.ndim != 2 or values.shape[1] != 1:
        raise InputError(f"{path}: PLY face property '{name}' is not one number per face")
    return values.reshape(-1)
