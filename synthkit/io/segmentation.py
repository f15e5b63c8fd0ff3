"""Segmentation files: labelled PLY meshes, Princeton ``.seg`` face labels, OBJ polylines.

All writes are atomic (a temporary file beside the target, then renamed).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from synthkit.errors import InputError
from synthkit.io.atomic import write_bytes_atomic
from synthkit.io.ply import ply_bytes

_LABEL = re.compile(rb"[-+]?[0-9]+")

RGB = ("red", "green", "blue")
"""PLY's colour property names."""

__all__ = ["write_labels_ply", "write_seg", "read_seg", "write_polylines_obj", "write_point_polylines_obj"]


def write_labels_ply(path, V, F, face_labels, vertex_labels, face_colors, vertex_colors) -> None:
    """Binary PLY of ``V (#V, 3)``, ``F (#F, 3)`` with int32 ``label`` and uchar ``red green blue``
    on both vertices (``vertex_labels (#V,)``, ``vertex_colors (#V, 3) uint8``) and faces
    (``face_labels (#F,)``, ``face_colors (#F, 3) uint8``)."""
    def props(labels, colors):
        colors = np.asarray(colors)
        return [("label", "int", labels), *[(c, "uchar", colors[:, k]) for k, c in enumerate(RGB)]]

    data = ply_bytes(V, F, vertex=props(vertex_labels, vertex_colors), face=props(face_labels, face_colors))
    write_bytes_atomic(Path(path), data)


def write_seg(path, face_labels) -> None:
    """One integer face label per line (the Princeton Segmentation Benchmark's ``.seg``)."""
    labels = np.asarray(face_labels, np.int64).reshape(-1)
    write_bytes_atomic(Path(path), "".join(f"{v}\n" for v in labels.tolist()).encode("ascii"))


def read_seg(path, n_faces: int | None = None) -> np.ndarray:
    """Face labels ``(#F,) int64`` of a ``.seg`` file (one integer per line; blank lines and ``#``
    comments skipped); InputError naming the file, and the line where one is at fault, when it is
    unreadable, not text, holds something other than an int32 label, no label, or the wrong count."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read segmentation: {exc.strerror or exc}") from None
    labels = [_seg_label(path, number, line) for number, line in enumerate(data.split(b"\n"), start=1)]
    labels = [label for label in labels if label is not None]
    if not labels:
        raise InputError(f"{path}: segmentation holds no labels")
    if n_faces is not None and len(labels) != n_faces:
        raise InputError(f"{path}: {len(labels)} labels for {n_faces} faces")
    return np.array(labels, np.int64)


def _seg_label(path: Path, number: int, line: bytes) -> int | None:
    """The label on line ``number`` of a ``.seg`` file, None for a blank or comment line."""
    token = line.split(b"#", 1)[0].strip()
    if not token:
        return None
    if not _LABEL.fullmatch(token) or not -(2**31) <= int(token) < 2**31:
        shown = token[:24].decode("ascii", "backslashreplace")
        raise InputError(f"{path}: line {number}: {shown!r} is not an integer face label")
    return int(token)


def write_polylines_obj(path, V, polylines) -> None:
    """OBJ with the vertices ``V (#V, 3)`` that ``polylines`` (index arrays) use, one ``l`` record each."""
    V = np.asarray(V, np.float64)
    used = np.unique(np.concatenate(polylines)) if polylines else np.zeros(0, np.int64)
    remap = np.full(len(V), -1, np.int64)
    remap[used] = np.arange(1, len(used) + 1)
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V[used].tolist()]
    lines += ["l " + " ".join(map(str, remap[p].tolist())) + "\n" for p in polylines]
    write_bytes_atomic(Path(path), "".join(lines).encode("ascii"))


def write_point_polylines_obj(path, curves) -> None:
    """OBJ with one ``l`` record per curve of ``curves`` (each ``(m, 3)`` points; a closed curve, whose
    last point equals its first, reuses its first vertex)."""
    lines, start = [], 1
    for c in curves:
        c = np.asarray(c, np.float64)
        closed = len(c) > 2 and np.array_equal(c[0], c[-1])
        pts = c[:-1] if closed else c
        lines += [f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in pts.tolist()]
        idx = list(range(start, start + len(pts))) + ([start] if closed else [])
        lines.append("l " + " ".join(map(str, idx)) + "\n")
        start += len(pts)
    write_bytes_atomic(Path(path), "".join(lines).encode("ascii"))
