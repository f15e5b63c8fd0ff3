"""Labelling a graph ``edges (E, 2)``, ``weights (E,)`` with region costs ``unary (n, L)`` and fixed
nodes ``seeds (n,)`` (-1 free): single level and multiresolution (section 3.5).

Energy: ``sum_p unary[p, l_p] + sum_(p,q) weights[pq] [l_p != l_q]`` with every fixed node held to
its region. Two regions are solved exactly by one s-t min cut (:func:`synthkit.core.graphcut.mincut`),
three or more by alpha-expansion on the same costs (:func:`synthkit.core.graphcut.alpha_expansion`,
Potts pairwise terms with per-edge weights, within a factor 2 of the optimum).

Multiresolution: ``maps[k]`` sends the nodes of level k to those of level k + 1 (level 0 the
finest). A coarse problem is the exact contraction of the finer one: node costs and the weights of
edges joining two clusters are summed, so a coarse labelling costs what its lifting costs. A
cluster is first split into the connected pieces its inner edges leave when barrier edges (sharp
concave creases) are removed, so that no cluster hides a crease the cut may follow, then a cluster
holding fixed nodes of two regions is split by region (its free nodes form one more cluster).
The coarsest level is solved whole; at each finer level only the free nodes within
``band_rings`` rings of the lifted cut take part, the others keep their coarse labels and enter
the band's problem as node costs; when the new cut reaches the band's edge, the band moves onto
it and is solved again. The coarse cut can only run where clusters meet: with boundary costs
alone, whose cheapest cuts are often nearly tied, a coarse cut can settle in a parallel place the
bands cannot leave (docs/findings/surface-by-numbers.md).

Static and per-stroke work: :func:`build_hierarchy` does what depends on the mesh alone (barrier
splits, the coarse graphs' edges and weights, each level's adjacency), once; :func:`solve_multires`
then contracts the node costs and strokes and solves. A stroke set that puts fixed nodes of two
regions into one cluster splits that cluster, and the levels are then contracted again from the raw
maps (the same result as the static path whenever there is no such cluster).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from synthkit.core.graphcut import alpha_expansion, mincut

__all__ = [
    "Problem", "Hierarchy", "solve_labels", "cut_cost", "contract", "build_hierarchy", "solve_multires",
    "band_nodes", "adjacency", "incidence",
]


@dataclass
class Problem:
    """One level: ``unary (n, L)`` finite, ``edges (E, 2)``, ``weights (E,)``, ``seeds (n,)`` and
    optionally ``barrier (E,) bool``, edges no cluster may contain (kept at every coarser level)."""

    unary: np.ndarray
    edges: np.ndarray
    weights: np.ndarray
    seeds: np.ndarray
    barrier: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.seeds)


def solve_labels(unary, edges, weights, seeds, *, init=None, rng=None) -> np.ndarray:
    """Optimal (two regions) or alpha-expansion (more) labels ``(n,) int64``."""
    u = np.array(unary, dtype=np.float64)
    u -= u.min(axis=1, keepdims=True)  # a constant per node: the same minimiser, costs >= 0 for the cut
    n, n_labels = u.shape
    fixed = np.flatnonzero(seeds >= 0)
    own = u[fixed, seeds[fixed]]
    u[fixed] = np.inf
    u[fixed, seeds[fixed]] = own
    if n_labels == 2:
        side, _ = mincut(n, edges, weights, weights, u[:, 1], u[:, 0])
        return side.astype(np.int64)
    w = np.asarray(weights, np.float64)

    def potts(eidx, la, lb):
        return w[eidx] * (la != lb)

    if init is not None:
        init = np.where(seeds >= 0, seeds, init)
    return alpha_expansion(u, edges, potts, init=init, rng=rng).labels


def cut_cost(labels, edges, weights) -> float:
    """Sum of the weights of the edges whose ends have different labels."""
    return float(np.asarray(weights)[labels[edges[:, 0]] != labels[edges[:, 1]]].sum())


def _split_conflicts(cluster: np.ndarray, seeds: np.ndarray, n_labels: int) -> tuple[np.ndarray, np.ndarray]:
    """Split clusters holding fixed nodes of two regions; returns new ``cluster (n,)`` and the old
    cluster of each new one ``origin (n_new,)``."""
    s = seeds >= 0
    pairs = np.unique(cluster[s] * n_labels + seeds[s])
    counts = np.bincount(pairs // n_labels, minlength=int(cluster.max()) + 1)
    conflicted = counts[cluster] > 1
    key = cluster * (n_labels + 1) + np.where(conflicted, seeds + 1, 0)
    uniq, new = np.unique(key, return_inverse=True)
    return new.astype(np.int64), uniq // (n_labels + 1)


def _split_barriers(cluster: np.ndarray, p: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Split each cluster that contains a barrier edge into the connected pieces its non-barrier
    inner edges leave; returns new ``cluster (n,)`` and ``origin (n_new,)`` (identity maps when no
    cluster contains a barrier)."""
    e = p.edges
    inner = cluster[e[:, 0]] == cluster[e[:, 1]]
    cut = np.zeros(int(cluster.max()) + 1, bool)
    if p.barrier is not None:
        cut[cluster[e[inner & p.barrier, 0]]] = True
    if not cut.any():
        return cluster, np.arange(len(cut))
    keep = inner & ~(p.barrier & inner)
    keep |= inner & ~cut[cluster[e[:, 0]]]
    A = sp.coo_matrix((np.ones(int(keep.sum())), (e[keep, 0], e[keep, 1])), shape=(p.n, p.n))
    _, comp = connected_components(A, directed=False)
    key = np.where(cut[cluster], comp + len(cut), cluster)
    uniq, new = np.unique(key, return_inverse=True)
    origin = np.zeros(len(uniq), np.int64)
    origin[new] = cluster
    return new.astype(np.int64), origin


def _contract_graph(p: Problem, cluster: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The coarse ``edges (E', 2)``, summed ``weights (E',)`` and ``barrier (E',)`` (any fine barrier
    edge between the two clusters) of the clusters ``cluster (n,)`` of ``p``'s nodes."""
    nc = int(cluster.max()) + 1
    e = np.sort(cluster[p.edges], axis=1)
    keep = e[:, 0] != e[:, 1]
    key, inv = np.unique(e[keep, 0] * nc + e[keep, 1], return_inverse=True)
    weights = np.bincount(inv, weights=p.weights[keep], minlength=len(key))
    edges = np.stack([key // nc, key % nc], axis=1)
    barrier = None
    if p.barrier is not None:
        barrier = np.bincount(inv, weights=p.barrier[keep], minlength=len(key)) > 0
    return edges, weights, barrier


def _contract_costs(unary: np.ndarray, seeds: np.ndarray, cluster: np.ndarray, nc: int):
    """Summed node costs ``(nc, L)`` and the fixed region ``(nc,)`` of each cluster (-1: none)."""
    member = sp.csr_matrix((np.ones(len(cluster)), (cluster, np.arange(len(cluster)))), shape=(nc, len(cluster)))
    coarse = member @ unary
    fixed = np.flatnonzero(seeds >= 0)
    coarse_seeds = np.full(nc, -1, np.int64)
    np.maximum.at(coarse_seeds, cluster[fixed], seeds[fixed])
    return coarse, coarse_seeds


def contract(p: Problem, cluster: np.ndarray) -> Problem:
    """The coarse problem whose nodes are the clusters ``cluster (n,)`` of ``p``'s nodes."""
    nc = int(cluster.max()) + 1
    unary, seeds = _contract_costs(p.unary, p.seeds, cluster, nc)
    edges, weights, barrier = _contract_graph(p, cluster)
    return Problem(unary, edges, weights, seeds, barrier)


def adjacency(n: int, edges: np.ndarray) -> sp.csr_matrix:
    """Symmetric ``(n, n)`` boolean adjacency of ``edges``."""
    return sp.csr_matrix((np.ones(2 * len(edges), bool), (edges.ravel(), edges[:, ::-1].ravel())), shape=(n, n))


def band_nodes(n: int, edges: np.ndarray, labels: np.ndarray, rings: int, A=None) -> np.ndarray:
    """Nodes ``(n,) bool`` within ``rings`` rings of an edge whose ends differ in ``labels`` (ring 1
    is the cut edges' ends); rings grow from the cut only, over the adjacency ``A`` (built when
    not given)."""
    cut = labels[edges[:, 0]] != labels[edges[:, 1]]
    band = np.zeros(n, bool)
    band[edges[cut].ravel()] = True
    if rings > 1 and band.any():
        A = adjacency(n, edges) if A is None else A
        _spread(A, band, np.flatnonzero(band), rings - 1)
    return band


def _spread(A: sp.csr_matrix, reached: np.ndarray, frontier: np.ndarray, rings: int) -> None:
    """Mark in ``reached (n,) bool`` the nodes within ``rings`` rings of ``frontier`` (in place)."""
    for _ in range(rings):
        nb = _row_entries(A, frontier)
        frontier = np.unique(nb[~reached[nb]])
        reached[frontier] = True


def _row_entries(M: sp.csr_matrix, rows: np.ndarray) -> np.ndarray:
    """The column indices stored in the rows ``rows (k,)`` of ``M``, row after row: ``M[rows].indices``
    without building the sub-matrix."""
    start, stop = M.indptr[rows], M.indptr[rows + 1]
    lengths = stop - start
    offsets = np.repeat(start - np.cumsum(lengths) + lengths, lengths)
    return M.indices[offsets + np.arange(int(lengths.sum()))]


def incidence(n: int, edges: np.ndarray) -> sp.csr_matrix:
    """``(n, E)`` node-edge incidence: row ``i`` holds the indices of the edges at node ``i``."""
    ends = edges.ravel()
    ids = np.repeat(np.arange(len(edges)), 2)
    return sp.csr_matrix((np.ones(len(ends), bool), (ends, ids)), shape=(n, len(edges)))


def _nearby_labels(idx: np.ndarray, labels: np.ndarray, sub: Problem, rim: tuple, n_labels: int,
                   hops: int) -> np.ndarray:
    """``(k, L) bool``: the labels found within ``hops`` steps of each node ``idx (k,)`` (its own
    included): the first step over every edge (``sub``'s inner edges and the ``rim`` edges to held
    nodes, given as ``(local node, held label)``), the others within ``sub``."""
    k = len(idx)
    own = np.zeros((k, n_labels), bool)
    own[np.arange(k), labels[idx]] = True
    e = sub.edges
    M = sp.csr_matrix((np.ones(2 * len(e), np.uint8), (e.ravel(), e[:, ::-1].ravel())), shape=(k, k))
    reach = own | ((M @ own.astype(np.uint8)) > 0)
    reach[rim[0], rim[1]] = True
    for _ in range(hops - 1):
        reach |= (M @ reach.astype(np.uint8)) > 0
    return reach


def _subproblem(p: Problem, labels: np.ndarray, mask: np.ndarray, inc=None) -> tuple[Problem, np.ndarray, tuple]:
    """The problem of the nodes ``mask (n,) bool`` with every other node held at ``labels``: the
    edges to held nodes become node costs. Returns it, the nodes' indices ``(k,)`` and those rim
    edges as ``(local node (r,), held label (r,))``. ``inc``: ``p``'s :func:`incidence`, which finds
    the nodes' edges without a pass over all of ``p``'s (built when not given)."""
    idx = np.flatnonzero(mask)
    inc = incidence(p.n, p.edges) if inc is None else inc
    eids, count = np.unique(_row_entries(inc, idx), return_counts=True)
    inner, cross = eids[count == 2], eids[count == 1]
    unary = p.unary[idx].copy()
    first_inside = mask[p.edges[cross, 0]]
    nodes, others = [], []
    for a, b, side in ((0, 1, first_inside), (1, 0, ~first_inside)):
        rim = cross[side]
        node, other = np.searchsorted(idx, p.edges[rim, a]), labels[p.edges[rim, b]]
        w = p.weights[rim]
        np.add.at(unary, node, w[:, None])
        np.add.at(unary, (node, other), -w)
        nodes.append(node)
        others.append(other)
    sub = Problem(unary, np.searchsorted(idx, p.edges[inner]), p.weights[inner], p.seeds[idx])
    return sub, idx, (np.concatenate(nodes), np.concatenate(others))


def _band_solve(p: Problem, labels: np.ndarray, free: np.ndarray, rng, inc: sp.csr_matrix,
                hops: int = 3) -> tuple[np.ndarray, int]:
    """Best labels of the ``free (n,) bool`` nodes with every other node held; returns the labels and
    the number of edges of the graph cut solved. With three or more labels a node may take only
    the labels found within ``hops`` steps of it (the regions the cut runs between). The band's
    connected pieces are independent problems (every edge to a held node is a node cost), so each
    is solved alone over the labels its nodes may take: two of them, as usual between two regions,
    give one exact s-t cut (:func:`_solve_pieces`)."""
    sub, idx, rim = _subproblem(p, labels, free, inc)
    unary = sub.unary
    if unary.shape[1] > 2:
        unary[~_nearby_labels(idx, labels, sub, rim, unary.shape[1], hops)] = np.inf
    out = labels.copy()
    out[idx] = _solve_pieces(unary, sub, labels[idx], rng)
    return out, int(len(sub.edges))


def _improves(before, after):
    """Strictly lower, beyond rounding (elementwise on arrays): equal-cost alternatives leave the
    labels as they were, so ties do not drift."""
    return after < before - 1e-9 * np.maximum(np.abs(before), 1.0)


def _solve_pieces(unary: np.ndarray, sub: Problem, init: np.ndarray, rng) -> np.ndarray:
    """Labels ``(k,)`` of the band ``sub`` with costs ``unary (k, L)`` (infinite: a label the node may
    not take), from ``init (k,)``. The band's connected pieces are independent: every piece offered
    two labels is solved in one exact s-t cut together with the others, the pieces offered more in
    one alpha-expansion; a piece takes its new labels only when they lower its energy."""
    k, e = len(init), sub.edges
    graph = sp.csr_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(k, k))
    n_pieces, piece = connected_components(graph, directed=False)
    node, label = np.nonzero(np.isfinite(unary))
    offered = np.zeros((n_pieces, unary.shape[1]), bool)
    offered[piece[node], label] = True
    n_offered = offered.sum(axis=1)[piece]
    new = init.copy()
    two = np.flatnonzero(n_offered == 2)
    if len(two):
        first = np.argmax(offered, axis=1)[piece[two]]
        last = unary.shape[1] - 1 - np.argmax(offered[:, ::-1], axis=1)[piece[two]]
        part = _part(unary, sub, two)
        rows = np.arange(len(two))
        side = solve_labels(np.stack([part.unary[rows, first], part.unary[rows, last]], axis=1),
                            part.edges, part.weights, part.seeds)
        new[two] = np.where(side == 1, last, first)
    more = np.flatnonzero(n_offered > 2)
    if len(more):
        new[more] = _solve_offered(_part(unary, sub, more), init[more], rng)
    before, after = (_piece_energy(unary, sub, piece, n_pieces, lab) for lab in (init, new))
    return np.where(_improves(before, after)[piece], new, init)


def _part(unary: np.ndarray, sub: Problem, nodes: np.ndarray) -> Problem:
    """The problem of ``sub``'s nodes ``nodes (m,)`` (sorted; whole connected pieces, so no edge
    leaves them), numbered ``0..m-1``."""
    inside = np.zeros(sub.n, bool)
    inside[nodes] = True
    eidx = np.flatnonzero(inside[sub.edges[:, 0]])
    return Problem(unary[nodes], np.searchsorted(nodes, sub.edges[eidx]), sub.weights[eidx], np.full(len(nodes), -1))


def _piece_energy(unary: np.ndarray, sub: Problem, piece: np.ndarray, n_pieces: int, labels: np.ndarray):
    """Energy ``(n_pieces,)`` of each connected piece of ``sub`` under ``labels (k,)``."""
    e = sub.edges
    node = np.bincount(piece, weights=unary[np.arange(len(labels)), labels], minlength=n_pieces)
    cut = sub.weights * (labels[e[:, 0]] != labels[e[:, 1]])
    return node + np.bincount(piece[e[:, 0]], weights=cut, minlength=n_pieces)


def _solve_offered(part: Problem, init: np.ndarray, rng) -> np.ndarray:
    """:func:`solve_labels` of ``part`` over only the labels some node may take (finite in its
    ``unary (k, L)``; two of them: one exact s-t cut), from ``init (k,)``; labels in ``0..L-1``."""
    offered = np.flatnonzero(np.isfinite(part.unary).any(axis=0))
    if len(offered) == 1:
        return np.full(len(init), offered[0])
    rank = np.cumsum(np.isin(np.arange(part.unary.shape[1]), offered)) - 1
    local = solve_labels(part.unary[:, offered], part.edges, part.weights, part.seeds, init=rank[init], rng=rng)
    return offered[local]


def _refine(p: Problem, labels: np.ndarray, rings: int, rng, *, A=None, inc=None,
            reach: int = 8) -> tuple[np.ndarray, dict]:
    """Re-solve the free nodes of ``p`` near the cut of ``labels``; others keep their labels. The
    bands move inside the nodes within ``reach * rings`` rings of the first band (:func:`_slide`),
    so the work grows with the length of the cut, not with the size of the graph. ``A``, ``inc``:
    ``p``'s adjacency and incidence (built when not given)."""
    A = adjacency(p.n, p.edges) if A is None else A
    band = band_nodes(p.n, p.edges, labels, rings, A)
    seen = np.zeros(p.n, bool)
    stats = {"nodes": p.n, "free_nodes": 0, "edges": 0, "bands": 0, "free": seen}
    if not band.any():
        return labels, stats
    sub, idx, _ = _subproblem(p, labels, _grow(A, np.flatnonzero(band), reach * rings), inc)
    sub_labels, stats = _slide(sub, labels[idx], rings, rng)
    out = labels.copy()
    out[idx] = sub_labels
    seen[idx] = stats["free"]
    stats.update(nodes=p.n, free=seen)
    return out, stats


def _slide(p: Problem, labels: np.ndarray, rings: int, rng, max_moves: int = 32) -> tuple[np.ndarray, dict]:
    """Bands around the cut of ``labels`` solved in turn. Where the new labels change on the band's
    rim (or leave the band), the new cut's band within ``3 rings`` of those nodes is solved again,
    so a cut can slide past the band of its first guess while each further band stays local; once
    nothing moves, the whole band of the cut is solved once more, and the process goes on until
    that changes nothing (at most ``max_moves`` bands)."""
    seen = np.zeros(p.n, bool)
    stats = {"nodes": p.n, "free_nodes": 0, "edges": 0, "bands": 0}
    A, inc = adjacency(p.n, p.edges), incidence(p.n, p.edges)
    free = band_nodes(p.n, p.edges, labels, rings, A) & (p.seeds < 0)
    whole = True
    for _ in range(max_moves):
        if not free.any():
            break
        new, n_edges = _band_solve(p, labels, free, rng, inc)
        seen |= free
        stats["edges"] += n_edges
        stats["bands"] += 1
        changed = new != labels
        labels = new
        band = band_nodes(p.n, p.edges, labels, rings, A) & (p.seeds < 0)
        moved = np.flatnonzero(changed & ((free & ~band) | _rim(A, free)))
        if len(moved):
            free, whole = band & _grow(A, moved, 3 * rings), False  # the new cut's band where it moved
        elif whole:
            break
        else:
            free, whole = band, True  # settled locally: check with the whole band once more
    stats["free_nodes"] = int(seen.sum())
    stats["free"] = seen
    return labels, stats


def _grow(A: sp.csr_matrix, start: np.ndarray, rings: int) -> np.ndarray:
    """Nodes ``(n,) bool`` within ``rings`` rings of the nodes ``start``."""
    out = np.zeros(A.shape[0], bool)
    out[start] = True
    _spread(A, out, start, rings)
    return out


def _rim(A: sp.csr_matrix, free: np.ndarray) -> np.ndarray:
    """Nodes of ``free (n,) bool`` with a neighbour outside it (over the adjacency ``A``)."""
    idx = np.flatnonzero(free)
    rim = np.zeros(len(free), bool)
    rim[idx[A[idx] @ (~free).astype(np.int32) > 0]] = True
    return rim


@dataclass
class Hierarchy:
    """The static part of a multiresolution solve. ``maps``: the raw level-of-detail maps (finest
    first); ``clusters[k] (n_k,)``: level k's nodes to level k + 1's after barrier splits;
    ``graphs[k]``: level k's ``(edges, weights, barrier)`` (level 0 the fine graph); ``adjacency[k]``
    and ``incidence[k]``: level k's :func:`adjacency` and :func:`incidence`."""

    maps: list[np.ndarray]
    clusters: list[np.ndarray]
    graphs: list[tuple]
    adjacency: list[sp.csr_matrix]
    incidence: list[sp.csr_matrix]

    @property
    def depth(self) -> int:
        return len(self.clusters)


def build_hierarchy(fine: Problem, maps: list[np.ndarray]) -> Hierarchy:
    """Barrier-split clusters and contracted graphs of ``fine`` through ``maps`` (its node costs
    and strokes are not used)."""
    graphs = [(fine.edges, fine.weights, fine.barrier)]
    clusters, sizes = [], [fine.n]
    raw = list(maps)
    for k in range(len(raw)):
        level = Problem(np.zeros((sizes[-1], 0)), *graphs[-1][:2], np.full(sizes[-1], -1), graphs[-1][2])
        cluster, origin = _split_barriers(raw[k], level)
        if k + 1 < len(raw):
            raw[k + 1] = raw[k + 1][origin]
        clusters.append(cluster)
        sizes.append(int(cluster.max()) + 1)
        graphs.append(_contract_graph(level, cluster))
    A = [adjacency(n, g[0]) for n, g in zip(sizes, graphs, strict=True)]
    inc = [incidence(n, g[0]) for n, g in zip(sizes, graphs, strict=True)]
    return Hierarchy(list(maps), clusters, graphs, A, inc)


def _static_levels(fine: Problem, h: Hierarchy) -> list[Problem] | None:
    """The levels of ``fine`` on ``h``'s static clusters, or None when a cluster would hold fixed
    nodes of two regions."""
    levels = [fine]
    for k, cluster in enumerate(h.clusters):
        p = levels[-1]
        fixed = np.flatnonzero(p.seeds >= 0)
        pairs = np.unique(cluster[fixed] * p.unary.shape[1] + p.seeds[fixed]) // p.unary.shape[1]
        if len(pairs) != len(np.unique(pairs)):
            return None
        unary, seeds = _contract_costs(p.unary, p.seeds, cluster, h.adjacency[k + 1].shape[0])
        levels.append(Problem(unary, *h.graphs[k + 1][:2], seeds, h.graphs[k + 1][2]))
    return levels


def _split_levels(fine: Problem, maps: list[np.ndarray]) -> tuple[list[Problem], list[np.ndarray]]:
    """Levels and clusters of ``fine`` through the raw ``maps``, splitting barrier clusters and
    clusters that hold fixed nodes of two regions."""
    L = fine.unary.shape[1]
    levels, clusters = [fine], []
    maps = list(maps)
    for k in range(len(maps)):
        cluster, origin = _split_barriers(maps[k], levels[-1])
        cluster, origin2 = _split_conflicts(cluster, levels[-1].seeds, L)
        if k + 1 < len(maps):
            maps[k + 1] = maps[k + 1][origin[origin2]]
        clusters.append(cluster)
        levels.append(contract(levels[-1], cluster))
    return levels, clusters


def solve_multires(fine: Problem, hierarchy: Hierarchy, *, band_rings: int, rng=None):
    """Labels ``(n,)`` of ``fine`` through ``hierarchy`` (:func:`build_hierarchy` of ``fine``'s graph);
    also a list of per-level stats (finest first): ``nodes``, ``free_nodes``, ``edges`` (of the graph
    cut solved), ``seconds`` and ``free (n,) bool`` (the level's free nodes, seen from the finest
    nodes)."""
    levels = _static_levels(fine, hierarchy)
    clusters, A, inc = hierarchy.clusters, hierarchy.adjacency, hierarchy.incidence
    if levels is None:
        levels, clusters = _split_levels(fine, hierarchy.maps)
        A = inc = [None] * len(levels)
    to_level = [np.arange(fine.n)]
    for cluster in clusters:
        to_level.append(cluster[to_level[-1]])
    top = levels[-1]
    t0 = time.perf_counter()
    labels = solve_labels(top.unary, top.edges, top.weights, top.seeds, rng=rng)
    stats = [{"nodes": top.n, "free_nodes": int((top.seeds < 0).sum()), "edges": int(len(top.edges)),
              "seconds": time.perf_counter() - t0, "free": (top.seeds < 0)[to_level[-1]]}]
    for k in range(len(clusters) - 1, -1, -1):
        t0 = time.perf_counter()
        labels, st = _refine(levels[k], labels[clusters[k]], band_rings, rng, A=A[k], inc=inc[k])
        st["seconds"] = time.perf_counter() - t0
        st["free"] = st["free"][to_level[k]]
        stats.append(st)
    return labels, stats[::-1]
