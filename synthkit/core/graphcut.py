"""Graph cuts on sparse graphs in edge-list form: binary s-t min-cut and multi-label alpha-expansion.

A graph has ``n`` nodes numbered ``0..n-1`` and ``edges`` as an ``(E, 2) int`` array of node pairs.
Costs are ``float64``. Infinite costs are written ``np.inf``; any value ``>= INF`` counts as infinite
too, so callers may use either. Internally an infinite cost becomes a finite constant larger than every
finite cost that can be compared with it (Kolmogorov and Zabih's usual device), and results are checked
to be finite afterwards.

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
    e = e.astype(np.int64, copy=False)
    lo, hi = int(e.min()), int(e.max())
    if lo < 0 or hi >= n:
        raise ValueError(f"{name} index out of range [0, {n}): found {lo if lo < 0 else hi}")
    if np.any(e[:, 0] == e[:, 1]):
        k = int(np.flatnonzero(e[:, 0] == e[:, 1])[0])
        raise ValueError(f"{name}[{k}] is a self-loop ({e[k, 0]}, {e[k, 1]})")
    return e


def _as_costs(values, shape: tuple[int, ...], name: str, *, nonnegative: bool) -> np.ndarray:
    """Return ``values`` as a float64 array of ``shape`` with every value ``>= INF`` set to ``np.inf``."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {v.shape}")
    if np.isnan(v).any():
        raise ValueError(f"{name} contains NaN")
    if nonnegative and (v < 0).any():
        raise ValueError(f"{name} must be non-negative, found {float(v.min())}")
    if (v == -np.inf).any():
        raise ValueError(f"{name} contains -inf")
    if (v >= INF).any():
        v = np.where(v >= INF, np.inf, v)
    return v


def _big_constant(finite_values: np.ndarray) -> float:
    """A cost exceeding twice the total of all ``finite_values`` in magnitude: one such cost then
    outweighs any combination of the finite ones."""
    return 2.0 * float(np.abs(finite_values).sum()) + 1.0


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
    arrays = (c, r, s, t)
    finite_total = sum(float(a[np.isfinite(a)].sum()) for a in arrays)
    big = 2.0 * finite_total + 1.0
    c, r, s, t = (np.where(np.isinf(a), big, a) for a in arrays)
    g = maxflow.Graph[float](n, max(m, 1))
    ids = g.add_nodes(n)
    g.add_grid_tedges(ids, s, t)
    if m:
        g.add_edges(e[:, 0], e[:, 1], c, r)
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
        items = [(tuple(int(i) - 1 for i in o), weights * st[tuple(o)]) for o in np.argwhere(st != 0)]
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


class _Expansion:
    """State of an alpha-expansion run: current labels, their unary and pairwise terms."""

    def __init__(self, u: np.ndarray, e: np.ndarray, pw: _Pairwise, labels: np.ndarray):
        self.u = u
        self.uT = np.ascontiguousarray(u.T)
        self.okT = np.isfinite(self.uT)
        self.e0 = np.ascontiguousarray(e[:, 0])
        self.e1 = np.ascontiguousarray(e[:, 1])
        self.pw = pw
        self.n = u.shape[0]
        self.lab = labels.copy()
        self.un = u[np.arange(self.n), self.lab]
        self.pv = pw(np.arange(len(e)), self.lab[self.e0], self.lab[self.e1])
        self.pos = np.full(self.n, -1, dtype=np.int64)

    def energy(self) -> float:
        return _sum_terms(self.un, self.pv)

    def move(self, alpha: int) -> bool:
        """One expansion move on ``alpha``; applies it and returns True when it lowers the energy."""
        lab = self.lab
        act = self.okT[alpha] & (lab != alpha)
        nodes = np.flatnonzero(act)
        na = len(nodes)
        if na == 0:
            return False
        pos = self.pos
        pos[nodes] = np.arange(na)
        e0, e1 = self.e0, self.e1
        a0 = act[e0]
        a1 = act[e1]
        tk = np.flatnonzero(a0 | a1)
        p, q = e0[tk], e1[tk]
        ap, aq = a0[tk], a1[tk]
        both = ap & aq
        lp, lq = lab[p], lab[q]
        k = len(tk)
        nb = int(both.sum())
        bi = np.flatnonzero(both)
        # one call: V(new_p, new_q) for touched edges, V(l_p, alpha) and V(alpha, l_q) for edges
        # with both ends active.
        la = np.concatenate([np.where(ap, alpha, lp), lp[bi], np.full(nb, alpha)])
        lb = np.concatenate([np.where(aq, alpha, lq), np.full(nb, alpha), lq[bi]])
        vals = self.pw(np.concatenate([tk, tk[bi], tk[bi]]), la, lb) if k else np.zeros(0)
        w11 = vals[:k]
        e01 = vals[k : k + nb]
        e10 = vals[k + nb :]
        e00 = self.pv[tk]
        c0 = self.un[nodes]
        c1 = self.uT[alpha, nodes]

        raw = (c0, c1, e00, vals)
        fin_total = sum(float(np.abs(r[np.isfinite(r)]).sum()) for r in raw)
        big = 2.0 * fin_total + 1.0
        if not all(np.isfinite(r).all() for r in raw):
            c0, c1, e00f, w11f, e01f, e10f = (
                np.where(np.isinf(r), big, r) for r in (c0, c1, e00, w11, e01, e10)
            )
        else:
            e00f, w11f, e01f, e10f = e00, w11, e01, e10

        # node costs of keeping (x=0) and switching (x=1), Kolmogorov-Zabih decomposition
        one = ~both
        sp = ap & one  # p active, q fixed
        sq = aq & one  # q active, p fixed
        ip = pos[p]
        iq = pos[q]
        k0 = np.zeros(na)
        k1 = np.zeros(na)
        k0 += np.bincount(ip[sp], weights=e00f[sp], minlength=na)
        k0 += np.bincount(iq[sq], weights=e00f[sq], minlength=na)
        k1 += np.bincount(ip[sp], weights=w11f[sp], minlength=na)
        k1 += np.bincount(iq[sq], weights=w11f[sq], minlength=na)
        b00 = e00f[bi]
        b11 = w11f[bi]
        bp, bq = ip[bi], iq[bi]
        k1 += np.bincount(bp, weights=e10f - b00, minlength=na)
        k1 += np.bincount(bq, weights=b11 - e10f, minlength=na)
        cap = e01f + e10f - b00 - b11
        # Rother et al. 2005 truncation: a non-submodular term (cap < 0) is replaced by raising
        # E01 to E00 + E11 - E10, an overestimate that is exact at the current labeling (x = 0).
        keep = cap > 0
        d = (c1 + k1) - (c0 + k0)
        g = maxflow.Graph[float](na, int(keep.sum()) or 1)
        ids = g.add_nodes(na)
        g.add_grid_tedges(ids, np.maximum(d, 0.0), np.maximum(-d, 0.0))
        if keep.any():
            g.add_edges(bp[keep], bq[keep], cap[keep], np.zeros(int(keep.sum())))
        g.maxflow()
        x = g.get_grid_segments(ids)
        if not x.any():
            return False

        # exact energy change of the proposed labeling (infinite terms counted separately)
        xp = np.zeros(k, dtype=bool)
        xq = np.zeros(k, dtype=bool)
        xp[ap] = x[ip[ap]]
        xq[aq] = x[iq[aq]]
        v10 = w11.copy()
        v01 = w11.copy()
        v10[bi] = e10
        v01[bi] = e01
        new_pv = np.where(xp & xq, w11, np.where(xp, v10, np.where(xq, v01, e00)))
        sw = nodes[x]
        old_u = self.un[sw]
        new_u = self.uT[alpha, sw]
        ch = xp | xq
        old_p = e00[ch]
        new_p = new_pv[ch]
        n_old = int(np.isinf(old_u).sum() + np.isinf(old_p).sum())
        n_new = int(np.isinf(new_u).sum() + np.isinf(new_p).sum())
        if n_new > n_old:
            return False
        if n_new == n_old:
            f_old = float(old_u[np.isfinite(old_u)].sum() + old_p[np.isfinite(old_p)].sum())
            f_new = float(new_u[np.isfinite(new_u)].sum() + new_p[np.isfinite(new_p)].sum())
            if not f_new < f_old - _REL_TOL * (fin_total + 1.0):
                return False
        lab[sw] = alpha
        self.un[sw] = new_u
        self.pv[tk[ch]] = new_p
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

    For metric ``V_pq`` every move is exact and the result is within a factor 2 of the optimum
    (for Potts within 2x); non-submodular move terms (``E00 + E11 > E01 + E10``) are truncated as in
    Rother et al. 2005 (``E01`` raised until submodular), which overestimates the move energy
    everywhere except at the current labeling, so moves can still only lower the energy.

    Infinite costs: the initial labeling is the per-node cheapest unary label when ``init`` is not
    given. Within a move every infinite term becomes a finite constant larger than twice the sum
    of all finite terms of that move, so a move first minimises the number of infinite terms and then
    the finite energy; nodes whose unary cost for alpha is infinite do not take part in alpha's move.

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
