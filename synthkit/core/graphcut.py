"""Graph cuts on sparse graphs in edge-list form: binary s-t min-cut and multi-label alpha-expansion.

A graph has ``n`` nodes numbered ``0..n-1`` and ``edges`` as an ``(E, 2) int`` array of node pairs.
Costs are ``float64``. Infinite costs are written ``np.inf``; any value ``>= INF`` counts as infinite
too, so callers may use either. Internally an infinite cost becomes a finite constant larger than twice
the sum of all finite costs of the same cut problem, so that one such cost outweighs any combination of
finite ones, and results are checked to be finite afterwards.

Min-cuts use PyMaxflow (Boykov-Kolmogorov max-flow, ``maxflow.Graph[float]``). Alpha-expansion
(Boykov, Veksler and Zabih, PAMI 2001) is built on it here because the retargeting method needs
pairwise costs that depend on the edge (position-dependent tables or a cost function), which
PyMaxflow's own ``fastmin`` grid routines cannot express.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import maxflow
import numpy as np

INF = 1e12
"""Costs at or above this value are treated as infinite (forbidden), exactly like ``np.inf``."""

PairwiseFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

_REL_TOL = 1e-12
_KEPT_EDGES = 3 << 20  # edge entries kept across moves, summed over labels: 36 bytes each, 113 MB at most


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


def _binary_cut(d: np.ndarray, p: np.ndarray, q: np.ndarray, c_pq: np.ndarray, c_qp: np.ndarray,
                *, rounds: int = 3) -> np.ndarray:
    """Minimiser ``x (n,) bool`` of ``sum_i d_i x_i + sum_k c_pq[k] (1 - x_p) x_q + c_qp[k] x_p (1 - x_q)``.

    ``d`` (n,) finite, ``p, q`` (m,) int node pairs, ``c_pq, c_qp`` (m,) finite and non-negative.
    Before the max-flow, nodes are fixed by the exact persistency test: ``x_i = 0`` is optimal
    when ``d_i`` is at least the sum of the pair costs ``x_i = 0`` can meet, ``x_i = 1`` when
    ``-d_i`` is at least the sum of those ``x_i = 1`` can meet (flipping such a node in any
    labeling never costs more). Fixed nodes turn their pairs into unary terms of the other end,
    and the test repeats (at most ``rounds`` times, and only while a round fixes at least 1 / 20 of
    the free nodes) on what is left; a min-cut solves the rest. Ties go to ``x = 0``.
    """
    n = len(d)
    fixed = np.full(n, -1, dtype=np.int8)
    d = d.copy()
    for _ in range(rounds):
        if len(p) == 0:
            break
        meet0 = np.bincount(p, c_pq, n) + np.bincount(q, c_qp, n)  # costs x_i = 0 can meet
        meet1 = np.bincount(p, c_qp, n) + np.bincount(q, c_pq, n)
        free = fixed < 0
        to0 = free & (d >= meet0)
        to1 = free & ~to0 & (-d >= meet1)
        if 20 * (np.count_nonzero(to0) + np.count_nonzero(to1)) < np.count_nonzero(free):
            break  # too few to pay for the folding: the min-cut settles them
        fixed[to0] = 0
        fixed[to1] = 1
        fp, fq = fixed[p], fixed[q]
        # a fixed end adds its pair's cost to the free end: x_p = 0 with x_q = 1 costs c_pq, ...
        m = (fp >= 0) & (fq < 0)
        d += np.bincount(q[m], np.where(fp[m] == 0, c_pq[m], -c_qp[m]), n)
        m = (fq >= 0) & (fp < 0)
        d += np.bincount(p[m], np.where(fq[m] == 0, c_qp[m], -c_pq[m]), n)
        live = (fp < 0) & (fq < 0)
        p, q, c_pq, c_qp = p[live], q[live], c_pq[live], c_qp[live]
    x = fixed == 1
    free = np.flatnonzero(fixed < 0)
    if len(free) == 0:
        return x
    pos = np.zeros(n, dtype=np.int64)
    pos[free] = np.arange(len(free))
    g = maxflow.Graph[float](len(free), max(len(p), 1))
    ids = g.add_nodes(len(free))
    df = d[free]
    g.add_grid_tedges(ids, np.maximum(df, 0.0), np.maximum(-df, 0.0))
    if len(p):
        g.add_edges(pos[p], pos[q], c_pq, c_qp)
    g.maxflow()
    x[free] = g.get_grid_segments(ids)
    return x


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
    """One label's edges and pairwise values, kept across moves on that label.

    ``idx`` (k,) int: the edges with at least one end that can take the label (the only ones a
    move on it can change), ascending. ``v01``, ``v10``, ``v11`` (k,): ``V(l_p, alpha)``,
    ``V(alpha, l_q)`` and ``V(alpha, alpha)``, evaluated only when a move needs them (``v11`` NaN
    until then); ``at01`` and ``at10`` (k,) int32: the move at which ``v01`` (for the labels of
    the edges' first ends) and ``v10`` (second ends) were evaluated (0: never).
    """

    idx: np.ndarray
    v01: np.ndarray
    v10: np.ndarray
    v11: np.ndarray
    at01: np.ndarray
    at10: np.ndarray


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
        self.pos = np.zeros(self.n, dtype=np.int64)
        self.changed_at = np.zeros(self.n, dtype=np.int64)
        self.step = 0
        self.kept: dict[int, _Kept] = {}
        self.n_kept = 0

    def _label_edges(self, alpha: int) -> _Kept:
        """The kept edges and values of ``alpha`` (created on first use); past ``_KEPT_EDGES``
        entries in all, a fresh, unkept one for this move only."""
        kept = self.kept.get(alpha)
        if kept is None:
            ok = self.okT[alpha]
            idx = np.flatnonzero(ok[self.e0] | ok[self.e1])
            k = len(idx)
            small = np.int32 if len(self.e0) < 2**31 else np.int64
            kept = _Kept(idx.astype(small), np.empty(k), np.empty(k), np.full(k, np.nan),
                         np.zeros(k, dtype=np.int32), np.zeros(k, dtype=np.int32))
            if self.n_kept + k <= _KEPT_EDGES:
                self.kept[alpha] = kept
                self.n_kept += k
        return kept

    def _refresh(self, kept: _Kept, alpha: int, idx: np.ndarray, p: np.ndarray, q: np.ndarray,
                 w01: np.ndarray, w10: np.ndarray, w11: np.ndarray) -> None:
        """Evaluate, in one call of the pairwise function, the kept values the move needs that are
        missing or stale: ``v01`` at the positions ``w01``, ``v10`` at ``w10``, ``v11`` at ``w11``
        (positions into ``kept``; ``idx``, ``p``, ``q`` are the kept edges and their ends).

        ``V(alpha, alpha)`` never changes; ``V(l_p, alpha)`` only when ``l_p`` does and ``V(alpha,
        l_q)`` only when ``l_q`` does. Moves are numbered from 1 and a label change carries its
        move's number, so a value evaluated at move ``at`` is stale once its end has ``changed_at
        >= at``.
        """
        ch = self.changed_at
        w01 = w01[ch[p[w01]] >= kept.at01[w01]]
        w10 = w10[ch[q[w10]] >= kept.at10[w10]]
        w11 = w11[np.isnan(kept.v11[w11])]
        n01, n10 = len(w01), len(w10)
        if n01 + n10 + len(w11) == 0:
            return
        lab = self.lab
        full = np.full(n01 + n10 + len(w11), alpha)
        vals = self.pw(idx[np.concatenate([w01, w10, w11])],
                       np.concatenate([lab[p[w01]], full[n01:]]),
                       np.concatenate([full[:n01], lab[q[w10]], full[n01 + n10 :]]))
        kept.v01[w01] = vals[:n01]
        kept.v10[w10] = vals[n01 : n01 + n10]
        kept.v11[w11] = vals[n01 + n10 :]
        kept.at01[w01] = self.step
        kept.at10[w10] = self.step

    def energy(self) -> float:
        return _sum_terms(self.un, self.pv)

    def move_terms(self, alpha: int, act: np.ndarray):
        """The edge terms of the move on ``alpha`` for the active nodes ``act`` (updated in place).

        Returns ``(oi, ov, o0, bi, e01, e10, e11)``: the edges with exactly one active end, their
        cost after that end switches to alpha and whether that end is the first; the edges with
        both ends active and their ``V(l_p, alpha)``, ``V(alpha, l_q)``, ``V(alpha, alpha)``.
        Edge indices ascend.

        When the current energy is finite, an active node whose switch would meet an infinite
        cost with a fixed neighbour keeps its label in every finite move result: it is made fixed
        and the test repeats on the edges this creates.
        """
        kept = self._label_edges(alpha)
        idx = kept.idx.astype(np.intp)  # indexing by int32 arrays is several times slower
        p, q = self.e0[idx], self.e1[idx]
        while True:
            ap, aq = act[p], act[q]
            o = np.flatnonzero(ap != aq)
            o0 = ap[o]
            self._refresh(kept, alpha, idx, p, q, o[~o0], o[o0], o[:0])
            ov = np.where(o0, kept.v10[o], kept.v01[o])
            if self.n_inf:
                break
            bad = np.isinf(ov)
            if not bad.any():
                break
            act[np.where(o0[bad], p[o[bad]], q[o[bad]])] = False
        b = np.flatnonzero(ap & aq)
        self._refresh(kept, alpha, idx, p, q, b, b, b)
        return (idx[o], ov, o0, idx[b],
                kept.v01[b], kept.v10[b], kept.v11[b])

    def move(self, alpha: int) -> bool:
        """One expansion move on ``alpha``; applies it and returns True when it lowers the energy."""
        lab, e0, e1 = self.lab, self.e0, self.e1
        self.step += 1
        act = self.okT[alpha] & (lab != alpha)
        if not act.any():
            return False
        oi, ov, o0, bi, e01, e10, e11 = self.move_terms(alpha, act)
        nodes = np.flatnonzero(act)
        na = len(nodes)
        if na == 0:
            return False
        pos = self.pos
        pos[nodes] = np.arange(na)
        on = pos[np.where(o0, e0[oi], e1[oi])]  # the active end of each one-sided edge
        e00 = self.pv[bi]
        o00 = self.pv[oi]
        c0 = self.un[nodes]
        c1 = self.uT[alpha, nodes]
        bp, bq = pos[e0[bi]], pos[e1[bi]]

        raw = (c0, c1, e00, e11, e01, e10, o00, ov)
        sums = [float(np.abs(r).sum()) for r in raw]
        if np.isfinite(sums).all():
            fin_total = sum(sums)
            c0f, c1f, e00f, e11f, e01f, e10f, o00f, ovf = raw
        else:
            fin_total = sum(_finite_sum(np.abs(r)) for r in raw)
            big = 2.0 * fin_total + 1.0
            c0f, c1f, e00f, e11f, e01f, e10f, o00f, ovf = (_finite_or(r, big) for r in raw)

        # Kolmogorov-Zabih: x = 1 switches to alpha. One-sided edges are unary terms of their
        # active end; two-sided edges give E00 + a x_p + b x_q + c_pq (1 - x_p) x_q + c_qp x_p (1 - x_q).
        # Rother et al. 2005 truncation: a non-submodular term (E01 + E10 < E00 + E11) gets E01
        # raised to E00 + E11 - E10, an overestimate that is exact at the current labeling (x = 0).
        cap = np.maximum(e01f + e10f - e00f - e11f, 0.0)
        # Split cap between the two directions so that the unary parts a, b stay small: with
        # E00 = E11 = 0 both vanish, and infinite terms create no large opposite terminal links.
        c_qp = np.clip(e10f - e00f, 0.0, cap)
        c_pq = cap - c_qp
        d = c1f - c0f
        d += np.bincount(on, weights=ovf - o00f, minlength=na)
        d += np.bincount(bp, weights=e10f - e00f - c_qp, minlength=na)
        d += np.bincount(bq, weights=e11f - e10f + c_qp, minlength=na)
        keep = np.flatnonzero(cap > 0)
        x = _binary_cut(d, bp[keep], bq[keep], c_pq[keep], c_qp[keep])
        if not x.any():
            return False

        # exact change of the energy (infinite terms counted separately)
        xo = x[on]
        xp, xq = x[bp], x[bq]
        bch = xp | xq
        new_b = np.where(xp, np.where(xq, e11, e10), e01)[bch]
        old_terms = (self.un[nodes[x]], o00[xo], e00[bch])
        new_terms = (c1[x], ov[xo], new_b)
        n_old = sum(int(np.isinf(t).sum()) for t in old_terms)
        n_new = sum(int(np.isinf(t).sum()) for t in new_terms)
        if n_new > n_old:
            return False
        if n_new == n_old:
            f_old = sum(float(t[np.isfinite(t)].sum()) for t in old_terms)
            f_new = sum(float(t[np.isfinite(t)].sum()) for t in new_terms)
            if not f_new < f_old - _REL_TOL * (fin_total + 1.0):
                return False
        lab[nodes[x]] = alpha
        self.changed_at[nodes[x]] = self.step
        self.un[nodes[x]] = new_terms[0]
        self.pv[oi[xo]] = new_terms[1]
        self.pv[bi[bch]] = new_b
        self.n_inf += n_new - n_old
        return True


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

    Each move's graph has only the nodes that can switch to alpha; before its min-cut, nodes whose
    best choice is certain whatever their neighbours do (the persistency test of ``_binary_cut``)
    are fixed, which leaves the same minimum. A pairwise function is evaluated, per move, only on
    the edges whose values are not kept from an earlier move on the same label (see
    ``_Expansion._refresh``): both change nothing in the result, only the time.

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
    u, e, pw = _check_problem(unary, edges, pairwise)
    n, n_labels = u.shape
    if max_cycles < 1:
        raise ValueError(f"max_cycles must be at least 1, got {max_cycles}")
    feasible = np.isfinite(u).any(axis=1)
    if not feasible.all():
        p = int(np.flatnonzero(~feasible)[0])
        raise ValueError(f"unary row {p} has no finite label: node {p} cannot be labeled")
    if init is None:
        labels = np.argmin(u, axis=1).astype(np.int64)
    else:
        labels = _check_labels(init, n, n_labels, "init")
    gen = None if rng is None else np.random.default_rng(rng)

    state = _Expansion(u, e, pw, labels)
    history = [state.energy()]
    last_fail = np.full(n_labels, -1, dtype=np.int64)
    step = 0
    last_change = 0
    moves = 0
    cycles = 0
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
    final = state.energy()
    if not np.isfinite(final) and not allow_infinite:
        raise ValueError(
            f"alpha_expansion found no finite-energy labeling after {cycles} cycles "
            f"({int(np.isinf(state.un).sum())} infinite unary, {int(np.isinf(state.pv).sum())} infinite "
            "pairwise terms remain)"
        )
    return ExpansionResult(labels=state.lab, energy=final, cycles=cycles, history=history, moves=moves)
