"""A modular building made of lattice pieces, the example of petri-synth.

The building spans [0, 12] x [0, 12] x [0, 4] (X, Y up, Z towards the viewer) and is a lattice of
6 x 4 x 2 units of size 2 x 3 x 2 with its corner at the origin: floor slabs straddle the floor
planes, long walls, a cornice and corner pilasters span many units and are cut by the lattice,
while windows, balconies, shop windows and a door sit inside single units. Everything is a union
of axis-aligned boxes with exact coordinates, each side subdivided at the lattice planes, so the
lattice pieces repeat exactly and neighbouring pieces share their boundary vertices.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

UNIT = (2.0, 3.0, 2.0)
COUNTS = (6, 4, 2)
ORIGIN = (0.0, 0.0, 0.0)


def box(lo, hi, *, unit=UNIT, detail: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Surface of the axis-aligned box ``[lo, hi]`` as a grid of triangles, outward facing.

    Each side is subdivided at every lattice plane (multiples of ``unit``) strictly inside the box,
    with the same diagonal in every grid rectangle, so the lattice never splits a triangle and the
    pieces of a long box are translated copies of each other. ``detail`` further splits every grid
    interval into that many equal parts. Vertices are not shared between sides.
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    breaks = []
    for a in range(3):
        inner = np.arange(np.floor(lo[a] / unit[a]) + 1, np.ceil(hi[a] / unit[a])) * unit[a]
        b = np.unique(np.concatenate([[lo[a], hi[a]], inner[(inner > lo[a]) & (inner < hi[a])]]))
        t = np.arange(detail) / detail
        breaks.append(np.append((b[:-1, None] + t[None, :] * np.diff(b)[:, None]).ravel(), b[-1]))
    Vs, Fs, off = [], [], 0
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3  # (b, c, a) is right-handed
        gb, gc = np.meshgrid(breaks[b], breaks[c], indexing="ij")
        nb, nc = gb.shape
        q = np.arange(nb * nc).reshape(nb, nc)
        v00, v10, v11, v01 = q[:-1, :-1].ravel(), q[1:, :-1].ravel(), q[1:, 1:].ravel(), q[:-1, 1:].ravel()
        for side, value in ((0, lo[a]), (1, hi[a])):
            V = np.zeros((nb * nc, 3))
            V[:, a], V[:, b], V[:, c] = value, gb.ravel(), gc.ravel()
            if side:  # normal +a: counter-clockwise in (b, c)
                F = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
            else:
                F = np.concatenate([np.stack([v00, v11, v10], 1), np.stack([v00, v01, v11], 1)])
            Vs.append(V)
            Fs.append(F + off)
            off += len(V)
    return np.concatenate(Vs), np.concatenate(Fs)


def building(
    *, floors: int = COUNTS[1], columns: int = COUNTS[0], depth: int = COUNTS[2], detail: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """``(V, F)`` of the building: ``columns`` x ``floors`` x ``depth`` units, every box side subdivided
    ``detail`` times more finely than the lattice (for large benchmark examples)."""
    ux, uy, uz = UNIT
    W, H, D = columns * ux, floors * uy, depth * uz
    boxes = []
    # floor slabs straddling the floor planes (bottom and roof inside the box)
    boxes.append(((0, 0, 0), (W, 0.2, D)))
    for f in range(1, floors):
        boxes.append(((0, f * uy - 0.1, 0), (W, f * uy + 0.1, D)))
    boxes.append(((0, H - 0.2, 0), (W, H, D)))
    # walls
    boxes.append(((0, 0, D - 0.4), (W, H, D - 0.2)))
    boxes.append(((0, 0, 0.2), (W, H, 0.4)))
    boxes.append(((0, 0, 0.4), (0.2, H, D - 0.4)))
    boxes.append(((W - 0.2, 0, 0.4), (W, H, D - 0.4)))
    # cornice and corner pilasters on the front
    boxes.append(((0, H - 1.0, D - 0.2), (W, H - 0.4, D)))
    boxes.append(((0, 0, D - 0.2), (0.3, H - 1.0, D)))
    boxes.append(((W - 0.3, 0, D - 0.2), (W, H - 1.0, D)))
    door = columns // 2 - 1 if columns > 1 else 0
    for i in range(columns):
        x0 = i * ux
        # ground floor: a door or shop windows in front, plain windows at the back
        if i == door:
            boxes.append(((x0 + 0.4, 0.2, D - 0.2), (x0 + 1.6, 2.4, D)))
        else:
            boxes.append(((x0 + 0.5, 0.6, D - 0.2), (x0 + 1.5, 2.2, D - 0.05)))
        boxes.append(((x0 + 0.5, 0.9, 0), (x0 + 1.5, 2.1, 0.2)))
        for f in range(1, floors):
            y0 = f * uy
            boxes.append(((x0 + 0.5, y0 + 0.9, D - 0.2), (x0 + 1.5, y0 + 2.1, D)))
            boxes.append(((x0 + 0.5, y0 + 0.9, 0), (x0 + 1.5, y0 + 2.1, 0.2)))
            if f == 2 and i % 3 == 1:  # balconies
                boxes.append(((x0 + 0.2, y0 + 0.3, D - 0.2), (x0 + 1.8, y0 + 0.7, D)))
    Vs, Fs, off = [], [], 0
    for lo, hi in boxes:
        V, F = box(lo, hi, detail=detail)
        Vs.append(V)
        Fs.append(F + off)
        off += len(V)
    V, inverse = np.unique(np.concatenate(Vs), axis=0, return_inverse=True)
    return V, inverse.reshape(-1)[np.concatenate(Fs)]


def _write_obj(path: Path, V: np.ndarray, F: np.ndarray) -> None:
    lines = ["# synthkit sample: modular building of lattice pieces"]
    lines += [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in V]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path.write_text("\n".join(lines) + "\n")


def generate(out_dir: Path) -> list[Path]:
    """Write ``building_modular.obj`` and ``building_modular.truth.json`` into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    V, F = building()
    mesh_path = out_dir / "building_modular.obj"
    _write_obj(mesh_path, V, F)
    truth = {
        "unit": list(UNIT),
        "origin": list(ORIGIN),
        "counts": list(COUNTS),
        "extent": [COUNTS[i] * UNIT[i] for i in range(3)],
        "vertices": int(len(V)),
        "faces": int(len(F)),
        "axes": "X right, Y up, Z towards the front facade",
    }
    truth_path = out_dir / "building_modular.truth.json"
    truth_path.write_text(json.dumps(truth, indent=2) + "\n")
    return [mesh_path, truth_path]
