"""Shapes with known parts for surface-by-numbers: unions of voxels and a painted sphere.

A shape is an integer voxel grid of part ids (0 empty); its surface is the set of voxel faces
between a filled and an empty cell, two triangles per face, with shared lattice vertices, so parts
meet along concave creases exactly on mesh edges and every face knows its part (the ground truth).

- ``surfacing-crease.ply``: two boxes glued along one concave crease (an L), parts 0 and 1;
- ``surfacing-figure.ply``: a body with a head and two arms (four parts), the bundled example;
- ``surfacing-disc.ply``: a sphere with vertex colours, a red disc around +Z on white;
- ``surfacing-figure-front.png``: the figure's ``front`` view (256 pixels) as surface-by-numbers
  renders it, with round dabs painted on the body (red), head (blue) and arms (green, purple), as
  a user would paint them in an image editor.

Each ``<name>.truth.json`` holds the face parts and a stroke vertex near the middle of each part.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh

__all__ = ["voxel_surface", "crease_boxes", "figure", "disc_sphere", "part_centre_vertices", "generate"]


def voxel_surface(occ, spacing: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Surface of the filled cells of ``occ (nx, ny, nz) int`` (part id + 1, 0 empty).

    Returns ``(V (#V, 3) float64, F (#F, 3) int64, part (#F,) int64)``, faces outward, vertices on
    the lattice ``spacing * (i, j, k)``."""
    occ = np.pad(np.asarray(occ, np.int64), 1)
    shape = np.array(occ.shape) + 1
    quads, parts = [], []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for step in (1, -1):
            nb = np.roll(occ, -step, axis=a)
            cells = np.argwhere((occ > 0) & (nb == 0))
            base = cells.copy()
            if step == 1:
                base[:, a] += 1
            corner = [np.zeros(3, np.int64) for _ in range(4)]
            corner[1][b] = 1
            corner[2][b] = corner[2][c] = 1
            corner[3][c] = 1
            order = (0, 1, 2, 3) if step == 1 else (0, 3, 2, 1)
            q = np.stack([np.ravel_multi_index((base + corner[o]).T, shape) for o in order], axis=1)
            quads.append(q)
            parts.append(occ[tuple(cells.T)] - 1)
    Q = np.concatenate(quads)
    part = np.repeat(np.concatenate(parts), 2)
    F = np.stack([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    used, F = np.unique(F, return_inverse=True)
    V = (np.stack(np.unravel_index(used, shape), axis=1) - 1).astype(np.float64) * spacing
    return V, F.reshape(-1, 3).astype(np.int64), part


def crease_boxes(n: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An L of two boxes: part 0 is ``[0, 2] x [0, 1.5] x [0, 1]``, part 1 ``[0, 1] x [1.5, 2.5] x [0, 1]``;
    the concave crease is the line x = 1, y = 1.5, and the cheapest cut continues it along y = 1.5
    (length 1 on each flat side, against 1.5 along x = 1). ``n`` (even) cells per unit."""
    if n % 2:
        raise ValueError(f"n must be even, got {n}")
    h = 3 * n // 2
    occ = np.zeros((2 * n, h + n, n), np.int64)
    occ[:, :h, :] = 1
    occ[:n, h:, :] = 2
    return voxel_surface(occ, 1.0 / n)


def figure(n: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body (part 0), head (1), left arm (2), right arm (3); ``n`` cells per unit."""
    occ = np.zeros((9 * n, 8 * n, 2 * n), np.int64)
    occ[3 * n:6 * n, 0:5 * n, :] = 1
    occ[int(3.75 * n):int(5.25 * n), 5 * n:int(6.5 * n), int(0.25 * n):int(1.75 * n)] = 2
    occ[0:3 * n, int(3.5 * n):int(4.5 * n), int(0.5 * n):int(1.5 * n)] = 3
    occ[6 * n:9 * n, int(3.5 * n):int(4.5 * n), int(0.5 * n):int(1.5 * n)] = 4
    return voxel_surface(occ, 1.0 / n)


def disc_sphere(subdivisions: int = 4, radius_deg: float = 35.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit icosphere with vertex colours ``(#V, 3) uint8``: red within ``radius_deg`` of +Z, white
    elsewhere. Returns ``(V, F, colors)``; the disc's faces (all corners red) are part 1."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    V = np.asarray(m.vertices)
    red = V[:, 2] > np.cos(np.radians(radius_deg))
    colors = np.where(red[:, None], [220, 30, 30], [245, 245, 245]).astype(np.uint8)
    return V, np.asarray(m.faces, np.int64), colors


def part_centre_vertices(V, F, part) -> list[int]:
    """Per part, its deepest interior vertex (all incident faces in the part, farthest on the edge
    graph from the part's boundary): a stroke in the body of the part."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import dijkstra

    from synthkit.core.mesh import vertex_graph_edges

    E = vertex_graph_edges(F)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    G = sp.csr_matrix((w, (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    out = []
    for p in range(int(part.max()) + 1):
        inside = np.zeros(len(V), bool)
        outside = np.zeros(len(V), bool)
        inside[F[part == p].ravel()] = True
        outside[F[part != p].ravel()] = True
        rim = np.flatnonzero(inside & outside)
        depth = dijkstra(G, directed=False, indices=rim, min_only=True) if len(rim) else np.zeros(len(V))
        out.append(int(np.argmax(np.where(inside & ~outside, depth, -1.0))))
    return out


def _write(out_dir: Path, name: str, V, F, part, colors=None) -> list[Path]:
    mesh = trimesh.Trimesh(V, F, vertex_colors=colors, process=False)
    path = out_dir / f"{name}.ply"
    path.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="ascii", vertex_normal=False))
    truth = {"faces": int(len(F)), "vertices": int(len(V)), "face_part": part.astype(int).tolist(),
             "stroke_vertices": part_centre_vertices(V, F, part)}
    tpath = out_dir / f"{name}.truth.json"
    tpath.write_text(json.dumps(truth) + "\n")
    return [path, tpath]


PAINT = {"body": ((4.5, 2.0, 2.0), (220, 40, 40)), "head": ((4.5, 5.75, 1.75), (40, 60, 220)),
         "left_arm": ((1.5, 4.0, 1.5), (40, 180, 60)), "right_arm": ((7.5, 4.0, 1.5), (160, 60, 170))}
"""Region -> (a point of it facing the front view, the RGB its dab is painted in)."""


def painted_front(V, F, *, size: int = 256, radius: int = 4) -> np.ndarray:
    """The ``front`` render of ``V``, ``F`` with a round dab of each :data:`PAINT` colour, uint8 RGB."""
    from synthkit.methods.surfacing import views

    cam = views.camera(V, "front", size)
    img = views.render(V, F, views.face_id_buffer(V, F, cam), cam)
    img = np.round(img * 255).astype(np.uint8)
    yy, xx = np.mgrid[:size, :size]
    for point, rgb in PAINT.values():
        (x, y), = cam.to_pixels(np.array([point]))[0]
        img[(xx - x) ** 2 + (yy - y) ** 2 <= radius**2] = rgb
    return img


def generate(out_dir: Path) -> list[Path]:
    """Write the samples and their truth files into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = _write(out_dir, "surfacing-crease", *crease_boxes())
    V, F, part = figure()
    written += _write(out_dir, "surfacing-figure", V, F, part)
    from synthkit.io.images import save_image

    png = out_dir / "surfacing-figure-front.png"
    save_image(png, painted_front(V, F))
    written.append(png)
    V, F, colors = disc_sphere()
    part = (colors[F][:, :, 1] < 100).all(axis=1).astype(np.int64)
    written += _write(out_dir, "surfacing-disc", V, F, part, colors)
    return written
