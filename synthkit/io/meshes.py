"""Reading and writing meshes through trimesh: the only place meshes touch files.

``load_mesh`` returns one ``trimesh.Trimesh`` (a scene of several geometries is merged with its
transforms applied) and refuses missing, unreadable or degenerate input with an
:class:`~synthkit.errors.InputError` naming the file. ``save_mesh`` writes by suffix (.obj, .ply,
.glb, .off, .stl), optionally with an int32 per-face ``label`` property in PLY.

trimesh reports trouble with the files a mesh names (a PLY's ``comment TextureFile``, an OBJ's
``mtllib`` and the textures its materials name) through :mod:`logging`, a missing texture with a
whole traceback, and goes on loading. ``load_mesh`` holds trimesh's log records during the load
and says instead, once per named file, ``<path>: texture file x.png named by the mesh is missing;
loading without texture`` (or ``material file ... loading without materials``) as a warning of
its own logger; trimesh's other records go to DEBUG level.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import trimesh

from synthkit.errors import InputError
from synthkit.io._capture import check_readable
from synthkit.io.atomic import write_bytes_atomic
from synthkit.io.ply import ply_bytes, read_face_property

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".ply", ".glb", ".gltf", ".off", ".stl")


def load_mesh(path: Path | str, *, process: bool = False) -> trimesh.Trimesh:
    """Load a triangle mesh from ``path``.

    Parameters
    ----------
    path : path to an OBJ, PLY, GLB/glTF, OFF or STL file.
    process : let trimesh merge duplicate vertices (False keeps the file's vertex order).

    Returns
    -------
    mesh : trimesh.Trimesh with ``vertices (#V, 3) float64`` and ``faces (#F, 3) int64``. Scenes
        are merged into one mesh in world coordinates (UVs and textures are kept only for a single
        geometry); ``mesh.metadata["merged_geometries"]`` says how many geometries were merged.

    Raises
    ------
    InputError : the file is missing, unreadable (permission denied, a folder), has no triangles,
        or has non-finite vertices.

    A texture or material file the mesh names but that is missing gives one warning (see the
    module docstring) and the mesh is loaded without it.
    """
    path = Path(path)
    check_readable(path, "mesh")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(f"{path}: unsupported mesh format {path.suffix!r} (use {', '.join(MESH_SUFFIXES)})")
    loaded = trimesh_load(path, process=process)
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        if not geoms:
            raise InputError(f"{path}: file holds no triangle mesh")
        mesh = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
        mesh.metadata["merged_geometries"] = len(geoms)
    elif isinstance(loaded, trimesh.Trimesh):
        mesh = loaded
        mesh.metadata["merged_geometries"] = 1
    elif isinstance(loaded, trimesh.PointCloud):
        raise InputError(f"{path}: mesh has no faces ({len(loaded.vertices)} vertices, no triangles)")
    else:
        raise InputError(f"{path}: file holds a {type(loaded).__name__}, not a triangle mesh")
    check_mesh(mesh.vertices, mesh.faces, source=path)
    if path.suffix.lower() == ".obj" and mesh.visual.kind == "texture" and not _names_material(path):
        mesh.visual.material.image = None  # trimesh's 2x2 stand-in: the file has UVs but no material
    return mesh


def _names_material(obj: Path) -> bool:
    """Whether some line of the OBJ ``obj`` is a ``usemtl`` statement."""
    with obj.open("rb") as f:
        return any(line.lstrip().startswith(b"usemtl") for line in f)


def trimesh_load(path: Path, *, process: bool = False):
    """``trimesh.load(path)`` with trimesh's log records held and reported in our words (module
    docstring) and the Python warnings of its parsers (casts of NaN, overflow) at DEBUG level; a
    file trimesh cannot read, or whose faces name vertices it does not hold, is an InputError
    naming it."""
    with _trimesh_records() as records, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            loaded = trimesh.load(path, process=process)
        except Exception as exc:  # trimesh raises many types for corrupt files
            raise InputError(f"{path}: cannot read mesh: {type(exc).__name__}: {exc}".splitlines()[0]) from None
    for warning in caught:
        log.debug("%s: trimesh: %s", path, warning.message)
    _report_trimesh_records(records, path)
    geoms = loaded.geometry.values() if isinstance(loaded, trimesh.Scene) else [loaded]
    for geom in geoms:
        if isinstance(geom, trimesh.Trimesh):
            _check_face_indices(np.asarray(geom.faces), len(geom.vertices), path)
    return loaded


def _check_face_indices(F: np.ndarray, n_vertices: int, source: Path | str) -> None:
    """InputError naming the first face of ``F`` that names a vertex outside ``[0, n_vertices)``."""
    bad = (F < 0) | (F >= n_vertices)
    if F.size and bad.any():
        k = int(np.flatnonzero(bad.any(axis=-1))[0])
        raise InputError(f"{source}: face {k} names vertex {int(F[k][bad[k]][0])}, out of range "
                         f"[0, {n_vertices}) ({int(bad.any(axis=-1).sum())} such faces)")


class _Collect(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


_TRIMESH_LOCK = threading.Lock()


@contextlib.contextmanager
def _trimesh_records() -> Iterator[list[logging.LogRecord]]:
    """Hold every record of the ``trimesh`` loggers during the block (none is printed) and yield
    the list they are collected in."""
    logger = logging.getLogger("trimesh")
    collect = _Collect()
    with _TRIMESH_LOCK:
        saved = (logger.handlers[:], logger.level, logger.propagate)
        logger.handlers[:] = [collect]
        logger.setLevel(logging.DEBUG)
        logger.propagate = False
        try:
            yield collect.records
        finally:
            logger.handlers[:], logger.propagate = saved[0], saved[2]
            logger.setLevel(saved[1])


def _report_trimesh_records(records: list[logging.LogRecord], path: Path) -> None:
    """One warning per texture or material file the mesh names that trimesh could not load; the
    other records at DEBUG level."""
    said: set[str] = set()
    for record in records:
        message = record.getMessage()
        exc = record.exc_info[1] if record.exc_info else None
        if message.startswith("unable to load materials from"):
            kind, name = "material", message.split(":", 1)[-1].strip()
        elif "image" in message and exc is not None:
            kind, name = "texture", str(exc) if isinstance(exc, FileNotFoundError) else ""
        else:
            log.debug("%s: trimesh: %s", path, message)
            continue
        without = "materials" if kind == "material" else "texture"
        if name and not (path.parent / name).exists():
            warning = f"{kind} file {name} named by the mesh is missing; loading without {without}"
        else:
            reason = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}" if exc else "unreadable"
            warning = (f"{kind} file {name or '(unnamed)'} named by the mesh cannot be read ({reason}); "
                       f"loading without {without}")
        if warning not in said:
            said.add(warning)
            log.warning("%s: %s", path, warning)


def check_mesh(V: np.ndarray, F: np.ndarray, *, source: Path | str = "mesh") -> None:
    """Raise InputError unless ``V (#V, 3)`` is finite and ``F (#F, 3)`` indexes it with >= 1 face,
    no face names a vertex twice (a self-loop: malformed topology) and some face has an area
    (zero-area faces among others are kept: real assets have a few)."""
    V = np.asarray(V)
    F = np.asarray(F)
    if F.ndim != 2 or F.shape[0] == 0:
        raise InputError(f"{source}: mesh has no faces")
    if F.shape[1] != 3:
        raise InputError(f"{source}: faces have {F.shape[1]} corners; only triangles are supported")
    if V.ndim != 2 or V.shape[1] != 3 or V.shape[0] == 0:
        raise InputError(f"{source}: mesh has no 3-D vertices")
    if not np.isfinite(V).all():
        bad = (~np.isfinite(V)).any(axis=1)
        raise InputError(f"{source}: {int(bad.sum())} vertices have NaN or infinite coordinates "
                         f"(first: vertex {int(np.flatnonzero(bad)[0])})")
    _check_face_indices(F, V.shape[0], source)
    looped = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    if looped.any():
        k = int(np.flatnonzero(looped)[0])
        raise InputError(f"{source}: {int(looped.sum())} of {len(F)} faces name one vertex twice "
                         f"(first: face {k}, vertices {F[k].tolist()})")
    T = V[F].astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):  # huge coordinates: an infinite area is an area
        area = np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    if not (area > 0).any():
        raise InputError(f"{source}: every triangle has zero area ({len(F)} faces)")


def save_mesh(
    mesh: trimesh.Trimesh,
    path: Path | str,
    *,
    face_labels: np.ndarray | None = None,
    face_colors: np.ndarray | None = None,
) -> None:
    """Write ``mesh`` to ``path`` (format by suffix), atomically.

    ``face_labels (#F,) int`` is stored as an int32 per-face ``label`` property, and with it
    ``face_colors (#F, 3) uint8`` as per-face ``red green blue`` (PLY only; for other formats, or
    colours without labels, it raises ValueError).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise ValueError(f"unsupported mesh format {suffix!r}")
    if face_colors is not None and face_labels is None:
        raise ValueError("face colours are stored beside face labels only")
    if face_labels is not None:
        if suffix != ".ply":
            raise ValueError("face labels are stored in PLY files only")
        labels = np.asarray(face_labels)
        if labels.shape != (len(mesh.faces),):
            raise ValueError(f"face_labels has shape {labels.shape}, expected ({len(mesh.faces)},)")
        colors = None
        if face_colors is not None:
            colors = np.asarray(face_colors)
            if colors.shape != (len(mesh.faces), 3):
                raise ValueError(f"face_colors has shape {colors.shape}, expected ({len(mesh.faces)}, 3)")
            colors = colors.astype(np.uint8)
        data = _ply_with_face_labels(mesh, labels.astype(np.int32), colors)
    elif suffix == ".obj":  # geometry only; meshes with their appearance go through io.assets
        from synthkit.io.obj import obj_text

        corners = np.full((len(mesh.faces), 3, 3), -1, np.int64)
        corners[..., 0] = mesh.faces
        data = obj_text(mesh.vertices, corners, header="written by synthkit")
    else:
        data = mesh.export(file_type=suffix.lstrip("."))
    write_bytes_atomic(path, data.encode() if isinstance(data, str) else data)


def load_face_labels(path: Path | str) -> np.ndarray:
    """Per-face ``label`` property of a PLY written by :func:`save_mesh` (or any PLY with one), as
    ``(#F,) int32``."""
    return read_face_property(Path(path), "label").astype(np.int32)


def _ply_with_face_labels(mesh: trimesh.Trimesh, labels: np.ndarray, colors: np.ndarray | None = None) -> bytes:
    """Binary little-endian PLY: float32 xyz, triangles with an int32 ``label`` per face and, with
    ``colors (#F, 3) uint8``, ``uchar red green blue``."""
    face = [("label", "int", labels)]
    if colors is not None:
        face += [(c, "uchar", colors[:, k]) for k, c in enumerate(("red", "green", "blue"))]
    return ply_bytes(mesh.vertices, mesh.faces, face=face)
