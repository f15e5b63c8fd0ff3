"""Signals carried by meshes and images for surface-by-numbers' transfer: vertex colours, PLY
vertex properties, textures through UVs, and image regions as flat grids.

Writes are atomic (a temporary file beside the target, then renamed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from synthkit.errors import InputError
from synthkit.io.atomic import write_bytes_atomic
from synthkit.io.ply import ply_bytes, read_face_property

__all__ = [
    "vertex_colors", "vertex_attribute", "texture_of", "image_grid", "write_signal_ply", "read_face_labels",
]


def vertex_colors(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """``(#V, 3)`` float RGB in [0, 1] of a mesh with vertex colours; None otherwise."""
    if mesh.visual.kind != "vertex":
        return None
    return np.asarray(mesh.visual.vertex_colors, np.float64)[:, :3] / 255.0


def vertex_attribute(mesh: trimesh.Trimesh, name: str) -> np.ndarray | None:
    """``(#V, C)`` float64 of the PLY vertex property ``name``, or of the properties ``name_*``
    (in file order) as one vector; None when the file has neither."""
    raw = mesh.metadata.get("_ply_raw", {}).get("vertex", {}).get("data")
    if not isinstance(raw, dict):
        return None
    keys = [name] if name in raw else [k for k in raw if k.startswith(name + "_")]
    if not keys:
        return None
    cols = [np.asarray(raw[k], np.float64).reshape(len(mesh.vertices), -1) for k in keys]
    return np.concatenate(cols, axis=1)


def texture_of(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray] | None:
    """``(uv (#V, 2), image (H, W, 3) float in [0, 1])`` of a textured mesh; None without UVs or image."""
    visual = mesh.visual
    if visual.kind != "texture" or visual.uv is None or len(visual.uv) != len(mesh.vertices):
        return None
    image = getattr(visual.material, "image", None)
    if image is None:
        image = getattr(visual.material, "baseColorTexture", None)
    if image is None:
        return None
    img = np.asarray(image.convert("RGB"), np.float64) / 255.0
    return np.asarray(visual.uv, np.float64), img


def image_grid(mask: np.ndarray, *, width: float, resolution: int):
    """A flat grid over the true pixels of ``mask (H, W) bool``: ``V (n, 3)`` (x right, y up; the
    image's width spans ``width`` units), ``F (m, 3)`` and per-vertex ``uv (n, 2)`` into the image.
    Cells are ``ceil(max(H, W) / resolution)`` pixels; a cell is kept when its four corner pixels
    are in the mask. ValueError when no cell is."""
    H, W = mask.shape
    step = max(1, int(np.ceil(max(H, W) / resolution)))
    xs, ys = np.arange(0, W, step), np.arange(0, H, step)
    gx, gy = np.meshgrid(xs, ys)
    inside = mask[gy, gx]
    nx = len(xs)
    idx = np.arange(gx.size).reshape(gy.shape)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    ok = (inside[:-1, :-1] & inside[:-1, 1:] & inside[1:, :-1] & inside[1:, 1:]).ravel()
    if not ok.any() or nx < 2:
        raise ValueError("region holds no full grid cell")
    lower = np.stack([c.ravel(), b.ravel(), a.ravel()], 1)[ok]
    upper = np.stack([c.ravel(), d.ravel(), b.ravel()], 1)[ok]
    F = np.concatenate([lower, upper])
    px = (gx.ravel() + 0.5).astype(np.float64)
    py = (gy.ravel() + 0.5).astype(np.float64)
    V = np.stack([px * width / W, (H - py) * width / W, np.zeros(len(px))], 1)
    uv = np.stack([px / W, 1.0 - py / H], 1)
    return V, F, uv


def write_signal_ply(path, V, F, colors, attributes: dict[str, np.ndarray] | None = None) -> None:
    """Binary PLY of ``V (#V, 3)``, ``F (#F, 3)`` with uchar ``red green blue`` from ``colors
    (#V, 3) uint8`` and float properties ``<name>`` (one column) or ``<name>_<k>`` per column."""
    colors = np.asarray(colors)
    props = [(c, "uchar", colors[:, k]) for k, c in enumerate(("red", "green", "blue"))]
    for name, values in (attributes or {}).items():
        values = np.asarray(values, np.float32).reshape(len(V), -1)
        names = [name] if values.shape[1] == 1 else [f"{name}_{k}" for k in range(values.shape[1])]
        props += [(n, "float", values[:, k]) for k, n in enumerate(names)]
    write_bytes_atomic(path, ply_bytes(V, F, vertex=props))


def read_face_labels(path, n_faces: int) -> np.ndarray:
    """Face labels ``(#F,) int64`` of a ``.seg`` file or of a PLY's per-face ``label`` property
    (``labels.ply`` of a segment run); InputError when unreadable, without labels or of the wrong
    length."""
    from synthkit.io.segmentation import read_seg

    path = Path(path)
    if path.suffix.lower() != ".ply":
        return read_seg(path, n_faces)
    labels = read_face_property(path, "label").astype(np.int64)
    if len(labels) != n_faces:
        raise InputError(f"{path}: {len(labels)} labels for {n_faces} faces")
    return labels
