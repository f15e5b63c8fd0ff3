"""Small man-made meshes with known lattice vectors, the retargeting method's test inputs.

Every sample is a union of closed boxes (and a few hexahedra) laid out on an exact lattice, so the
repetition the method must find is known: ``<name>.truth.json`` beside each mesh holds the lattice
vectors in model units, the number of repetitions along each, the counts of the repeated elements
and the expected number of principal offsets. Models are in metres-like units, not normalised.
The man-made samples (bookshelf, facade, railing, stairs, sheared grid, bridge) are tessellated
the way modelled assets are (faces cut on a grid whose spacings divide the lattice periods, so
each cell repeats the same vertex layout, see :func:`box` and :func:`lattice_box`); the benchmark's
large facade is built from plain 8-vertex boxes and cylinders.

The railing has 8 balusters: in a 1-D lattice of n exact copies a feature's best match is about
equally likely in any other copy, so the offsets spread over the 2(n - 1) multiples of the period
in proportion to the pairs at each separation; with 10 balusters the top 7% of the occupied bins
(8 bins) can then hold only about 2(9 + 8 + 7 + 6) / 90 = 0.67 of the lattice offsets (measured
0.62-0.71 over seeds and tessellations), with 8 they hold 0.74-0.78.

:func:`generate` writes them all (PLY or OBJ); ``build_<name>`` functions return the arrays, so
tests can use the same geometry without files.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = [
    "SAMPLES",
    "generate",
    "box",
    "hexahedron",
    "lattice_box",
    "build_bookshelf",
    "build_facade",
    "build_railing",
    "build_stairs",
    "build_sheared_grid",
    "build_bridge",
    "build_facade_large",
]

_BOX_FACES = np.array(
    [
        [0, 2, 1], [0, 3, 2],  # z = lo (normal -z)
        [4, 5, 6], [4, 6, 7],  # z = hi (normal +z)
        [0, 1, 5], [0, 5, 4],  # y = lo
        [3, 7, 6], [3, 6, 2],  # y = hi
        [0, 4, 7], [0, 7, 3],  # x = lo
        [1, 2, 6], [1, 6, 5],  # x = hi
    ],
    dtype=np.int64,
)  # fmt: skip


def hexahedron(corners) -> tuple[np.ndarray, np.ndarray]:
    """A closed hexahedron from ``corners (8, 3)`` ordered like a box's (x fastest in the bottom
    quad ``0 1 2 3`` counter-clockwise seen from +z, top quad ``4 5 6 7`` above it).

    Returns ``(V (8, 3) float64, F (12, 3) int64)`` with outward normals for a convex, positively
    oriented hexahedron.
    """
    return np.asarray(corners, dtype=np.float64).reshape(8, 3), _BOX_FACES.copy()


def box(lo, hi, *, step=None) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned closed box ``lo (3,) .. hi (3,)`` as ``(V, F)``, outward normals.

    Without ``step``: 8 vertices, 12 triangles. With ``step (3,)`` (spacing per axis, ``None`` for
    no cut along that axis): every face is cut by the planes ``x = i * step[0]``, ``y = j *
    step[1]``, ``z = k * step[2]`` (integers ``i, j, k``) that cross it, a grid of rectangles split
    into two triangles each. The grid is global, so two boxes that differ by a translation made of
    whole steps get the same vertex layout; faces of one box share their cut edges and vertices (closed, welded).
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if step is None:
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        corners = [
            [x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
            [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1],
        ]  # fmt: skip
        return hexahedron(corners)
    cuts = []
    for a in range(3):
        s = step[a]
        inner = np.zeros(0) if s is None else np.arange(np.floor(lo[a] / s) + 1, np.ceil(hi[a] / s)) * s
        inner = inner[(inner > lo[a] + 1e-9) & (inner < hi[a] - 1e-9)]
        cuts.append(np.concatenate([[lo[a]], inner, [hi[a]]]))
    Vs, Fs, off = [], [], 0
    for a, (b, c) in enumerate([(1, 2), (2, 0), (0, 1)]):  # e_b x e_c = e_a
        gb, gc = np.meshgrid(cuts[b], cuts[c], indexing="ij")
        idx = np.arange(gb.size).reshape(gb.shape)
        q0, q1, q2, q3 = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
        tri = np.concatenate([np.stack([q0, q1, q2], -1).reshape(-1, 3), np.stack([q0, q2, q3], -1).reshape(-1, 3)])
        for val, faces in ((lo[a], tri[:, ::-1]), (hi[a], tri)):
            P = np.zeros((gb.size, 3))
            P[:, a], P[:, b], P[:, c] = val, gb.ravel(), gc.ravel()
            Vs.append(P)
            Fs.append(faces + off)
            off += len(P)
    V, inv = np.unique(np.concatenate(Vs), axis=0, return_inverse=True)  # edge vertices are exact copies
    return V, inv.reshape(-1)[np.concatenate(Fs)].astype(np.int64)


def lattice_box(frame, lo, hi, *, step=None) -> tuple[np.ndarray, np.ndarray]:
    """A closed parallelepiped: :func:`box` ``lo .. hi`` (with ``step``) built in the coordinates of
    ``frame (3, 3)`` (columns: the edge directions, e.g. lattice vectors) and mapped by it, so a
    grid step of ``1 / k`` cuts every lattice cell the same way. Outward normals."""
    V, F = box(lo, hi, step=step)
    return _outward(V @ np.asarray(frame, float).T, F)


def _outward(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flip the faces of a closed mesh whose signed volume is negative, so normals point out."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    return (V, F) if volume > 0 else (V, F[:, ::-1].copy())


def _merge(parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate ``(V, F)`` parts into one indexed mesh (no welding)."""
    Vs, Fs, off = [], [], 0
    for V, F in parts:
        Vs.append(V)
        Fs.append(F + off)
        off += len(V)
    return np.concatenate(Vs), np.concatenate(Fs)


def _cylinder(center, radius: float, height: float, sections: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed vertical (y axis) cylinder, base centre ``center (3,)``, as ``(V, F)``, outward normals."""
    c = np.asarray(center, float)
    t = np.linspace(0, 2 * np.pi, sections, endpoint=False)
    ring = np.stack([radius * np.cos(t), np.zeros_like(t), -radius * np.sin(t)], axis=1)
    bottom, top = c + ring, c + ring + [0, height, 0]
    V = np.concatenate([bottom, top, [c], [c + [0, height, 0]]])
    i = np.arange(sections)
    j = (i + 1) % sections
    n = sections
    side = np.concatenate([np.stack([i, j, j + n], 1), np.stack([i, j + n, i + n], 1)])
    caps = np.concatenate([np.stack([np.full(n, 2 * n), j, i], 1), np.stack([np.full(n, 2 * n + 1), i + n, j + n], 1)])
    return V, np.concatenate([side, caps]).astype(np.int64)


RAILING_STEP = (0.03, 0.05, 0.03)  # 6 per period
STAIRS_STEP = (0.05, 0.034, 0.056)  # 5 per rise and per run
SHEARED_STEP = (0.03, 0.04, 0.03)  # x: 10 per 0.30, 4 per 0.12; z: 10 per 0.30
SHEARED_SLAB_DIVISIONS = 10
BRIDGE_STEP = (0.05, 0.05, 0.05)  # 12 per span


def build_bookshelf(cols: int = 4, rows: int = 3, *, step=(0.05, 0.05, 0.05)) -> tuple[np.ndarray, np.ndarray, dict]:
    """A bookshelf: ``rows`` x ``cols`` cells between full-width boards and per-row dividers,
    on a plinth, with a crown on top. Lattice: (0.40, 0, 0) per column, (0, 0.35, 0) per row.

    Tessellated like a modelled asset (see :func:`box`, ``step``; ``None`` gives plain 8-vertex
    boxes): the default spacings divide the lattice periods, so every cell carries the same vertex
    layout, the exactly repeated vertices the paper's real models bring as features."""
    px, py, t, depth = 0.40, 0.35, 0.02, 0.30
    width = cols * px
    parts = [box([-t, -0.08, 0.0], [width + t, 0.0, depth], step=step)]  # plinth
    for j in range(rows + 1):
        parts.append(box([-t, j * py, 0.0], [width + t, j * py + t, depth], step=step))  # board j
    for j in range(rows):
        for i in range(cols + 1):
            parts.append(box([i * px - t / 2, j * py + t, 0.0], [i * px + t / 2, (j + 1) * py, depth], step=step))
    top = rows * py + t
    parts.append(box([-t - 0.02, top, -0.02], [width + t + 0.02, top + 0.04, depth + 0.02], step=step))  # crown
    V, F = _merge(parts)
    truth = {
        "lattice": [[px, 0.0, 0.0], [0.0, py, 0.0]],
        "repeats": [cols, rows],
        "counts": {"boards": rows + 1, "cells": rows * cols, "dividers": (cols + 1) * rows},
        "board_size": [width + 2 * t, t, depth],
        "board_pitch": py,
        "principal_offsets": 2,
    }
    return V, F, truth


def build_facade(cols: int = 5, floors: int = 3, *, step=(0.0625, 0.075, None)) -> tuple[np.ndarray, np.ndarray, dict]:
    """A wall with a ``floors`` x ``cols`` lattice of framed windows with sills, on a base band
    with a cornice. Lattice: (0.5, 0, 0), (0, 0.6, 0).

    Tessellated like a modelled asset (see :func:`box`, ``step``; ``None`` gives plain 8-vertex
    boxes): the default spacings divide the lattice periods (8 steps each), so every cell carries
    the same vertex layout."""
    wx, wy = 0.5, 0.6
    wall_t, fw, fd = 0.10, 0.03, 0.04
    width, height = cols * wx, floors * wy
    parts = [box([0.0, 0.0, -wall_t], [width, height, 0.0], step=step)]
    parts.append(box([-0.02, -0.10, -wall_t], [width + 0.02, 0.0, 0.05], step=step))  # base band
    parts.append(box([-0.04, height, -wall_t], [width + 0.04, height + 0.06, 0.08], step=step))  # cornice
    win_w, win_h = 0.26, 0.34
    for j in range(floors):
        for i in range(cols):
            x0, y0 = i * wx + (wx - win_w) / 2, j * wy + 0.15
            x1, y1 = x0 + win_w, y0 + win_h
            parts += [
                box([x0, y0, 0.0], [x1, y0 + fw, fd], step=step),
                box([x0, y1 - fw, 0.0], [x1, y1, fd], step=step),
                box([x0, y0 + fw, 0.0], [x0 + fw, y1 - fw, fd], step=step),
                box([x1 - fw, y0 + fw, 0.0], [x1, y1 - fw, fd], step=step),
                box([(x0 + x1) / 2 - 0.01, y0 + fw, 0.0], [(x0 + x1) / 2 + 0.01, y1 - fw, fd / 2], step=step),
                box([x0 - 0.03, y0 - 0.04, 0.0], [x1 + 0.03, y0, fd + 0.04], step=step),  # sill
            ]
    V, F = _merge(parts)
    truth = {
        "lattice": [[wx, 0.0, 0.0], [0.0, wy, 0.0]],
        "repeats": [cols, floors],
        "counts": {"windows": cols * floors, "floors": floors, "columns": cols},
        "principal_offsets": 2,
    }
    return V, F, truth


def build_railing(n_posts: int = 8, *, step=RAILING_STEP) -> tuple[np.ndarray, np.ndarray, dict]:
    """A railing: ``n_posts`` turned-looking balusters (stacked boxes) between a bottom and a top
    rail. Lattice: (0.18, 0, 0).

    Tessellated like a modelled asset (see :func:`box`; ``None`` gives plain boxes): the x spacing
    divides the period, so every baluster and its stretch of rail carry the same vertex layout."""
    p = 0.18
    length = (n_posts - 1) * p
    parts = [box([-0.06, 0.0, -0.05], [length + 0.06, 0.05, 0.05], step=step)]  # bottom rail
    parts.append(box([-0.06, 0.62, -0.06], [length + 0.06, 0.68, 0.06], step=step))  # hand rail
    profile = [(0.05, 0.05, 0.12), (0.12, 0.02, 0.40), (0.40, 0.045, 0.48), (0.48, 0.03, 0.55), (0.55, 0.04, 0.62)]
    for i in range(n_posts):
        x = i * p
        for y0, r, y1 in profile:
            parts.append(box([x - r, y0, -r], [x + r, y1, r], step=step))
    V, F = _merge(parts)
    truth = {
        "lattice": [[p, 0.0, 0.0]],
        "repeats": [n_posts],
        "counts": {"balusters": n_posts},
        "principal_offsets": 1,
    }
    return V, F, truth


def build_stairs(n_steps: int = 7, *, step=STAIRS_STEP) -> tuple[np.ndarray, np.ndarray, dict]:
    """A straight flight of ``n_steps`` blocks between two stringers. Lattice: (0, 0.17, 0.28).

    Tessellated like a modelled asset (see :func:`box`; ``None`` gives plain boxes): the y and z
    spacings divide the rise and the run, so every step carries the same vertex layout."""
    h, d, w = 0.17, 0.28, 0.5
    parts = []
    for i in range(n_steps):
        parts.append(box([0.0, i * h, i * d], [w, (i + 1) * h, (i + 1) * d], step=step))
        for x0 in (-0.05, w):  # stringer segments, one per step, so the flight stays exactly periodic
            parts.append(box([x0, i * h + 0.04, i * d], [x0 + 0.05, (i + 1) * h + 0.08, (i + 1) * d], step=step))
    V, F = _merge(parts)
    truth = {
        "lattice": [[0.0, h, d]],
        "repeats": [n_steps],
        "counts": {"steps": n_steps},
        "principal_offsets": 1,
    }
    return V, F, truth


def build_sheared_grid(
    n1: int = 6, n2: int = 3, *, step=SHEARED_STEP, slab_divisions: int | None = SHEARED_SLAB_DIVISIONS
) -> tuple[np.ndarray, np.ndarray, dict]:
    """A parallelogram slab carrying an ``n1`` x ``n2`` sheared lattice of studs (a post with a cap).
    Lattice: (0.30, 0, 0) and (0.12, 0, 0.30): 68 degrees apart.

    Tessellated like a modelled asset (``None`` gives plain boxes and an 8-vertex slab): the studs
    on the axis grid ``step`` (see :func:`box`), whose x spacing divides both lattice vectors' x
    components and whose z spacing divides 0.30; the slab on its own sheared grid, each lattice cell
    cut into ``slab_divisions`` x ``slab_divisions`` parallelograms (:func:`lattice_box`)."""
    v1, v2 = np.array([0.30, 0.0, 0.0]), np.array([0.12, 0.0, 0.30])
    lo = -0.5 * (v1 + v2)
    if slab_divisions is None:
        quad = [lo, lo + n1 * v1, lo + n1 * v1 + n2 * v2, lo + n2 * v2]
        parts = [_outward(*hexahedron([q + [0, -0.06, 0] for q in quad] + quad))]
    else:
        frame = np.stack([v1, [0.0, 1.0, 0.0], v2], axis=1)
        k = 1.0 / slab_divisions
        parts = [lattice_box(frame, [-0.5, -0.06, -0.5], [n1 - 0.5, 0.0, n2 - 0.5], step=(k, None, k))]
    for i in range(n1):
        for j in range(n2):
            q = i * v1 + j * v2
            parts.append(box(q + [-0.04, 0.0, -0.04], q + [0.04, 0.12, 0.04], step=step))
            parts.append(box(q + [-0.07, 0.12, -0.03], q + [0.07, 0.16, 0.03], step=step))
    V, F = _merge(parts)
    truth = {
        "lattice": [v1.tolist(), v2.tolist()],
        "repeats": [n1, n2],
        "counts": {"studs": n1 * n2},
        "principal_offsets": 2,
    }
    return V, F, truth


def build_bridge(spans: int = 5, *, step=BRIDGE_STEP) -> tuple[np.ndarray, np.ndarray, dict]:
    """A road bridge: a deck on ``spans + 1`` piers with a guard post above each pier and a
    parapet rail. Lattice: (0.6, 0, 0).

    Tessellated like a modelled asset (see :func:`box`; ``None`` gives plain boxes): the x spacing
    divides the span, so every span carries the same vertex layout."""
    p = 0.6
    length = spans * p
    parts = [box([-0.1, 0.0, -0.3], [length + 0.1, 0.06, 0.3], step=step)]  # deck
    parts.append(box([-0.1, 0.16, 0.24], [length + 0.1, 0.19, 0.28], step=step))  # parapet rail, one side
    for i in range(spans + 1):
        x = i * p
        parts.append(box([x - 0.05, -0.5, -0.2], [x + 0.05, 0.0, 0.2], step=step))  # pier
        parts.append(box([x - 0.12, -0.56, -0.25], [x + 0.12, -0.5, 0.25], step=step))  # footing
        parts.append(box([x - 0.02, 0.06, 0.24], [x + 0.02, 0.16, 0.28], step=step))  # guard post
        if i < spans:
            parts.append(box([x + 0.2, 0.06, -0.01], [x + 0.4, 0.07, 0.01], step=step))  # dashed lane marking
    V, F = _merge(parts)
    truth = {
        "lattice": [[p, 0.0, 0.0]],
        "repeats": [spans + 1],
        "counts": {"piers": spans + 1},
        "principal_offsets": 1,
    }
    return V, F, truth


def build_facade_large(cols: int = 6, floors: int = 4, sections: int = 24) -> tuple[np.ndarray, np.ndarray, dict]:
    """The benchmark input (about 20k triangles): the facade, each window with a balcony of eight
    round balusters (``sections``-sided cylinders) and a rail. Lattice: (0.5, 0, 0), (0, 0.6, 0)."""
    V, F, truth = build_facade(cols, floors, step=None)
    parts = [(V, F)]
    wx, wy = 0.5, 0.6
    for j in range(floors):
        for i in range(cols):
            x0, y0 = i * wx + 0.08, j * wy + 0.05
            for k in range(8):
                parts.append(_cylinder([x0 + 0.02 + k * 0.0457, y0, 0.12], 0.008, 0.12, sections))
            parts.append(box([x0, y0 + 0.12, 0.11], [x0 + 0.36, y0 + 0.135, 0.13]))
            parts.append(box([x0, y0 - 0.01, 0.0], [x0 + 0.36, y0, 0.14]))  # balcony slab
    V, F = _merge(parts)
    truth = dict(truth, counts={"windows": cols * floors, "balconies": cols * floors})
    return V, F, truth


SAMPLES: dict[str, tuple[Callable[[], tuple[np.ndarray, np.ndarray, dict]], str]] = {
    "bookshelf": (build_bookshelf, ".obj"),
    "facade": (build_facade, ".ply"),
    "railing": (build_railing, ".obj"),
    "stairs": (build_stairs, ".ply"),
    "sheared_grid": (build_sheared_grid, ".ply"),
    "bridge": (build_bridge, ".obj"),
    "facade_large": (build_facade_large, ".ply"),
}
"""Sample name -> (builder, file suffix)."""


def generate(out_dir: Path) -> list[Path]:
    """Write every sample as ``<name>.<obj|ply>`` plus ``<name>.truth.json`` into ``out_dir``.

    Returns the written paths (meshes and truth files, in :data:`SAMPLES` order).
    """
    import trimesh

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, (builder, suffix) in SAMPLES.items():
        V, F, truth = builder()
        mesh_path = out_dir / f"retarget-{name}{suffix}"
        data = trimesh.Trimesh(V, F, process=False).export(file_type=suffix[1:])  # input files, as trimesh writes them
        mesh_path.write_bytes(data.encode() if isinstance(data, str) else data)
        truth = dict(truth, mesh=mesh_path.name, n_faces=int(len(F)), units="model")
        truth_path = out_dir / f"retarget-{name}.truth.json"
        truth_path.write_text(json.dumps(truth, indent=2) + "\n")
        written += [mesh_path, truth_path]
    return written
