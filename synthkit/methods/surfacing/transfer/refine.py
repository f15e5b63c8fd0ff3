"""Adaptive refinement of the target at extraction (section 4.5, after ADF construction).

Per covered face, the signal is read through the face's patch at its three edge midpoints and its
centre and compared with the piecewise-linear reconstruction from its corners; an edge whose
midpoint differs by more than ``tolerance`` (Euclidean over the channels) is marked, and a face
whose centre differs by more while none of its edges is marked gets its longest edge marked.
Marked edges are bisected and every face is split by the usual conforming patterns (one marked
edge: 2 triangles, two: 3, three: 4), so the mesh stays conforming; faces outside the regions
split too where a marked edge borders them. Each child corner is a fixed combination of its
parent's corners, so positions, domain coordinates and vertex colours follow linearly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["edge_index", "split_faces", "mark_edges"]

_MID = np.array([[0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]])
"""Weights of the midpoints m0 (c0 c1), m1 (c1 c2), m2 (c2 c0) over the corners."""
_C = np.eye(3)
_PATTERNS = {
    1: [(_C[0], _MID[0], _C[2]), (_MID[0], _C[1], _C[2])],
    2: [(_MID[0], _C[1], _MID[1]), (_C[0], _MID[0], _MID[1]), (_C[0], _MID[1], _C[2])],
    3: [(_C[0], _MID[0], _MID[2]), (_MID[0], _C[1], _MID[1]), (_MID[2], _MID[1], _C[2]), (_MID[0], _MID[1], _MID[2])],
}
"""Children of a face as corner weights, in the rotation where edge 0 (and, for two, edge 1) is marked."""


def edge_index(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(edge (#F, 3), edges (E, 2))``: the id of each face's edge ``k`` (corners k, k + 1) and
    the unique undirected edges."""
    E = np.sort(np.stack([F, np.roll(F, -1, axis=1)], axis=2), axis=2).reshape(-1, 2)
    edges, inverse = np.unique(E, axis=0, return_inverse=True)
    return inverse.reshape(-1, 3), edges


def mark_edges(V: np.ndarray, F: np.ndarray, edge: np.ndarray, n_edges: int, mid_err: np.ndarray,
               centre_err: np.ndarray, tolerance: float) -> np.ndarray:
    """``(E,) bool`` edges to bisect from the midpoint errors ``mid_err (#F, 3)`` and centre errors
    ``centre_err (#F,)`` (NaN: not measured)."""
    marked = np.zeros(n_edges, bool)
    marked[edge[np.nan_to_num(mid_err) > tolerance]] = True
    lone = (np.nan_to_num(centre_err) > tolerance) & ~marked[edge].any(axis=1)
    length = np.linalg.norm(V[np.roll(F, -1, axis=1)] - V[F], axis=2)
    longest = edge[np.arange(len(F)), np.argmax(length, axis=1)]
    marked[longest[lone]] = True
    return marked


def split_faces(F: np.ndarray, edge: np.ndarray, marked: np.ndarray, n_vertices: int):
    """Split ``F (#F, 3)`` at the ``marked (E,)`` edges. Returns ``(F2 (#F2, 3), parent (#F2,),
    weights (#F2, 3, 3), new_edges (k,))``: child corner ``j`` is ``weights[., j] @`` the parent's
    corners, new vertex ``n_vertices + i`` is the midpoint of edge ``new_edges[i]``."""
    new_edges = np.flatnonzero(marked)
    mid_vertex = np.full(len(marked), -1, np.int64)
    mid_vertex[new_edges] = n_vertices + np.arange(len(new_edges))
    m = marked[edge]
    count = m.sum(axis=1)
    keep = np.flatnonzero(count == 0)
    out_f, out_p, out_w = [F[keep]], [keep], [np.tile(_C, (len(keep), 1, 1))]
    for k, children in _PATTERNS.items():
        for r in range(3 if k < 3 else 1):
            rolled = np.roll(m, -r, axis=1)
            want = rolled[:, 0] & (rolled[:, 1] if k >= 2 else True)
            if k == 2:
                want &= ~rolled[:, 2]
            faces = np.flatnonzero((count == k) & want)
            if not len(faces):
                continue
            perm = (np.arange(3) + r) % 3  # rotated corner j is original corner perm[j]
            verts = np.concatenate([F[faces][:, perm], mid_vertex[edge[faces][:, perm]]], axis=1)
            for child in children:
                w_rot = np.stack(child)  # (3 corners, 3 rotated parent corners)
                w = np.zeros_like(w_rot)
                w[:, perm] = w_rot
                out_f.append(np.stack([_vertex_of(verts, row) for row in w_rot], axis=1))
                out_p.append(faces)
                out_w.append(np.tile(w, (len(faces), 1, 1)))
    order = np.argsort(np.concatenate(out_p), kind="stable")
    return (np.concatenate(out_f)[order], np.concatenate(out_p)[order], np.concatenate(out_w)[order], new_edges)


def _vertex_of(verts: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Vertex ids ``(n,)`` of a child corner given by ``weights (3,)`` over the rotated corners:
    a corner or the midpoint of edge (j, j + 1), from ``verts (n, 6)`` = corners then midpoints."""
    nz = np.flatnonzero(weights)
    if len(nz) == 1:
        return verts[:, nz[0]]
    j = 2 if set(nz.tolist()) == {0, 2} else int(nz[0])
    return verts[:, 3 + j]
