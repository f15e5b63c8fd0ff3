"""Sizes of input files read from their headers (or a counting pass), before anything is decoded.

A budget is checked against these sizes before a run loads its inputs, so a 30000x30000 PNG of
2.6 MB or a mesh of millions of faces is refused in milliseconds, not after gigabytes.

- images: width and height from the PNG/JPEG/TIFF header (Pillow reads only the header);
- meshes: face count from the PLY and OFF headers, the binary STL count, the GLB's JSON chunk
  (index accessor counts), or a counting pass over an OBJ's ``f`` lines (polygons counted as
  the triangles of their fans).
"""

from __future__ import annotations

import json
import re
import struct
import threading
import warnings
from pathlib import Path

__all__ = ["image_shape", "mesh_face_count"]

_PIL_LOCK = threading.Lock()
_CHUNK = 1 << 22


def image_shape(path: Path | str) -> tuple[int, int] | None:
    """``(height, width)`` from an image file's header, or None when the header cannot be read
    (the decoder then says what is wrong)."""
    from PIL import Image, UnidentifiedImageError

    with _PIL_LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pillow warns about odd tags; the decoder judges the pixels
        saved, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None  # only the header is read
        try:
            with Image.open(path) as im:
                width, height = im.size
        except (OSError, UnidentifiedImageError, ValueError, SyntaxError):
            return None
        finally:
            Image.MAX_IMAGE_PIXELS = saved
    return int(height), int(width)


def mesh_face_count(path: Path | str) -> int | None:
    """Triangles a mesh file holds, from its header or a counting pass (None when unknown)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".ply":
            return _ply_faces(path)
        if suffix == ".off":
            return _off_faces(path)
        if suffix == ".stl":
            return _stl_faces(path)
        if suffix == ".glb":
            return _glb_faces(path)
        if suffix == ".obj":
            return _obj_faces(path)
    except (OSError, ValueError, struct.error, UnicodeDecodeError, LookupError, TypeError, AttributeError):
        return None  # a header this pass cannot read: the reader says what is wrong with the file
    return None


def _ply_faces(path: Path) -> int | None:
    with open(path, "rb") as fh:
        for _ in range(200):
            line = fh.readline()
            if not line or line.strip() == b"end_header":
                break
            parts = line.split()
            if len(parts) == 3 and parts[0] == b"element" and parts[1] == b"face":
                return int(parts[2])
    return None


def _off_faces(path: Path) -> int | None:
    with open(path, "rb") as fh:
        head = fh.read(4096).decode("ascii", "replace")
    tokens = [t for line in head.splitlines() for t in line.split("#")[0].split()]
    if not tokens or not tokens[0].endswith("OFF"):
        return None
    counts = tokens[1:4] if tokens[0] == "OFF" else tokens[0][:-3].split() + tokens[1:3]
    return int(counts[1]) if len(counts) >= 2 else None


def _stl_faces(path: Path) -> int | None:
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
    if len(head) == 84:
        (count,) = struct.unpack("<I", head[80:84])
        if 84 + 50 * count == size:
            return int(count)
    return _count_lines(path, re.compile(rb"^\s*facet\b", re.MULTILINE))


def _glb_faces(path: Path) -> int | None:
    with open(path, "rb") as fh:
        header = fh.read(20)
        if len(header) < 20 or header[:4] != b"glTF":
            return None
        length, kind = struct.unpack("<II", header[12:20])
        if kind != 0x4E4F534A:  # "JSON"
            return None
        doc = json.loads(fh.read(length))
    accessors = doc.get("accessors", [])
    total = 0
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            if "indices" in prim:
                total += int(accessors[prim["indices"]]["count"]) // 3
            elif "POSITION" in prim.get("attributes", {}):
                total += int(accessors[prim["attributes"]["POSITION"]]["count"]) // 3
    return total


def _obj_faces(path: Path) -> int:
    """Triangles of an OBJ's ``f`` lines (an n-gon is n - 2 triangles), counted in chunks."""
    triangles, tail = 0, b""
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            data = tail + chunk
            cut = data.rfind(b"\n") + 1
            data, tail = data[:cut], data[cut:]
            triangles += _obj_chunk_triangles(data)
    return triangles + _obj_chunk_triangles(tail + b"\n")


_FACE_LINE = re.compile(rb"^[ \t]*f[ \t]+([^\n]*)", re.MULTILINE)


def _obj_chunk_triangles(data: bytes) -> int:
    return sum(max(len(m.split()) - 2, 0) for m in _FACE_LINE.findall(data))


def _count_lines(path: Path, pattern: re.Pattern) -> int:
    count, tail = 0, b""
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            data = tail + chunk
            cut = data.rfind(b"\n") + 1
            count += len(pattern.findall(data[:cut]))
            tail = data[cut:]
    return count + len(pattern.findall(tail))
