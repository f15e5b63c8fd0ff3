"""Strokes of a batch user turned into fixed nodes of a graph, on ``V (#V, 3)``, ``F (#F, 3)``.

A region's strokes are vertex indices, face indices and polylines in model units. Each point of a
polyline is snapped to the closest surface point (the stroked vertex is the corner of the hit
triangle nearest to it) and consecutive points are joined by the shortest edge path between
their vertices, traced on the surface. A vertex stroked for two
regions, or a face stroked for two regions, is an error.

Fixed nodes (``seeds (n,) int64``, -1 free): on the vertex graph, the stroked vertices and the
corners of stroked faces (a corner shared by faces of two regions stays free); on the face graph,
the stroked faces and the faces around stroked vertices (a face touching stroked vertices of two
regions stays free).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

__all__ = ["check_indices", "snap_polyline", "stroke_sets", "graph_seeds", "assign_unstroked_components"]


def check_indices(idx, n: int, what: str) -> np.ndarray:
    """``idx`` as int64; ValueError naming the first index outside ``[0, n)``."""
    idx = np.asarray(idx, dtype=np.int64).reshape(-1)
    bad = idx[(idx < 0) | (idx >= n)]
    if len(bad):
        raise ValueError(f"{what} index {int(bad[0])} out of range [0, {n})")
    return idx


def snap_polyline(mesh: trimesh.Trimesh, points, *, tolerance: float) -> np.ndarray:
    """Vertices ``(k,) int64`` of the stroke drawn by the polyline ``points (m, 3)``.

    Each of the user's points is snapped to the closest surface point, and its stroked vertex is the
    corner of the hit triangle nearest to it; ValueError names the first point (its index and
    position) farther than ``tolerance`` from the surface. Only the user's points are held to the
    tolerance, whatever their spacing: a chord between two of them may cut through the body or
    float above a curved limb, so it is traced on the surface instead, as the shortest path over the
    mesh's edges between the two stroked vertices (the chord's own straight line is never
    snapped, so it cannot jump to a nearby part it passes). Two points on pieces that no edge
    path joins are a ValueError."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    closest, dist, tri = trimesh.proximity.closest_point(mesh, P)
    far = np.flatnonzero(dist > tolerance)
    if len(far):
        k = int(far[0])
        raise ValueError(f"point {k} {np.round(P[k], 6).tolist()} lies {dist[k]:.4g} from the surface "
                         f"(tolerance {tolerance:.4g})")
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    corners = F[tri]
    d = np.linalg.norm(V[corners] - closest[:, None, :], axis=2)
    ends = corners[np.arange(len(corners)), np.argmin(d, axis=1)]
    if len(ends) < 2:
        return np.unique(ends)
    E = np.asarray(mesh.edges_unique, np.int64)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1) + 1e-12
    G = sp.csr_matrix((w, (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    reach = 4.0 * np.linalg.norm(np.diff(P, axis=0), axis=1) + 10.0 * float(w.mean())
    pairs = zip(ends[:-1], ends[1:], reach, strict=True)
    return np.unique(np.concatenate([_edge_path(G, a, b, r, k) for k, (a, b, r) in enumerate(pairs)]))


def _edge_path(G: sp.csr_matrix, a: int, b: int, reach: float, k: int) -> np.ndarray:
    """Vertices ``(p,)`` of the shortest path from ``a`` to ``b`` over the graph ``G``, searched first
    within ``reach`` of ``a`` (so that a short chord on a large mesh stays local), then everywhere;
    ValueError when there is none (``k``: the chord's index, for the message)."""
    if a == b:
        return np.array([a], np.int64)
    _, pred = dijkstra(G, directed=False, indices=int(a), return_predecessors=True, limit=reach)
    if pred[b] < 0:
        _, pred = dijkstra(G, directed=False, indices=int(a), return_predecessors=True)
    if pred[b] < 0:
        raise ValueError(f"points {k} and {k + 1} lie on pieces of the mesh that no surface path joins")
    path = [int(b)]
    while path[-1] != a:
        path.append(int(pred[path[-1]]))
    return np.asarray(path, np.int64)


def _claim(n: int, sets: list[np.ndarray], what: str, names: list[str]) -> np.ndarray:
    """Owner ``(n,)`` of each index (-1 none); ValueError when one index is in two regions' sets."""
    owner = np.full(n, -1, np.int64)
    for r, idx in enumerate(sets):
        clash = idx[(owner[idx] >= 0) & (owner[idx] != r)]
        if len(clash):
            k = int(clash[0])
            raise ValueError(f"{what} {k} is stroked for regions '{names[owner[k]]}' and '{names[r]}'")
        owner[idx] = r
    return owner


def stroke_sets(n_vertices: int, n_faces: int, vertex_sets, face_sets, names) -> tuple[np.ndarray, np.ndarray]:
    """Owners of stroked vertices ``(#V,)`` and faces ``(#F,)`` (-1 none), checked for clashes."""
    return (_claim(n_vertices, list(vertex_sets), "vertex", list(names)),
            _claim(n_faces, list(face_sets), "face", list(names)))


def _spread(owner: np.ndarray, src: np.ndarray, dst: np.ndarray, n: int) -> np.ndarray:
    """Owner per ``dst`` node from incidences ``src -> dst``: the one region among its sources, or -1
    when none or several."""
    o = owner[src]
    keep = o >= 0
    lo = np.full(n, np.iinfo(np.int64).max)
    hi = np.full(n, -1)
    np.minimum.at(lo, dst[keep], o[keep])
    np.maximum.at(hi, dst[keep], o[keep])
    return np.where((hi >= 0) & (lo == hi), hi, -1)


def graph_seeds(F, kind: str, vertex_owner: np.ndarray, face_owner: np.ndarray) -> np.ndarray:
    """Fixed region per graph node ``(n,)`` (-1 free), by the rules in the module docstring."""
    F = np.asarray(F, np.int64)
    fid = np.repeat(np.arange(len(F)), 3)
    if kind == "vertex":
        from_faces = _spread(face_owner, fid, F.ravel(), len(vertex_owner))
        return np.where(vertex_owner >= 0, vertex_owner, from_faces)
    from_vertices = _spread(vertex_owner, F.ravel(), fid, len(F))
    return np.where(face_owner >= 0, face_owner, from_vertices)


def assign_unstroked_components(points, edges, seeds) -> tuple[np.ndarray, int]:
    """Fix every node of a connected component without strokes to the region of the stroke nearest
    to it (Euclidean, over all the component's nodes). Returns the new seeds and the number of such
    components. ``points (n, 3)``, ``edges (E, 2)``, ``seeds (n,)``."""
    n = len(points)
    A = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    n_comp, comp = connected_components(A, directed=False)
    has = np.zeros(n_comp, bool)
    has[comp[seeds >= 0]] = True
    missing = np.flatnonzero(~has)
    if not len(missing):
        return seeds, 0
    stroked = np.flatnonzero(seeds >= 0)
    dist, near = cKDTree(points[stroked]).query(points)
    seeds = seeds.copy()
    for c in missing:
        members = np.flatnonzero(comp == c)
        seeds[members] = seeds[stroked[near[members[np.argmin(dist[members])]]]]
    return seeds, len(missing)
