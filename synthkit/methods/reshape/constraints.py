"""Linear constraints of the reshape (paper section 3.2) as weighted rows of ``A x = b``.

Unknowns ``x (3 n,)`` are the node positions flattened node-major (``x[3 i + c]``). Every block
is a :class:`Rows` whose rows are already multiplied by their weight, so the least squares is
``min ||A x - b||^2``. Directions ``u_ki`` and lengths ``l_ki`` come from the rest positions
``X0 (n, 3)`` and are constants.

Each function scales its rows by the weight it is given. Strict constraints (edge direction
eq. 1, contact coplanarity eq. 5, user links) take ``strict_weight`` [Van Loan 1985]; soft ones
their paper weights: edge stress eq. 2 with the stiffness of eq. 3 (:func:`stiffness`; edges
shorter than ``l_min`` rigid, ``w = 1``), contact position eq. 6 (``w_c``), edge groups eq. 7
(``w_g``). The paper's weights weight squared residuals, so
:func:`synthkit.methods.reshape.system.build_system` passes their square roots. Positivity
(eq. 4) is checked by the solver after each step (section 3.4), not written as rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__ = [
    "Rows",
    "edge_frames",
    "stiffness",
    "direction_rows",
    "stress_rows",
    "find_contacts",
    "contact_rows",
    "bridge_rows",
    "edge_groups",
    "group_rows",
    "link_rows",
    "attach_rows",
    "stack_rows",
]


@dataclass
class Rows:
    """One block of weighted rows: COO ``rows``, ``cols``, ``vals`` (local row ids), ``b (m,)``."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    b: np.ndarray

    @property
    def m(self) -> int:
        return len(self.b)

    @staticmethod
    def empty() -> Rows:
        z = np.zeros(0, np.int64)
        return Rows(z, z, np.zeros(0), np.zeros(0))


def edge_frames(X0, edges) -> tuple[np.ndarray, np.ndarray]:
    """``(u (E, 3), l (E,))``: unit direction from ``edges[:, 0]`` to ``edges[:, 1]`` and length."""
    d = X0[edges[:, 1]] - X0[edges[:, 0]]
    length = np.linalg.norm(d, axis=1)
    return d / np.maximum(length, 1e-300)[:, None], length


def stiffness(length, *, l_min: float, w_small: float, w_long: float) -> np.ndarray:
    """Eq. 3: ``w (E,)`` from ``w_small`` at ``l_min`` to ``w_long`` at the longest edge; 1 below ``l_min``."""
    length = np.asarray(length, np.float64)
    l_max = float(length.max()) if len(length) else l_min
    t = (length - l_min) / max(l_max - l_min, 1e-300)
    w = w_small + (w_long - w_small) * np.clip(t, 0.0, 1.0)
    return np.where(length < l_min, 1.0, w)


def _block3(row0, col_i, col_k, M):
    """COO entries of ``M (E, 3, 3) (x_i - x_k)`` in rows ``row0 (E,) + 0..2``."""
    shape = M.shape
    rows = np.broadcast_to(row0[:, None, None] + np.arange(3)[None, :, None], shape).ravel()
    ci = np.broadcast_to(3 * col_i[:, None, None] + np.arange(3)[None, None, :], shape).ravel()
    ck = np.broadcast_to(3 * col_k[:, None, None] + np.arange(3)[None, None, :], shape).ravel()
    return np.concatenate([rows, rows]), np.concatenate([ci, ck]), np.concatenate([M.ravel(), -M.ravel()])


def direction_rows(X0, edges, *, weight: float, form: str = "vertex") -> Rows:
    """Eq. 1 with weight ``weight``.

    ``form="vertex"`` (the paper): per node i with neighbours N_i, three rows
    ``sum_k (I - u_ki u_ki^T)(x_i - x_k) = 0``. ``form="edge"``: three rows per edge,
    ``(I - u u^T)(x_i - x_k) = 0``, each edge on its own (stronger, more rows).
    """
    u, _ = edge_frames(X0, edges)
    P = weight * (np.eye(3)[None] - u[:, :, None] * u[:, None, :])
    if form == "edge":
        rows, cols, vals = _block3(3 * np.arange(len(edges)), edges[:, 1], edges[:, 0], P)
        return Rows(rows, cols, vals, np.zeros(3 * len(edges)))
    if form != "vertex":
        raise ValueError(f"unknown direction form {form!r}")
    nodes = np.unique(edges)
    slot = np.full(len(X0), -1, np.int64)
    slot[nodes] = np.arange(len(nodes))
    i = np.concatenate([edges[:, 1], edges[:, 0]])
    k = np.concatenate([edges[:, 0], edges[:, 1]])
    rows, cols, vals = _block3(3 * slot[i], i, k, np.concatenate([P, P]))
    return Rows(rows, cols, vals, np.zeros(3 * len(nodes)))


def stress_rows(X0, edges, weights, lengths=None) -> Rows:
    """Eq. 2: row e is ``w_e (u_e . (x_i - x_k) - l_e)``; ``lengths`` default to the rest lengths."""
    u, rest = edge_frames(X0, edges)
    lengths = rest if lengths is None else np.asarray(lengths, np.float64)
    wu = np.asarray(weights)[:, None] * u
    e = np.arange(len(edges))
    rows = np.repeat(np.concatenate([e, e]), 3)
    cols = np.concatenate([3 * edges[:, 1, None] + np.arange(3), 3 * edges[:, 0, None] + np.arange(3)]).ravel()
    vals = np.concatenate([wu, -wu]).ravel()
    return Rows(rows, cols, vals, np.asarray(weights) * lengths)


def find_contacts(X0, Fn, component, *, tol: float) -> np.ndarray:
    """Contacts ``(k, 2)``: (node i, triangle t) with node i within ``tol`` of triangle t (inside it,
    up to ``tol``) and every corner of t in another component than i; one triangle per node and
    component pair."""
    tri = X0[Fn]
    centroid = tri.mean(axis=1)
    radius = np.linalg.norm(tri - centroid[:, None], axis=2).max(axis=1) + tol
    tree = cKDTree(X0)
    cand = tree.query_ball_point(centroid, radius)
    counts = np.fromiter((len(c) for c in cand), np.int64, len(cand))
    if counts.sum() == 0:
        return np.zeros((0, 2), np.int64)
    t = np.repeat(np.arange(len(Fn)), counts)
    i = np.concatenate([np.asarray(c, np.int64) for c in cand if len(c)])
    T = Fn[t]
    other = np.all(component[T] != component[i][:, None], axis=1)
    i, t = i[other], t[other]
    a, b, c = X0[Fn[t, 0]], X0[Fn[t, 1]], X0[Fn[t, 2]]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    ok = area2 > 1e-300
    i, t, a, b, c, n, area2 = i[ok], t[ok], a[ok], b[ok], c[ok], n[ok], area2[ok]
    n = n / area2[:, None]
    p = X0[i]
    dist = np.abs(np.einsum("ij,ij->i", p - a, n))
    lam = [np.einsum("ij,ij->i", np.cross(q1 - p, q2 - p), n) / area2 for q1, q2 in ((b, c), (c, a), (a, b))]
    slack = tol / np.sqrt(area2)
    inside = (dist <= tol) & np.all(np.stack(lam) >= -slack[None], axis=0)
    pairs = np.column_stack([i[inside], t[inside]])
    if not len(pairs):
        return pairs.astype(np.int64)
    key = np.column_stack([pairs[:, 0], component[Fn[pairs[:, 1], 0]]])
    _, first = np.unique(key, axis=0, return_index=True)
    return pairs[np.sort(first)].astype(np.int64)


def contact_rows(X0, Fn, contacts, *, strict_weight: float, w_c: float) -> tuple[Rows, Rows]:
    """Eq. 5 (strict, one row per contact: ``(x_i - x_T0) . n_T = 0``) and eq. 6 (soft, nine rows
    per contact: ``w_c ((x_i - x_Tk) - (v_i - v_Tk))``, k = 0..2)."""
    if not len(contacts):
        return Rows.empty(), Rows.empty()
    i, t = contacts[:, 0], contacts[:, 1]
    T = Fn[t]
    a, b, c = X0[T[:, 0]], X0[T[:, 1]], X0[T[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    return _plane_rows(i, T[:, 0], n, strict_weight), _offset_rows(X0, np.tile(i, 3), T.T.ravel(), w_c)


def _plane_rows(a, b, n, w: float) -> Rows:
    """One row per pair: ``w (x_a - x_b) . n = 0`` for unit normals ``n (k, 3)``."""
    k = np.arange(len(a))
    cols = np.concatenate([3 * a[:, None] + np.arange(3), 3 * b[:, None] + np.arange(3)]).ravel()
    return Rows(np.repeat(np.concatenate([k, k]), 3), cols, w * np.concatenate([n, -n]).ravel(), np.zeros(len(a)))


def _offset_rows(X0, a, b, w: float) -> Rows:
    """Three rows per pair ``a (k,)``, ``b (k,)``: ``w ((x_a - x_b) - (v_a - v_b))``."""
    M = np.broadcast_to(w * np.eye(3), (len(a), 3, 3))
    rows, cols, vals = _block3(3 * np.arange(len(a)), a, b, M)
    return Rows(rows, cols, vals, w * (X0[a] - X0[b]).ravel())


def bridge_rows(X0, pairs, normals, *, strict_weight: float, w_c: float) -> tuple[Rows, Rows]:
    """Holes: flat edges ``pairs (k, 2)`` that join two graph components inside one planar surface
    of normal ``normals (k, 3)``. Like a contact, each gets a strict coplanarity row
    ``(x_a - x_b) . n = 0`` (eq. 5) and three soft rows ``w_c ((x_a - x_b) - (v_a - v_b))`` (eq. 6),
    so a hole (a window in a wall) stays in its wall's plane and follows it."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    if not len(pairs):
        return Rows.empty(), Rows.empty()
    n = np.asarray(normals, np.float64)
    return _plane_rows(pairs[:, 0], pairs[:, 1], n, strict_weight), _offset_rows(X0, pairs[:, 0], pairs[:, 1], w_c)


def edge_groups(X0, edges, *, angle_deg: float, length_tol: float, distance: float) -> list[np.ndarray]:
    """Clusters of similar edges: pairs whose midpoints are within ``distance`` times the edge's
    length, whose directions differ by at most ``angle_deg`` (either orientation) and whose
    lengths differ by at most ``length_tol`` of the longer, joined transitively. Returns groups of
    >= 2 edge indices, each sorted (its first edge is the reference)."""
    if len(edges) < 2:
        return []
    u, length = edge_frames(X0, edges)
    mid = 0.5 * (X0[edges[:, 0]] + X0[edges[:, 1]])
    near = cKDTree(mid).query_ball_point(mid, distance * length, return_sorted=False)
    counts = np.fromiter((len(c) for c in near), np.int64, len(near))
    a = np.repeat(np.arange(len(edges)), counts)
    b = np.concatenate([np.asarray(c, np.int64) for c in near])
    keep = a < b
    a, b = a[keep], b[keep]
    same_dir = np.abs(np.einsum("ij,ij->i", u[a], u[b])) >= np.cos(np.radians(angle_deg))
    same_len = np.abs(length[a] - length[b]) <= length_tol * np.maximum(length[a], length[b])
    ok = same_dir & same_len
    n = len(edges)
    G = sp.coo_matrix((np.ones(int(ok.sum())), (a[ok], b[ok])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    size = np.bincount(label)
    order = np.argsort(label, kind="stable")
    splits = np.split(order, np.cumsum(size)[:-1])
    return [s for s in splits if len(s) >= 2]


def group_rows(X0, edges, groups: list[np.ndarray], *, w_g: float) -> Rows:
    """Eq. 7, one row per non-reference edge e of a group G with reference r:
    ``w_g (u_e . (x_e1 - x_e0) - u_r . (x_r1 - x_r0)) = w_g (l_e - l_r)``, edges oriented along the
    reference. The right-hand side keeps the rest lengths' small differences, so the rest shape
    satisfies every row (the paper's printed eq. 7 sums these rows into one per group)."""
    if not groups:
        return Rows.empty()
    u, length = edge_frames(X0, edges)
    ref = np.concatenate([np.full(len(g) - 1, g[0]) for g in groups])
    oth = np.concatenate([g[1:] for g in groups])
    sign = np.sign(np.einsum("ij,ij->i", u[oth], u[ref]))
    ue, ur = u[oth] * sign[:, None], u[ref]
    e_hi = np.where(sign > 0, edges[oth, 1], edges[oth, 0])
    e_lo = np.where(sign > 0, edges[oth, 0], edges[oth, 1])
    k = np.arange(len(oth))
    ar = np.arange(3)
    rows = np.repeat(np.tile(k, 4), 3)
    cols = np.concatenate([
        3 * e_hi[:, None] + ar, 3 * e_lo[:, None] + ar, 3 * edges[ref, 1, None] + ar, 3 * edges[ref, 0, None] + ar
    ]).ravel()
    vals = w_g * np.concatenate([ue, -ue, -ur, ur]).ravel()
    return Rows(rows, cols, vals, w_g * (length[oth] - length[ref]))


def link_rows(X0, links, *, strict_weight: float) -> Rows:
    """User links ``(k, 2)`` node pairs (Fig. 6): ``x_a - x_b = v_a - v_b``, three strict rows each."""
    links = np.asarray(links, np.int64).reshape(-1, 2)
    if not len(links):
        return Rows.empty()
    return _offset_rows(X0, links[:, 0], links[:, 1], strict_weight)


def attach_rows(X0, Fn, attachment, *, strict_weight: float) -> Rows:
    """Parts carried by a host surface (beyond the paper): for each attached cluster of
    nodes N with host triangle T and barycentric coordinates lam (a :class:`parts.Attachment`),
    three strict rows ``mean_{i in N} x_i - sum_k lam_k x_Tk = (the same on X0)``: the cluster's
    centroid keeps its offset to the host point beneath it, so a window goes where its wall takes
    it (eq. 1 on its own edges keeps it from turning)."""
    if not len(attachment.nodes):
        return Rows.empty()
    rows, cols, vals, b = [], [], [], []
    for k, (nodes, t, lam) in enumerate(zip(attachment.nodes, attachment.tri, attachment.bary, strict=True)):
        ids = np.concatenate([nodes, Fn[t]])
        w = strict_weight * np.concatenate([np.full(len(nodes), 1.0 / len(nodes)), -lam])
        for c in range(3):
            rows.append(np.full(len(ids), 3 * k + c))
            cols.append(3 * ids + c)
            vals.append(w)
        b.append(w @ X0[ids])
    return Rows(np.concatenate(rows), np.concatenate(cols), np.concatenate(vals), np.concatenate(b))


def stack_rows(blocks: dict[str, Rows], n_nodes: int) -> tuple[sp.csr_matrix, np.ndarray, dict[str, slice]]:
    """Stack named blocks into ``A (m, 3 n)`` CSR and ``b (m,)``; returns the row slice of each block."""
    offset, rows, cols, vals, bs, where = 0, [], [], [], [], {}
    for name, blk in blocks.items():
        rows.append(blk.rows + offset)
        cols.append(blk.cols)
        vals.append(blk.vals)
        bs.append(blk.b)
        where[name] = slice(offset, offset + blk.m)
        offset += blk.m
    A = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(offset, 3 * n_nodes)
    )
    A.sum_duplicates()
    return A, np.concatenate(bs), where
