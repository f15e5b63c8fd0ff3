"""Graph cuts on sparse graphs in edge-list form: binary s-t min-cut and multi-label alpha-expansion.

A graph has ``n`` nodes numbered ``0..n-1`` and ``edges`` as an ``(E, 2) int`` array of node pairs.
Costs are ``float64``. Infinite costs are written ``np.inf``; any value ``>= INF`` counts as infinite
too, so callers may use either. Internally an infinite cost becomes a finite constant larger than twice
the sum of all finite costs of the same cut problem, so that one such cost outweighs any combination of
finite ones, and results are checked to be finite afterwards.

Binary min-cuts use PyMaxflow (Boykov-Kolmogorov max-flow, ``maxflow.Graph[float]``).
Alpha-expansion (Boykov, Veksler and Zabih, PAMI 2001) is our own because the retargeting method
needs pairwise costs that depend on the edge (position-dependent tables or a cost function), which
PyMaxflow's ``fastmin`` grid routines cannot express. Its moves run on the Boykov-Kolmogorov
max-flow of :mod:`synthkit.core.flow`, which keeps each label's residual graph from one move on
the label to the next (Kohli and Torr's dynamic graph cuts), compiled with numba like the move
construction itself.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import maxflow
import numba
import numpy as np

from synthkit.core.flow import ResidualGraph, bk_max_flow, saturate_greedy, update_residual
from synthkit.core.numba_cache import NUMBA_CACHE
from synthkit.core.tol import tol

INF = 1e12
"""Costs at or above this value are treated as infinite (forbidden), exactly like ``np.inf``."""

PairwiseFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

_KEPT_EDGES = 3 << 20  # edges kept across moves, summed over labels: ~104 bytes each with graph, 330 MB at most


# --------------------------------------------------------------------------------------------------
# validation helpers


def _as_edges(edges, n: int, name: str = "edges") -> np.ndarray:
    e = np.asarray(edges)
    if e.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if e.ndim != 2 or e.shape[1] != 2:
        raise ValueError(f"{name} must have shape (E, 2), got {e.shape}")
    if not np.issubdtype(e.dtype, np.integer):
        raise ValueError(f"{name} must be integers, got dtype {e.dtype}")
    lo, hi = int(e.min()), int(e.max())
    if lo < 0 or hi >= n:
        raise ValueError(f"{name} index out of range [0, {n}): found {lo if lo < 0 else hi}")
    e = e.astype(np.int64, copy=False)
    loops = e[:, 0] == e[:, 1]
    if loops.any():
        k = int(np.flatnonzero(loops)[0])
        raise ValueError(f"{name}[{k}] is a self-loop ({e[k, 0]}, {e[k, 1]})")
    return e


def _as_costs(values, shape: tuple[int, ...], name: str, *, nonnegative: bool) -> np.ndarray:
    """Return ``values`` as a float64 array of ``shape`` with every value ``>= INF`` set to ``np.inf``.

    The input array itself is returned (no copy) when it is already float64 and has no value in
    ``[INF, inf)``; one min and one max pass check NaN, negative values and ``-inf``.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {v.shape}")
    if v.size == 0:
        return v
    lo, hi = v.min(), v.max()
    if np.isnan(lo):
        raise ValueError(f"{name} contains NaN")
    if nonnegative and lo < 0:
        raise ValueError(f"{name} must be non-negative, found {float(lo)}")
    if lo == -np.inf:
        raise ValueError(f"{name} contains -inf")
    if hi >= INF and not np.isinf(v[v >= INF]).all():
        v = np.where(v >= INF, np.inf, v)
    return v


def _finite_sum(v: np.ndarray) -> float:
    """Sum of the finite entries of a cost array without NaN and ``-inf``."""
    if v.size == 0 or v.max() < np.inf:
        return float(v.sum())
    return float(v[np.isfinite(v)].sum())


def _finite_or(v: np.ndarray, big: float) -> np.ndarray:
    """``v`` with ``np.inf`` replaced by ``big`` (``v`` itself when it has no infinite entry)."""
    if v.size == 0 or v.max() < np.inf:
        return v
    return np.where(np.isinf(v), big, v)


# --------------------------------------------------------------------------------------------------
# binary min-cut


def mincut(n: int, edges, cap, rev_cap, source, sink) -> tuple[np.ndarray, float]:
    """Minimum s-t cut of a directed graph with terminal links.

    Parameters
    ----------
    n : int
        Number of non-terminal nodes.
    edges : (E, 2) int
        Node pairs ``(p, q)``.
    cap, rev_cap : (E,) float
        Capacity of ``p -> q`` and of ``q -> p``; non-negative, ``np.inf`` (or ``>= INF``) allowed.
    source, sink : (n,) float
        Capacity of ``s -> p`` and of ``p -> t``; non-negative, infinite allowed (seeds).

    Returns
    -------
    side : (n,) bool
        ``True`` for nodes on the sink side of the cut. A node in the sink side pays ``source[p]``,
        a node in the source side pays ``sink[p]``, an edge ``p -> q`` is cut when ``p`` is on the
        source side and ``q`` on the sink side.
    flow : float
        Maximum flow = capacity of the minimum cut; ``np.inf`` when every cut has an infinite edge.
        Ties between equal cuts are resolved towards the source side (PyMaxflow's convention).
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    e = _as_edges(edges, n)
    m = len(e)
    c = _as_costs(cap, (m,), "cap", nonnegative=True)
    r = _as_costs(rev_cap, (m,), "rev_cap", nonnegative=True)
    s = _as_costs(source, (n,), "source", nonnegative=True)
    t = _as_costs(sink, (n,), "sink", nonnegative=True)
    same = r is c
    finite_total = _finite_sum(s) + _finite_sum(t) + _finite_sum(c) * (2 if same else 1)
    if not same:
        finite_total += _finite_sum(r)
    big = 2.0 * finite_total + 1.0
    s, t, c = _finite_or(s, big), _finite_or(t, big), _finite_or(c, big)
    r = c if same else _finite_or(r, big)
    g = maxflow.Graph[float](n, max(m, 1))
    ids = g.add_nodes(n)
    g.add_grid_tedges(ids, s, t)
    if m:
        g.add_edges(np.ascontiguousarray(e[:, 0]), np.ascontiguousarray(e[:, 1]), c, r)
    flow = float(g.maxflow())
    side = g.get_grid_segments(ids)
    if flow > 1.5 * finite_total + 0.5:
        flow = np.inf
    return side, flow


def grid_mincut(source, sink, weights, *, structure=None) -> tuple[np.ndarray, float]:
    """Minimum s-t cut on a regular grid of any dimension with undirected neighbour edges.

    Parameters
    ----------
    source, sink : (*S) float
        Terminal capacities per grid cell (``s -> p`` and ``p -> t``), non-negative, infinite allowed.
    weights : float, (*S) float, or mapping ``{offset tuple: float or (*S) float}``
        Without a mapping: the capacity of every edge from cell ``x`` to ``x + o`` for each offset
        ``o`` of ``structure`` (the weight of the edge is read at ``x``). With a mapping: one entry
        per offset, e.g. ``{(0, 1): right, (1, 0): down}``, each weight read at the edge's first cell.
        Edges leaving the grid are dropped. Edges are undirected (same capacity both ways).
    structure : (3, ..., 3) array, optional
        Neighbourhood used with non-mapping ``weights``: non-zero entries mark the offsets (relative
        to the centre) that get an edge. Default: the forward axis neighbours (4-connectivity in 2-D,
        6 in 3-D). Ignored when ``weights`` is a mapping.

    Returns
    -------
    side : (*S) bool
        ``True`` on the sink side.
    flow : float
        Capacity of the minimum cut (``np.inf`` when infinite).
    """
    src = np.asarray(source, dtype=np.float64)
    shape = src.shape
    if src.ndim < 1 or src.size == 0:
        raise ValueError(f"source must be a non-empty grid, got shape {shape}")
    src = _as_costs(src, shape, "source", nonnegative=True)
    snk = _as_costs(sink, shape, "sink", nonnegative=True)
    nd = len(shape)
    if isinstance(weights, Mapping):
        items = list(weights.items())
    else:
        if structure is None:
            structure = np.zeros((3,) * nd)
            for ax in range(nd):
                idx = [1] * nd
                idx[ax] = 2
                structure[tuple(idx)] = 1
        st = np.asarray(structure, dtype=np.float64)
        if st.shape != (3,) * nd:
            raise ValueError(f"structure must have shape {(3,) * nd}, got {st.shape}")
        w = np.asarray(weights, dtype=np.float64)
        items = [(tuple(int(i) - 1 for i in o), w * st[tuple(o)]) for o in np.argwhere(st != 0)]
    ids = np.arange(src.size).reshape(shape)
    pairs, caps = [], []
    for off, w in items:
        off = tuple(int(o) for o in off)
        if len(off) != nd or all(o == 0 for o in off):
            raise ValueError(f"weights offset {off} must be a non-zero {nd}-tuple")
        try:
            wf = np.broadcast_to(np.asarray(w, dtype=np.float64), shape)
        except ValueError:
            raise ValueError(f"weights for offset {off} do not broadcast to grid shape {shape}") from None
        a = tuple(slice(max(0, -o), s - max(0, o)) for o, s in zip(off, shape, strict=True))
        b = tuple(slice(max(0, o), s - max(0, -o)) for o, s in zip(off, shape, strict=True))
        pairs.append(np.stack([ids[a].ravel(), ids[b].ravel()], axis=1))
        caps.append(_as_costs(wf[a].ravel(), (pairs[-1].shape[0],), f"weights{off}", nonnegative=True))
    e = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
    c = np.concatenate(caps) if caps else np.zeros(0)
    side, flow = mincut(src.size, e, c, c, src.ravel(), snk.ravel())
    return side.reshape(shape), flow


# --------------------------------------------------------------------------------------------------
# multi-label energies


class _Pairwise:
    """Evaluates pairwise costs ``V_e(la, lb)`` for arrays of edges, with ``>= INF`` mapped to inf."""

    def __init__(self, pairwise, n_edges: int, n_labels: int):
        self.fn: PairwiseFn | None = None
        self.table: np.ndarray | None = None
        self.per_edge = False
        if callable(pairwise):
            self.fn = pairwise
            return
        t = np.asarray(pairwise, dtype=np.float64)
        if t.shape == (n_labels, n_labels):
            self.table = _as_costs(t, t.shape, "pairwise", nonnegative=False)
        elif t.shape == (n_edges, n_labels, n_labels):
            self.table = _as_costs(t, t.shape, "pairwise", nonnegative=False)
            self.per_edge = True
        else:
            raise ValueError(
                f"pairwise must be a callable, an (L, L) = {(n_labels, n_labels)} table or an "
                f"(E, L, L) = {(n_edges, n_labels, n_labels)} table, got shape {t.shape}"
            )

    def __call__(self, eidx: np.ndarray, la: np.ndarray, lb: np.ndarray) -> np.ndarray:
        if self.fn is None:
            if self.per_edge:
                return self.table[eidx, la, lb]
            return self.table[la, lb]
        v = np.asarray(self.fn(eidx, la, lb), dtype=np.float64)
        if v.shape != eidx.shape:
            raise ValueError(f"pairwise function returned shape {v.shape}, expected {eidx.shape}")
        if np.isnan(v).any():
            raise ValueError("pairwise function returned NaN")
        if (v == -np.inf).any():
            raise ValueError("pairwise function returned -inf")
        if (v >= INF).any():
            v = np.where(v >= INF, np.inf, v)
        return v


def _check_problem(unary, edges, pairwise) -> tuple[np.ndarray, np.ndarray, _Pairwise]:
    u = np.asarray(unary, dtype=np.float64)
    if u.ndim != 2 or u.shape[0] < 1 or u.shape[1] < 1:
        raise ValueError(f"unary must have shape (N, L) with N, L >= 1, got {u.shape}")
    u = _as_costs(u, u.shape, "unary", nonnegative=False)
    e = _as_edges(edges, u.shape[0])
    return u, e, _Pairwise(pairwise, len(e), u.shape[1])


def _check_labels(labels, n: int, n_labels: int, name: str) -> np.ndarray:
    lab = np.asarray(labels)
    if lab.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {lab.shape}")
    if not np.issubdtype(lab.dtype, np.integer):
        raise ValueError(f"{name} must be integers, got dtype {lab.dtype}")
    if n and (lab.min() < 0 or lab.max() >= n_labels):
        raise ValueError(f"{name} out of range [0, {n_labels})")
    return lab.astype(np.int64)


def _sum_terms(*arrays: np.ndarray) -> float:
    total = 0.0
    for a in arrays:
        total += float(a.sum())
    return total


def energy(labels, unary, edges, pairwise) -> float:
    """Energy ``sum_p D_p(l_p) + sum_(p,q) V_pq(l_p, l_q)`` of a labeling.

    Parameters
    ----------
    labels : (N,) int
    unary : (N, L) float
        ``D_p(l)``; ``np.inf`` or ``>= INF`` for forbidden labels.
    edges : (E, 2) int
    pairwise : (L, L) float, (E, L, L) float, or callable ``f(edge_idx (k,), la (k,), lb (k,)) -> (k,)``
        ``V_e(la, lb)`` with ``la`` the label of ``edges[e, 0]`` and ``lb`` that of ``edges[e, 1]``.

    Returns
    -------
    float
        The energy; ``np.inf`` when any term is infinite.
    """
    u, e, pw = _check_problem(unary, edges, pairwise)
    lab = _check_labels(labels, u.shape[0], u.shape[1], "labels")
    un = u[np.arange(len(lab)), lab]
    pv = pw(np.arange(len(e)), lab[e[:, 0]], lab[e[:, 1]])
    return _sum_terms(un, pv)


@dataclass(frozen=True)
class ExpansionResult:
    """Outcome of :func:`alpha_expansion`.

    labels : (N,) int64 final labeling.
    energy : float, its energy (finite unless ``allow_infinite``).
    cycles : number of cycles over the labels that were run (the last one found no improving move,
        unless ``max_cycles`` stopped the run).
    history : energy of the initial labeling followed by the energy after each cycle (non-increasing).
    moves : number of expansion moves that lowered the energy.
    """

    labels: np.ndarray
    energy: float
    cycles: int
    history: list[float] = field(default_factory=list)
    moves: int = 0


@dataclass
class _Kept:
    """One label's edges, pairwise values and move graph, kept across moves on that label.

    ``idx`` (k,) int32: the edges with at least one end that can take the label (the only ones a
    move on it can change), ascending; ``gp``, ``gq`` (k,) int32 their first and second ends.
    ``v01``, ``v10``, ``v11`` (k,): ``V(l_p, alpha)``, ``V(alpha, l_q)`` and ``V(alpha, alpha)``,
    evaluated only when a move needs them (``v11`` NaN until then); ``at01`` and ``at10`` (k,)
    int32: the move at which ``v01`` (for the labels of the edges' first ends) and ``v10`` (second
    ends) were evaluated (0: never).

    ``graph``: the residual graph of the label's last move, over every node that can take the
    label (``nodes`` (n,) int32, ascending: graph node ``i`` is node ``nodes[i]``) and every kept
    edge whose ends both can (``slot`` (k,) int32: its index in the graph, -1 if not). ``big``: the finite
    stand-in for an infinite cost in that graph, never lowered so that more of the kept flow stays
    valid.
    """

    idx: np.ndarray
    gp: np.ndarray
    gq: np.ndarray
    v01: np.ndarray
    v10: np.ndarray
    v11: np.ndarray
    at01: np.ndarray
    at10: np.ndarray
    nodes: np.ndarray
    slot: np.ndarray
    graph: ResidualGraph
    big: float = 0.0


class _Expansion:
    """State of an alpha-expansion run: current labels, their unary and pairwise terms."""

    def __init__(self, u: np.ndarray, e: np.ndarray, pw: _Pairwise, labels: np.ndarray):
        self.uT = np.ascontiguousarray(u.T)
        self.okT = np.isfinite(self.uT)
        self.e0 = np.ascontiguousarray(e[:, 0])
        self.e1 = np.ascontiguousarray(e[:, 1])
        self.pw = pw
        self.n = u.shape[0]
        self.lab = labels.copy()
        self.un = u[np.arange(self.n), self.lab]
        self.pv = pw(np.arange(len(e)), self.lab[self.e0], self.lab[self.e1])
        self.n_inf = int(np.isinf(self.un).sum() + np.isinf(self.pv).sum())
        self.changed_at = np.zeros(self.n, dtype=np.int64)
        self.loc = np.full(self.n, -1, dtype=np.int32)  # graph index of a node, set for each move's label
        self.step = 0
        self.kept: dict[int, _Kept] = {}
        self.n_kept = 0

    def _label_edges(self, alpha: int) -> _Kept:
        """The kept edges, values and graph of ``alpha`` (created on first use); past
        ``_KEPT_EDGES`` edges in all, a fresh, unkept one for this move only."""
        kept = self.kept.get(alpha)
        if kept is None:
            ok = self.okT[alpha]
            idx = np.flatnonzero(ok[self.e0] | ok[self.e1]).astype(np.int32)
            gp, gq = self.e0[idx].astype(np.int32), self.e1[idx].astype(np.int32)
            k = len(idx)
            nodes = np.flatnonzero(ok).astype(np.int32)
            loc = np.full(self.n, -1, dtype=np.int32)
            loc[nodes] = np.arange(len(nodes))
            lp, lq = loc[gp], loc[gq]
            both = (lp >= 0) & (lq >= 0)
            slot = np.full(k, -1, dtype=np.int32)
            slot[both] = np.arange(np.count_nonzero(both))
            kept = _Kept(idx, gp, gq, np.empty(k), np.empty(k), np.full(k, np.nan),
                         np.zeros(k, dtype=np.int32), np.zeros(k, dtype=np.int32),
                         nodes, slot, ResidualGraph.build(len(nodes), lp[both], lq[both]))
            if self.n_kept + k <= _KEPT_EDGES:
                self.kept[alpha] = kept
                self.n_kept += k
        return kept

    def _refresh(self, kept: _Kept, alpha: int, w01: np.ndarray, w10: np.ndarray, w11: np.ndarray) -> None:
        """Evaluate, in one call of the pairwise function, ``v01`` at the kept positions ``w01``,
        ``v10`` at ``w10`` and ``v11`` at ``w11`` (the values ``_stale`` found missing or stale)."""
        n01, n10 = len(w01), len(w10)
        if n01 + n10 + len(w11) == 0:
            return
        lab = self.lab
        full = np.full(n01 + n10 + len(w11), alpha)
        vals = self.pw(kept.idx[np.concatenate([w01, w10, w11])].astype(np.intp),
                       np.concatenate([lab[kept.gp[w01]], full[n01:]]),
                       np.concatenate([full[:n01], lab[kept.gq[w10]], full[n01 + n10 :]]))
        kept.v01[w01] = vals[:n01]
        kept.v10[w10] = vals[n01 : n01 + n10]
        kept.v11[w11] = vals[n01 + n10 :]
        kept.at01[w01] = self.step
        kept.at10[w10] = self.step

    def energy(self) -> float:
        return _sum_terms(self.un, self.pv)

    def _prepare(self, kept: _Kept, alpha: int, act: np.ndarray) -> None:
        """Bring the kept values that the move on ``alpha`` reads up to date, for the active nodes
        ``act`` (updated in place): ``V(l_p, alpha)`` or ``V(alpha, l_q)`` on edges with one active
        end, all three on edges with two.

        When the current energy is finite, an active node whose switch would meet an infinite
        cost with a fixed neighbour keeps its label in every finite move result: it is made fixed
        and the test repeats on the edges this creates.
        """
        args = (act, kept.gp, kept.gq, self.changed_at, kept.at01, kept.at10, kept.v11)
        while True:
            self._refresh(kept, alpha, *_stale(*args, False))
            if self.n_inf or not _fix_blocked(act, kept.gp, kept.gq, kept.v01, kept.v10):
                break
        self._refresh(kept, alpha, *_stale(*args, True))

    def move(self, alpha: int) -> bool:
        """One expansion move on ``alpha``; applies it and returns True when it lowers the energy."""
        self.step += 1
        act = self.okT[alpha] & (self.lab != alpha)
        if not act.any():
            return False
        kept = self._label_edges(alpha)
        self._prepare(kept, alpha, act)
        if not act.any():
            return False
        g = kept.graph
        self.loc[kept.nodes] = np.arange(len(kept.nodes), dtype=np.int32)  # read for active nodes only
        status, kept.big, d_inf = _move(
            alpha, self.step, act, self.lab, self.un, self.uT[alpha], self.pv, self.changed_at,
            kept.idx, kept.gp, kept.gq, kept.v01, kept.v10, kept.v11, self.loc, kept.slot, kept.big,
            g.first, g.head, g.sister, g.rcap, g.tr, g.arc_pq, g.arc_qp, g.p, g.q, g.cap_pq, g.term,
            tol.energy)
        self.n_inf += d_inf
        return status == 1


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _stale(act, gp, gq, changed_at, at01, at10, v11, two_sided):  # pragma: no cover
    """Kept positions whose values a move with active nodes ``act`` (N,) bool reads and that are
    missing or stale: ``(w01, w10, w11)`` int arrays for ``v01``, ``v10``, ``v11``.

    An edge with one active end reads the value of that end's switch; with ``two_sided``, an edge
    with two reads all three. ``V(alpha, alpha)`` never changes; ``V(l_p, alpha)`` only when
    ``l_p`` does and ``V(alpha, l_q)`` only when ``l_q`` does. Moves are numbered from 1 and a
    label change carries its move's number, so a value evaluated at move ``at`` is stale once its
    end has ``changed_at >= at``.
    """
    k = len(gp)
    w01 = np.empty(k, dtype=np.int64)
    w10 = np.empty(k, dtype=np.int64)
    w11 = np.empty(k, dtype=np.int64)
    n01 = 0
    n10 = 0
    n11 = 0
    for e in range(k):
        ap = act[gp[e]]
        aq = act[gq[e]]
        if ap and aq:
            if not two_sided:
                continue
            if np.isnan(v11[e]):
                w11[n11] = e
                n11 += 1
        elif not (ap or aq):
            continue
        if aq and changed_at[gp[e]] >= at01[e]:
            w01[n01] = e
            n01 += 1
        if ap and changed_at[gq[e]] >= at10[e]:
            w10[n10] = e
            n10 += 1
    return w01[:n01], w10[:n10], w11[:n11]


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _fix_blocked(act, gp, gq, v01, v10):  # pragma: no cover
    """Make fixed (``act`` False) every active node with an edge to a fixed node that its switch
    makes infinite; the test reads ``act`` as it was on entry. Returns whether any node changed."""
    k = len(gp)
    blocked = np.empty(k, dtype=np.int64)
    nb = 0
    for e in range(k):
        ap = act[gp[e]]
        aq = act[gq[e]]
        if ap and not aq and np.isinf(v10[e]):
            blocked[nb] = gp[e]
            nb += 1
        elif aq and not ap and np.isinf(v01[e]):
            blocked[nb] = gq[e]
            nb += 1
    for i in range(nb):
        act[blocked[i]] = False
    return nb > 0


@numba.njit(cache=NUMBA_CACHE, inline="always")
def _finite(v, big):  # pragma: no cover
    return big if np.isinf(v) else v


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _move(alpha, step, act, lab, un, u_alpha, pv, changed_at, idx, gp, gq, v01, v10, v11, loc, slot, big,
          first, head, sister, rcap, tr, arc_pq, arc_qp, gpl, gql, cap_pq, term, rel_tol):  # pragma: no cover
    """The expansion move on ``alpha`` for the active nodes ``act`` (N,) bool, compiled.

    Builds the binary move energy (Kolmogorov and Zabih; x = 1 switches to alpha) from the current
    terms ``un`` (N,), ``pv`` (E,) and the kept values ``v01``, ``v10``, ``v11`` (k,) of the kept
    edges ``idx`` (k,) with ends ``gp``, ``gq``: one-sided edges are unary terms of their active end,
    two-sided ones give ``E00 + a x_p + b x_q + c_pq (1 - x_p) x_q + c_qp x_p (1 - x_q)``. A
    non-submodular term (``E01 + E10 < E00 + E11``) gets ``E01`` raised to ``E00 + E11 - E10``
    (Rother et al. 2005), an overestimate that is exact at the current labeling (x = 0). ``c_pq +
    c_qp`` is split so that the unary parts stay small: with ``E00 = E11 = 0`` both vanish, and
    infinite terms create no large opposite terminal links. Infinite terms become ``big``, at least
    twice the sum of the move's finite terms plus one.

    The cut runs on the label's kept residual graph (arrays of :class:`ResidualGraph`), brought to
    the new capacities by ``update_residual``: nodes and edges outside this move get capacity 0. The move
    is applied (labels, terms, ``changed_at``) only when it lowers the exact energy, with infinite
    terms counted first.

    Returns ``(status, big, d_inf)``: status 1 when applied, 0 otherwise; the ``big`` used; the
    change of the number of infinite terms.
    """
    n = len(lab)
    k = len(idx)
    fin = 0.0
    has_inf = False
    for g in range(n):
        if act[g]:
            for v in (un[g], u_alpha[g]):
                if np.isinf(v):
                    has_inf = True
                else:
                    fin += abs(v)
    for e in range(k):
        ap = act[gp[e]]
        aq = act[gq[e]]
        if not (ap or aq):
            continue
        for v in (pv[idx[e]], v01[e] if aq else 0.0, v10[e] if ap else 0.0, v11[e] if ap and aq else 0.0):
            if np.isinf(v):
                has_inf = True
            else:
                fin += abs(v)
    if has_inf and big < 2.0 * fin + 1.0:
        big = 2.0 * fin + 1.0

    new_pq = np.zeros(len(arc_pq))
    new_qp = np.zeros(len(arc_pq))
    new_term = np.zeros(len(tr))
    for g in range(n):
        if act[g]:
            new_term[loc[g]] += _finite(u_alpha[g], big) - _finite(un[g], big)
    for e in range(k):
        ap = act[gp[e]]
        aq = act[gq[e]]
        if ap and aq:
            e00 = _finite(pv[idx[e]], big)
            e01 = _finite(v01[e], big)
            e10 = _finite(v10[e], big)
            e11 = _finite(v11[e], big)
            cap = max(e01 + e10 - e00 - e11, 0.0)
            c_qp = min(max(e10 - e00, 0.0), cap)
            new_pq[slot[e]] = cap - c_qp
            new_qp[slot[e]] = c_qp
            new_term[loc[gp[e]]] += e10 - e00 - c_qp
            new_term[loc[gq[e]]] += e11 - e10 + c_qp
        elif ap:
            new_term[loc[gp[e]]] += _finite(v10[e], big) - _finite(pv[idx[e]], big)
        elif aq:
            new_term[loc[gq[e]]] += _finite(v01[e], big) - _finite(pv[idx[e]], big)
    update_residual(rcap, tr, arc_pq, arc_qp, gpl, gql, cap_pq, new_pq, new_qp, term, new_term)
    cap_pq[:] = new_pq
    term[:] = new_term
    saturate_greedy(first, head, sister, rcap, tr, 1)
    sink = bk_max_flow(first, head, sister, rcap, tr)

    # exact change of the energy, infinite terms counted separately
    n_old = 0
    n_new = 0
    f_old = 0.0
    f_new = 0.0
    switched = False
    for g in range(n):
        if act[g] and sink[loc[g]]:
            switched = True
            if np.isinf(un[g]):
                n_old += 1
            else:
                f_old += un[g]
            if np.isinf(u_alpha[g]):
                n_new += 1
            else:
                f_new += u_alpha[g]
    if not switched:
        return 0, big, 0
    for e in range(k):
        xp = act[gp[e]] and sink[loc[gp[e]]]
        xq = act[gq[e]] and sink[loc[gq[e]]]
        if not (xp or xq):
            continue
        old = pv[idx[e]]
        new = v11[e] if xp and xq else (v10[e] if xp else v01[e])
        if np.isinf(old):
            n_old += 1
        else:
            f_old += old
        if np.isinf(new):
            n_new += 1
        else:
            f_new += new
    if n_new > n_old or (n_new == n_old and not f_new < f_old - rel_tol * (fin + 1.0)):
        return 0, big, 0
    for e in range(k):
        xp = act[gp[e]] and sink[loc[gp[e]]]
        xq = act[gq[e]] and sink[loc[gq[e]]]
        if xp or xq:
            pv[idx[e]] = v11[e] if xp and xq else (v10[e] if xp else v01[e])
    for g in range(n):
        if act[g] and sink[loc[g]]:
            lab[g] = alpha
            changed_at[g] = step
            un[g] = u_alpha[g]
    return 1, big, n_new - n_old


def alpha_expansion(
    unary,
    edges,
    pairwise,
    *,
    init=None,
    max_cycles: int = 20,
    rng=None,
    allow_infinite: bool = False,
) -> ExpansionResult:
    """Minimise ``sum_p D_p(l_p) + sum_(p,q) V_pq(l_p, l_q)`` by alpha-expansion moves.

    Each move picks a label alpha and solves, by one min-cut, for the best labeling in which every
    node keeps its label or switches to alpha (Boykov, Veksler and Zabih 2001), with Kolmogorov and
    Zabih's construction of the binary move energy. A move is kept only when it lowers the exact
    energy, so the energy never rises. Moves cycle over all labels until a whole cycle brings no
    improvement or ``max_cycles`` cycles have run. A move on alpha is skipped when alpha's previous
    move failed and no label has changed since (it would fail again); this does not change the result.

    For metric ``V_pq`` every move is solved exactly, and with non-negative unary costs the result
    is within a factor ``2c`` of the optimum, ``c`` the ratio of the largest to the smallest non-zero
    ``V`` (``2`` for Potts). Non-submodular move terms (``E00 + E11 > E01 + E10``) are truncated as
    in Rother et al. 2005 (``E01`` raised until submodular), which overestimates the move energy
    everywhere except at the current labeling, so such moves can still only lower the energy.

    Each label keeps its move graph (the nodes that can take it and the edges between them) with
    the flow of its last move: the next move on the label changes the capacities and augments from
    there (Kohli and Torr 2005). Before the augmentation, a node whose source capacity covers all
    its outgoing capacity sends it all, and likewise towards the sink (the persistency test: such
    a node's side is certain whatever its neighbours do). The cut taken is the minimum cut with the
    largest set of nodes keeping their label, which depends only on the capacities, not on the
    flow found. A pairwise function is evaluated, per move, only on the edges whose values are not
    kept from an earlier move on the same label (see ``_stale``). None of this changes the result,
    only the time; past ``_KEPT_EDGES`` kept edges in all, further labels get a fresh graph and
    fresh values at every move.

    Infinite costs: the initial labeling is the per-node cheapest unary label when ``init`` is not
    given. Within a move every infinite term becomes a finite constant larger than twice the sum
    of all finite terms of that move, so a move first minimises the number of infinite terms and then
    the finite energy. Nodes whose unary cost for alpha is infinite do not take part in alpha's move;
    once the energy is finite, neither do nodes whose switch would meet an infinite pairwise cost
    with a node that cannot switch (they keep their label in every finite move result), found
    repeatedly until none is left. From a labeling with infinite terms, expansion can stop in a
    labeling that still has some (a local minimum of their number): then ``ValueError`` is raised
    unless ``allow_infinite``.

    Parameters
    ----------
    unary : (N, L) float
        ``D_p(l)``; ``np.inf`` (or ``>= INF``) forbids a label. Every node needs a finite label.
    edges : (E, 2) int
        Node pairs; each pair's cost is counted once per row (no self-loops).
    pairwise : (L, L) float, (E, L, L) float, or callable
        ``V_e(la, lb)`` where ``la`` is the label of ``edges[e, 0]`` and ``lb`` that of
        ``edges[e, 1]``: a table shared by all edges, one table per edge, or a vectorised function
        ``f(edge_idx (k,) int, la (k,) int, lb (k,) int) -> (k,) float`` (position dependent costs).
    init : (N,) int, optional
        Initial labeling.
    max_cycles : int
        Upper bound on cycles over the labels.
    rng : None, int or np.random.Generator
        Randomness enters only through the label order of each cycle, a fresh permutation per
        cycle drawn from ``np.random.default_rng(rng)``. ``None``: labels in order ``0..L-1``.
    allow_infinite : bool
        Return an infinite-energy result instead of raising ``ValueError`` when no finite labeling
        was reached.

    Returns
    -------
    ExpansionResult
        ``labels`` (N,) int64, ``energy`` (equal to :func:`energy` of ``labels``), ``cycles``,
        ``history`` (initial energy, then the energy after each cycle) and ``moves`` (successful moves).
    """
    u, e, pw, labels = _expansion_start(unary, edges, pairwise, init, max_cycles)
    state = _Expansion(u, e, pw, labels)
    cycles, history, moves = _cycle_moves(state, u.shape[1], max_cycles, rng)
    final = state.energy()
    if not np.isfinite(final) and not allow_infinite:
        raise ValueError(
            f"alpha_expansion found no finite-energy labeling after {cycles} cycles "
            f"({int(np.isinf(state.un).sum())} infinite unary, {int(np.isinf(state.pv).sum())} infinite "
            "pairwise terms remain)"
        )
    return ExpansionResult(labels=state.lab, energy=final, cycles=cycles, history=history, moves=moves)


def _expansion_start(unary, edges, pairwise, init, max_cycles: int):
    """The checked problem ``(u (N, L), e (E, 2), pairwise, labels (N,))`` of :func:`alpha_expansion`:
    ``labels`` is ``init`` or, without it, each node's cheapest unary label."""
    u, e, pw = _check_problem(unary, edges, pairwise)
    n, n_labels = u.shape
    if max(n, len(e)) >= 2**31:
        raise ValueError(f"alpha_expansion takes fewer than 2**31 nodes and edges, got {n} and {len(e)}")
    if max_cycles < 1:
        raise ValueError(f"max_cycles must be at least 1, got {max_cycles}")
    feasible = np.isfinite(u).any(axis=1)
    if not feasible.all():
        p = int(np.flatnonzero(~feasible)[0])
        raise ValueError(f"unary row {p} has no finite label: node {p} cannot be labeled")
    if init is None:
        return u, e, pw, np.argmin(u, axis=1).astype(np.int64)
    return u, e, pw, _check_labels(init, n, n_labels, "init")


def _cycle_moves(state: _Expansion, n_labels: int, max_cycles: int, rng) -> tuple[int, list[float], int]:
    """Expansion cycles over the labels on ``state`` until one changes nothing or ``max_cycles``
    have run, skipping a label whose last move failed with nothing changed since; returns
    ``(cycles, energy history, successful moves)``."""
    gen = None if rng is None else np.random.default_rng(rng)
    history = [state.energy()]
    last_fail = np.full(n_labels, -1, dtype=np.int64)
    step = last_change = moves = cycles = 0
    for _ in range(max_cycles):
        cycles += 1
        order = np.arange(n_labels) if gen is None else gen.permutation(n_labels)
        changed = False
        for alpha in order:
            step += 1
            if last_fail[alpha] >= last_change:
                continue
            if state.move(int(alpha)):
                last_change = step
                changed = True
                moves += 1
            else:
                last_fail[alpha] = step
        history.append(state.energy())
        if not changed:
            break
    return cycles, history, moves


def compile_kernels() -> None:
    """Compile the numba kernels of :func:`alpha_expansion` (or load them from numba's cache beside
    the sources) by running it on a 3-node problem, so that the first real run is not timed with
    the compilation (6-8 s). ``make install`` and the benchmarks call it."""
    alpha_expansion(np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5]]), np.array([[0, 1], [1, 2]]),
                    np.array([[0.0, 1.0], [1.0, 0.0]]))
