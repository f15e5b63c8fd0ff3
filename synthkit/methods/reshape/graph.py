"""Constraint graph of a textured mesh (paper section 3.1), over ``V (#V, 3)``, ``F (#F, 3)`` arrays.

- Surfaces: triangles of one material connected through shared render-vertex edges (a shared edge
  means shared 3-D and UV coordinates).
- Nodes: render vertices welded by position (``weld_tol``), so co-located vertices of different
  surfaces share one node.
- Edges within a surface: *contour* (used by one triangle of the surface), *angle* (two triangles
  whose normals differ by more than ``flat_angle_deg``; also edges used by more than two triangles)
  and *flat* (coplanar triangles; ignored). A node that only flat edges reach would be
  unconstrained, so its flat edges are kept (kind ``flat_kept``).
- Contours: each contour vertex of a surface should have exactly two contour edges (well formed);
  the loops are counted per surface, every loop beyond the first of a surface being a hole.
- Components: connected components of the graph's nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from synthkit.core.mesh import face_normals, weld

__all__ = ["ConstraintGraph", "build_graph", "classify_edges", "contour_loops", "surfaces", "CONTOUR", "ANGLE",
           "FLAT_KEPT"]

CONTOUR, ANGLE, FLAT_KEPT = 0, 1, 2
"""Graph edge kinds."""


@dataclass
class ConstraintGraph:
    """Nodes, classified edges, surfaces and components of one mesh.

    Attributes
    ----------
    X0 : (n, 3) float64 node positions
    node_of_vertex : (#V,) int64 node of each render vertex
    Fn : (#F, 3) int64 triangles over nodes
    face_surface : (#F,) int64 surface of each triangle
    edges : (E, 2) int64 node pairs (i < k) of contour and angle edges (and kept flat edges)
    edge_kind : (E,) int64 ``CONTOUR``, ``ANGLE`` or ``FLAT_KEPT`` (contour wins when an edge is both)
    component : (n,) int64 connected component of each node
    bridges : (k, 2) int64 flat edges (node pairs) joining two components inside one surface (holes)
    bridge_normals : (k, 3) float64 unit normal of a triangle beside each bridge
    counts : dict of the section 3.1 counts
    """

    X0: np.ndarray
    node_of_vertex: np.ndarray
    Fn: np.ndarray
    face_surface: np.ndarray
    edges: np.ndarray
    edge_kind: np.ndarray
    component: np.ndarray
    bridges: np.ndarray
    bridge_normals: np.ndarray
    counts: dict

    @property
    def n_nodes(self) -> int:
        return len(self.X0)


def _components(n: int, pairs: np.ndarray) -> tuple[int, np.ndarray]:
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(G, directed=False)


def surfaces(F: np.ndarray, face_material: np.ndarray) -> tuple[int, np.ndarray]:
    """Surface label ``(#F,)`` of each triangle: components of same-material triangles sharing an edge."""
    m = len(F)
    he = np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    key = np.column_stack([he, np.repeat(face_material, 3)])
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    face = np.repeat(np.arange(m), 3)
    order = np.argsort(inv, kind="stable")
    same = inv[order][1:] == inv[order][:-1]
    pairs = np.column_stack([face[order][:-1][same], face[order][1:][same]])
    return _components(m, pairs)


def classify_edges(V, F, face_surface, *, flat_angle_deg: float):
    """Edges of each surface over render vertices: ``(pairs (k, 2), kind (k,), surface (k,),
    face (k,), nonmanifold)`` with kind ``CONTOUR``, ``ANGLE`` or -1 for flat, a triangle using each
    edge, and the number of edges used by more than two triangles of a surface."""
    normals = face_normals(V, F)
    he = np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    face = np.repeat(np.arange(len(F)), 3)
    key = np.column_stack([he, face_surface[face]])
    uniq, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    kind = np.where(count == 1, CONTOUR, ANGLE)
    two = np.flatnonzero(count == 2)
    order = np.argsort(inv, kind="stable")
    first = np.searchsorted(inv[order], two)
    fa, fb = face[order][first], face[order][first + 1]
    cos = np.einsum("ij,ij->i", normals[fa], normals[fb])
    kind[two[cos > np.cos(np.radians(flat_angle_deg))]] = -1
    one = face[order][np.searchsorted(inv[order], np.arange(len(uniq)))]
    return uniq[:, :2], kind, uniq[:, 2], one, int((count > 2).sum())


def contour_loops(pairs: np.ndarray, surface: np.ndarray, n_vertices: int) -> tuple[int, int, int]:
    """``(loops, holes, ill_formed_vertices)`` of contour edges ``pairs (k, 2)`` over render vertices,
    ``surface (k,)`` their surface: a well-formed contour vertex has exactly two contour edges."""
    if not len(pairs):
        return 0, 0, 0
    deg = np.bincount(pairs.reshape(-1), minlength=n_vertices)
    ill = int(((deg != 0) & (deg != 2)).sum())
    _, comp = _components(n_vertices, pairs)
    loop_of_edge = comp[pairs[:, 0]]
    loops = np.unique(np.column_stack([loop_of_edge, surface]), axis=0)
    n_loops = len(np.unique(loops[:, 0]))
    holes = n_loops - len(np.unique(loops[:, 1]))
    return n_loops, max(holes, 0), ill


def _graph_edges(npairs: np.ndarray, kind: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Graph edges ``(E, 2)`` (i < k, unique) and kinds ``(E,)`` from the surface edges over nodes
    ``npairs (k, 2)`` with ``kind (k,)``: contour and angle edges, plus the flat edges of a node
    that no contour or angle edge reaches. Zero-length edges (welded ends) are dropped; an edge
    that is contour in one surface and angle in another counts as contour."""
    proper = npairs[:, 0] != npairs[:, 1]
    keep = (kind >= 0) & proper
    reached = np.zeros(n, bool)
    reached[npairs[keep].reshape(-1)] = True
    lonely = (kind < 0) & proper & ~(reached[npairs[:, 0]] & reached[npairs[:, 1]])
    sel = keep | lonely
    e = np.sort(npairs[sel], axis=1)
    k = np.where(kind < 0, FLAT_KEPT, kind)[sel]
    order = np.lexsort((k, e[:, 1], e[:, 0]))
    e, k = e[order], k[order]
    first = np.r_[True, np.any(e[1:] != e[:-1], axis=1)] if len(e) else np.zeros(0, bool)
    return e[first], k[first]


def build_graph(V, F, face_material, *, weld_tol: float, flat_angle_deg: float = 0.5) -> ConstraintGraph:
    """The constraint graph of render vertices ``V (#V, 3)``, triangles ``F (#F, 3)`` and
    ``face_material (#F,)``. ``weld_tol`` (model units) merges co-located vertices into one node;
    triangles within ``flat_angle_deg`` of each other are coplanar. Raises ValueError when no
    triangle has a non-zero area."""
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    if not (np.linalg.norm(normals, axis=1) > 0).any():
        raise ValueError("every triangle has zero area")
    n_surf, face_surface = surfaces(F, np.asarray(face_material, np.int64))
    pairs, kind, pair_surface, pair_face, nonmanifold = classify_edges(
        V, F, face_surface, flat_angle_deg=flat_angle_deg
    )
    used = np.unique(F)
    X0, _, node_of_vertex = weld(V, F, weld_tol, return_index=True)
    Fn = node_of_vertex[F]
    npairs = node_of_vertex[pairs]
    edges, edge_kind = _graph_edges(npairs, kind, len(X0))
    _, component = _components(len(X0), edges)
    cross = (kind < 0) & (component[npairs[:, 0]] != component[npairs[:, 1]])
    bridges, first_b = np.unique(np.sort(npairs[cross], axis=1), axis=0, return_index=True)
    bridge_normals = face_normals(V, F)[pair_face[cross][first_b]]
    node_used = np.zeros(len(X0), bool)
    node_used[node_of_vertex[used]] = True
    contour = kind == CONTOUR
    loops, holes, ill = contour_loops(pairs[contour], pair_surface[contour], len(V))
    counts = {
        "vertices": int(len(V)),
        "triangles": int(len(F)),
        "surfaces": int(n_surf),
        "nodes": int(node_used.sum()),
        "edges": int(len(edges)),
        "contour_edges": int((edge_kind == CONTOUR).sum()),
        "angle_edges": int((edge_kind == ANGLE).sum()),
        "flat_edges": int((kind < 0).sum()),
        "flat_edges_kept": int((edge_kind == FLAT_KEPT).sum()),
        "nonmanifold_edges": nonmanifold,
        "contour_loops": loops,
        "holes": holes,
        "ill_formed_contour_vertices": ill,
        "components": int(len(np.unique(component[node_used]))),
        "hole_bridges": int(len(bridges)),
    }
    return ConstraintGraph(
        X0, node_of_vertex, Fn, face_surface, edges, edge_kind, component, bridges, bridge_normals, counts
    )

