"""The segmentation graph of a mesh ``V (#V, 3) float64``, ``F (#F, 3) int64`` (sections 3.2, 3.3).

Two graphs share one form, :class:`SegGraph`: ``kind="vertex"`` is the paper's (a node per vertex,
mesh edges between neighbours) and ``kind="face"`` its dual (a node per face, an edge per pair of
faces sharing a mesh edge), whose cuts run along mesh edges. Edge weights are eq. 1,

    e_ij = eta (2 pi - theta_ij) / (2 pi) + gamma d_ij / d_mean,

with theta the interior dihedral angle of the mesh edge (pi flat, above pi concave, below pi
convex; ``pi - bending`` of :func:`synthkit.core.mesh.dihedral_angles`), d_ij the mesh edge's
length and d_mean the mean length of the faces' edges (an interior edge counted from both faces),
so that concave creases are cheap to cut (the minima rule). Every cost is multiplied by the mean
area of its two nodes' neighbourhoods divided by the mean node area (vertex graph: barycentric
vertex areas; face graph: face areas), as the paper weights all costs by area. A vertex-graph
edge's theta is the mean over its face pairs (boundary edges count as flat); at a non-manifold edge
every pair of its faces is one face-graph edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.core.mesh import (
    dihedral_angles,
    edge_lengths,
    face_areas,
    vertex_areas,
    vertex_graph_edges,
)

__all__ = ["SegGraph", "build_graph", "boundary_cost", "face_labels_from_vertices", "vertex_labels_from_faces"]


@dataclass
class SegGraph:
    """A graph to cut: ``kind``, node ``points (n, 3)``, ``areas (n,)`` (divided by their mean),
    ``edges (E, 2) int64``, area-weighted eq. 1 ``weights (E,)``, ``lengths (E,)`` (the mesh edge each
    graph edge crosses or follows), ``mesh_edges (E, 2)`` (that mesh edge's vertices) and ``bend (E,)``
    (that mesh edge's bending angle, ``pi - theta``: negative where concave)."""

    kind: str
    points: np.ndarray
    areas: np.ndarray
    edges: np.ndarray
    weights: np.ndarray
    lengths: np.ndarray
    mesh_edges: np.ndarray
    bend: np.ndarray

    @property
    def n(self) -> int:
        return len(self.points)


def boundary_cost(theta, length, *, mean_length: float, eta: float = 1.0, gamma: float = 1.0) -> np.ndarray:
    """Eq. 1 for dihedral angles ``theta (E,)`` (pi flat, larger concave) and lengths ``(E,)``."""
    theta = np.asarray(theta, dtype=np.float64)
    if np.any(theta < 0) or np.any(theta > 2 * np.pi):
        raise ValueError("dihedral angles must lie in [0, 2 pi]")
    if mean_length <= 0:
        raise ValueError(f"mean edge length must be positive, got {mean_length}")
    return eta * (2 * np.pi - theta) / (2 * np.pi) + gamma * np.asarray(length, np.float64) / mean_length


def _normalised(a: np.ndarray) -> np.ndarray:
    m = a[a > 0].mean() if np.any(a > 0) else 1.0
    return a / m


def _shared_edges(F: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """The mesh edge ``(k, 2)`` (sorted vertex pair) shared by each face pair ``pairs (k, 2)``."""
    a, b = F[pairs[:, 0]], F[pairs[:, 1]]
    shared = (a[:, :, None] == b[:, None, :]).any(axis=2)
    first = np.argmax(shared, axis=1)
    last = 2 - np.argmax(shared[:, ::-1], axis=1)
    rows = np.arange(len(a))
    return np.sort(np.stack([a[rows, first], a[rows, last]], axis=1), axis=1)


def build_graph(V, F, kind: str, *, eta: float = 1.0, gamma: float = 1.0) -> SegGraph:
    """The vertex or face graph of ``V``, ``F`` with area-weighted eq. 1 edge weights."""
    if kind not in ("vertex", "face"):
        raise ValueError(f"graph kind must be 'vertex' or 'face', got {kind!r}")
    pairs, bend = dihedral_angles(V, F)
    pair_edges = _shared_edges(np.asarray(F, np.int64), pairs)
    mean_length = float(edge_lengths(V, F).mean())
    if kind == "face":
        areas = _normalised(face_areas(V, F))
        lengths = np.linalg.norm(V[pair_edges[:, 0]] - V[pair_edges[:, 1]], axis=1)
        cost = boundary_cost(np.pi - bend, lengths, mean_length=mean_length, eta=eta, gamma=gamma)
        weights = cost * 0.5 * (areas[pairs[:, 0]] + areas[pairs[:, 1]])
        points = V[F].mean(axis=1)
        return SegGraph("face", points, areas, pairs, weights, lengths, pair_edges, bend)
    areas = _normalised(vertex_areas(V, F))
    E = vertex_graph_edges(F)
    length_all = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    n = len(V)
    keys = E[:, 0] * n + E[:, 1]
    idx = np.searchsorted(keys, pair_edges[:, 0] * n + pair_edges[:, 1])
    count = np.bincount(idx, minlength=len(E))
    mean_bend = np.bincount(idx, weights=bend, minlength=len(E)) / np.maximum(count, 1)
    cost = boundary_cost(np.pi - mean_bend, length_all, mean_length=mean_length, eta=eta, gamma=gamma)
    weights = cost * 0.5 * (areas[E[:, 0]] + areas[E[:, 1]])
    return SegGraph("vertex", np.asarray(V, np.float64), areas, E, weights, length_all, E, mean_bend)


def face_labels_from_vertices(F, vertex_labels) -> np.ndarray:
    """Face labels ``(#F,)`` from ``vertex_labels (#V,)``: the label held by at least two of a face's
    corners; a face whose three corners all differ takes its smallest corner label."""
    L = np.asarray(vertex_labels, np.int64)[np.asarray(F, np.int64)]
    return np.where(L[:, 1] == L[:, 2], L[:, 1], np.where(L[:, 0] == L[:, 2], L[:, 0],
                    np.where(L[:, 0] == L[:, 1], L[:, 0], L.min(axis=1))))


def vertex_labels_from_faces(V, F, face_labels, n_labels: int) -> np.ndarray:
    """Vertex labels ``(#V,)``: the label with the largest incident face area (ties: smallest label);
    a vertex no face uses gets -1."""
    F = np.asarray(F, np.int64)
    area = np.repeat(face_areas(V, F) + 1e-300, 3)
    score = np.zeros((len(V), n_labels))
    np.add.at(score, (F.ravel(), np.repeat(np.asarray(face_labels, np.int64), 3)), area)
    out = np.argmax(score, axis=1)
    out[score.sum(axis=1) == 0] = -1
    return out
