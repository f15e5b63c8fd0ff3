"""Parts of a reshaped model and how they stay attached (beyond the paper).

A *part* is a face-connected component of the welded mesh (a wall block, a window, a drainpipe):
``part (n,)`` labels the graph nodes, -1 on nodes no triangle uses. Every part other than the
root (the part with the most nodes) is carried by a *host*: the surface of another part nearest
to it. :func:`closest_points` finds, for points ``P (k, 3)``, the nearest point of a triangle set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

__all__ = ["mesh_parts", "closest_points", "Attachment", "attach_clusters", "part_distances"]


def mesh_parts(Fn: np.ndarray, n: int) -> np.ndarray:
    """Part label ``(n,)`` of each node of triangles ``Fn (F, 3)`` (face-connected components over
    nodes, numbered by their first node); -1 for nodes no triangle uses."""
    pairs = np.vstack([Fn[:, [0, 1]], Fn[:, [1, 2]]])
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    used = np.zeros(n, bool)
    used[Fn.reshape(-1)] = True
    _, first, inv = np.unique(label[used], return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))
    out = np.full(n, -1, np.int64)
    out[used] = order[inv.reshape(-1)]
    return out


def closest_points(P: np.ndarray, tri: np.ndarray, *, chunk: int = 256) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest point of triangles ``tri (T, 3, 3)`` to each point ``P (k, 3)``: distance ``(k,)``,
    triangle index ``(k,)`` and barycentric coordinates ``(k, 3)`` of the nearest point (brute force
    over triangles in chunks of points; Ericson's region tests)."""
    P = np.asarray(P, np.float64)
    dist = np.empty(len(P))
    tri_of = np.empty(len(P), np.int64)
    bary = np.empty((len(P), 3))
    for s in range(0, len(P), chunk):
        d, lam = _point_triangle(P[s:s + chunk, None], tri[None])
        j = np.argmin(d, axis=1)
        r = np.arange(len(j))
        dist[s:s + chunk], tri_of[s:s + chunk], bary[s:s + chunk] = np.sqrt(d[r, j]), j, lam[r, j]
    return dist, tri_of, bary


def _point_triangle(p, tri) -> tuple[np.ndarray, np.ndarray]:
    """Squared distances ``(k, T)`` and barycentric coordinates ``(k, T, 3)`` of the nearest point
    of each triangle ``tri (1, T, 3, 3)`` to each point ``p (k, 1, 3)``."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d, lam = _regions(p, tri)
    return np.where(np.isfinite(d), d, np.inf), lam


def _regions(p, tri) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_point_triangle` without the guards: degenerate triangles give non-finite values."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("...i,...i", ab, ap), np.einsum("...i,...i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("...i,...i", ab, bp), np.einsum("...i,...i", ac, bp)
    d5, d6 = np.einsum("...i,...i", ab, cp), np.einsum("...i,...i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    v, w = vb / denom, vc / denom
    t_ab = d1 / (d1 - d3)
    t_ac = d2 / (d2 - d6)
    t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    lam = np.stack([1 - v - w, v, w], axis=-1)
    cases = [
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.stack([1 - t_ab, t_ab, 0 * t_ab], -1)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.stack([1 - t_ac, 0 * t_ac, t_ac], -1)),
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), np.stack([0 * t_bc, 1 - t_bc, t_bc], -1)),
        ((d1 <= 0) & (d2 <= 0), np.array([1.0, 0, 0])),
        ((d3 >= 0) & (d4 <= d3), np.array([0, 1.0, 0])),
        ((d6 >= 0) & (d5 <= d6), np.array([0, 0, 1.0])),
    ]
    for mask, value in cases:
        lam = np.where(mask[..., None], value, lam)
    lam = np.nan_to_num(lam, nan=1.0 / 3.0)
    q = lam[..., 0:1] * a + lam[..., 1:2] * b + lam[..., 2:3] * c
    return np.einsum("...i,...i", p - q, p - q), lam


def part_distances(X: np.ndarray, Fn: np.ndarray, part: np.ndarray) -> np.ndarray:
    """Distance ``(p,)`` from each part to the nearest other part (inf when alone): the smallest
    distance from a node of either to a triangle of the other."""
    n_parts = int(part.max()) + 1
    face_part = part[Fn[:, 0]]
    D = np.full((n_parts, n_parts), np.inf)
    for k in range(n_parts):
        other = np.flatnonzero(face_part != k)
        if len(other):
            d, t, _ = closest_points(X[part == k], X[Fn[other]])
            np.minimum.at(D, (np.full(len(d), k), face_part[other[t]]), d)
    return np.minimum(D, D.T).min(axis=1)


@dataclass
class Attachment:
    """Clusters carried by a host surface: the cluster's nodes ``nodes[i] (k_i,)`` (their centroid
    is carried), the host triangle ``tri (a,)`` over nodes ``Fn`` and the barycentric coordinates
    ``bary (a, 3)`` of the host point nearest that centroid, and its distance ``gap (a,)``."""

    nodes: list
    tri: np.ndarray
    bary: np.ndarray
    gap: np.ndarray


def attach_clusters(X, Fn, pairs, known) -> Attachment:
    """Attach every cluster of nodes (linked by ``pairs (k, 2)``, used by a triangle of ``Fn``)
    that holds no ``known`` node to a held cluster: greedily, the free cluster whose centroid is
    nearest a held triangle is attached to it and becomes held, until every cluster is held. So
    a frame on a window on a wall hangs on the window or the wall, whichever is nearer, and two
    free parts never hold each other. Deterministic (ties by node order)."""
    n = len(X)
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    used = np.zeros(n, bool)
    used[Fn.reshape(-1)] = True
    face_label = label[Fn[:, 0]]
    held_labels = np.unique(label[np.asarray(known, np.int64)])
    free = [c for c in np.unique(label[used]) if c not in set(held_labels.tolist())]
    members = [np.flatnonzero((label == c) & used) for c in free]
    centre = np.array([X[m].mean(axis=0) for m in members]).reshape(-1, 3)
    best_d, best_t, best_l = np.full(len(free), np.inf), np.zeros(len(free), np.int64), np.zeros((len(free), 3))
    newly = np.flatnonzero(np.isin(face_label, held_labels))
    out = Attachment([], [], [], [])
    todo = np.ones(len(free), bool)
    while todo.any():
        if len(newly):
            d, t, lam = closest_points(centre, X[Fn[newly]])
            better = todo & (d < best_d)
            best_d[better], best_t[better], best_l[better] = d[better], newly[t[better]], lam[better]
        k = int(np.flatnonzero(todo)[np.argmin(best_d[todo])])
        if not np.isfinite(best_d[k]):
            break
        todo[k] = False
        out.nodes.append(members[k])
        out.tri.append(int(best_t[k]))
        out.bary.append(best_l[k])
        out.gap.append(float(best_d[k]))
        newly = np.flatnonzero(face_label == free[k])
    return Attachment(out.nodes, np.asarray(out.tri, np.int64), np.asarray(out.bary).reshape(-1, 3),
                      np.asarray(out.gap))
