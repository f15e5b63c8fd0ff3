"""Boykov-Kolmogorov max-flow on a residual graph that is kept and updated between solves.

Alpha-expansion solves one binary cut per move, and the cuts of successive moves on the same label
differ only where labels changed in between. Kohli and Torr (dynamic graph cuts, ICCV 2005) keep
the residual graph of the previous cut and change its capacities in place: the flow already pushed
stays valid wherever capacities did not fall below it, and the search for augmenting paths only
has to route what changed. PyMaxflow cannot change the capacity of an edge after a solve, so this
module holds its own implementation, compiled by numba.

A graph of ``n`` nodes and ``m`` undirected edges is stored as ``2 m`` arcs in compressed rows:
``first (n + 1,)`` the first arc of each node, ``head (2m,)`` the node each arc points to,
``sister (2m,)`` the reverse arc, ``rcap (2m,)`` the residual capacity. The terminal links of a
node are one signed residual ``tr (n,)``: positive is capacity left from the source, negative
capacity left to the sink (Kolmogorov's representation, which adds the same constant to both
links of a node and so changes every cut by that constant only).

Cut convention: a node is on the sink side (``True``) when it can still reach the sink in the
residual graph. That is the minimum cut with the largest source side, the one PyMaxflow returns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from synthkit.core.numba_cache import NUMBA_CACHE

_NONE = -1  # not in a tree
_TERMINAL = -2  # parent is the source or the sink
_ORPHAN = -3  # lost its parent during an augmentation
_FAR = 1 << 30


@dataclass
class ResidualGraph:
    """A graph and its residual state. Arrays as in the module docstring (indices int32); ``arc_pq
    (m,)`` and ``arc_qp (m,)`` are the positions of edge ``k``'s arcs ``p[k] -> q[k]`` and ``q[k] ->
    p[k]``; ``cap_pq (m,)`` and ``term (n,)`` the capacities of the arcs ``p -> q`` and the signed
    terminal values that the residual state was last brought up to date with (the flow of an edge
    is ``cap_pq - rcap[arc_pq]``, so the reverse capacities need not be kept)."""

    first: np.ndarray
    head: np.ndarray
    sister: np.ndarray
    rcap: np.ndarray
    tr: np.ndarray
    arc_pq: np.ndarray
    arc_qp: np.ndarray
    p: np.ndarray
    q: np.ndarray
    cap_pq: np.ndarray
    term: np.ndarray

    @classmethod
    def build(cls, n: int, p: np.ndarray, q: np.ndarray) -> ResidualGraph:
        """Arcs of the ``m`` edges ``(p[k], q[k])`` (``(m,)`` int, no self-loops), all capacities 0."""
        m = len(p)
        p = np.ascontiguousarray(p, dtype=np.int32)
        q = np.ascontiguousarray(q, dtype=np.int32)
        first, head, sister, arc_pq, arc_qp = _arcs(n, p, q)
        return cls(first=first, head=head, sister=sister, rcap=np.zeros(2 * m), tr=np.zeros(n),
                   arc_pq=arc_pq, arc_qp=arc_qp, p=p, q=q, cap_pq=np.zeros(m), term=np.zeros(n))

    def set_capacities(self, cap_pq: np.ndarray, cap_qp: np.ndarray, term: np.ndarray) -> None:
        """Change every capacity, keeping as much of the current flow as the new ones allow.

        ``cap_pq``, ``cap_qp (m,)`` non-negative finite capacities of ``p -> q`` and ``q -> p``;
        ``term (n,)`` signed terminal values (``> 0`` from the source, ``< 0`` to the sink).
        """
        cap_pq = np.asarray(cap_pq, dtype=np.float64)
        term = np.asarray(term, dtype=np.float64)
        update_residual(self.rcap, self.tr, self.arc_pq, self.arc_qp, self.p, self.q, self.cap_pq,
                cap_pq, np.asarray(cap_qp, dtype=np.float64), self.term, term)
        self.cap_pq[:] = cap_pq
        self.term[:] = term

    def solve(self, rounds: int = 0) -> np.ndarray:
        """Augment to a maximum flow; returns ``(n,) bool``, True on the sink side."""
        if rounds:
            saturate_greedy(self.first, self.head, self.sister, self.rcap, self.tr, rounds)
        return bk_max_flow(self.first, self.head, self.sister, self.rcap, self.tr)


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _arcs(n, p, q):  # pragma: no cover
    """Compressed rows of the arcs ``p -> q`` and ``q -> p`` of each edge, by a counting sort on
    their tails; returns ``first, head, sister, arc_pq, arc_qp``."""
    m = len(p)
    first = np.zeros(n + 1, dtype=np.int64)
    for k in range(m):
        first[p[k] + 1] += 1
        first[q[k] + 1] += 1
    for i in range(n):
        first[i + 1] += first[i]
    fill = first[:n].copy()
    head = np.empty(2 * m, dtype=np.int32)
    sister = np.empty(2 * m, dtype=np.int32)
    arc_pq = np.empty(m, dtype=np.int32)
    arc_qp = np.empty(m, dtype=np.int32)
    for k in range(m):
        a = fill[p[k]]
        fill[p[k]] += 1
        b = fill[q[k]]
        fill[q[k]] += 1
        head[a] = q[k]
        head[b] = p[k]
        sister[a] = b
        sister[b] = a
        arc_pq[k] = a
        arc_qp[k] = b
    return first, head, sister, arc_pq, arc_qp


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def update_residual(rcap, tr, arc_pq, arc_qp, p, q, old_pq, new_pq, new_qp, old_term, new_term):  # pragma: no cover
    """Bring the residual graph from capacities ``old_*`` to ``new_*`` (Kohli and Torr 2005).

    The flow ``f`` of an edge stays where the new capacities admit it. Where ``f`` exceeds the new
    capacity ``c`` of its direction, the flow is cut back to ``c`` and the surplus ``f - c`` left at
    the edge's tail becomes source capacity of that node, the shortfall at its head sink capacity
    (adding the same constant to both terminal links of a node changes every cut by that constant).
    """
    for k in range(len(arc_pq)):
        a, b = arc_pq[k], arc_qp[k]
        f = old_pq[k] - rcap[a]  # net flow p -> q
        r_pq = new_pq[k] - f
        r_qp = new_qp[k] + f
        if r_pq < 0.0:
            tr[p[k]] -= r_pq
            tr[q[k]] += r_pq
            r_qp += r_pq
            r_pq = 0.0
        elif r_qp < 0.0:
            tr[q[k]] -= r_qp
            tr[p[k]] += r_qp
            r_pq += r_qp
            r_qp = 0.0
        rcap[a] = r_pq
        rcap[b] = r_qp
    for i in range(len(tr)):
        tr[i] += new_term[i] - old_term[i]


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def bk_max_flow(first, head, sister, rcap, tr):  # pragma: no cover
    """Boykov-Kolmogorov max-flow (PAMI 2004) on the residual graph, in place; fresh search trees.

    Returns ``(n,) bool``: nodes of the sink tree at the end, i.e. those that can reach the sink.
    """
    n = len(tr)
    parent = np.full(n, _NONE, dtype=np.int64)
    tree = np.zeros(n, dtype=np.int8)  # 0 free, 1 source tree, 2 sink tree
    stamp = np.zeros(n, dtype=np.int64)
    dist = np.zeros(n, dtype=np.int64)
    queue = np.empty(n + 1, dtype=np.int64)  # circular FIFO of active nodes
    queued = np.zeros(n, dtype=np.bool_)
    orphans = np.empty(n + 1, dtype=np.int64)  # circular FIFO; a node is in it at most once at a time
    qh = 0
    qt = 0
    for i in range(n):
        if tr[i] != 0.0:
            tree[i] = 1 if tr[i] > 0.0 else 2
            parent[i] = _TERMINAL
            dist[i] = 1
            queue[qt] = i
            qt += 1
            queued[i] = True
    time = 0
    cur = -1
    while True:
        # --- growth: find an arc from the source tree to the sink tree
        mid = -1
        while mid < 0:
            if cur < 0 or tree[cur] == 0:
                cur = -1
                while qh != qt:
                    i = queue[qh]
                    qh = qh + 1 if qh < n else 0
                    queued[i] = False
                    if tree[i] != 0:
                        cur = i
                        break
                if cur < 0:
                    break
            i = cur
            t = tree[i]
            for a in range(first[i], first[i + 1]):
                # the source tree grows along residual arcs out of its nodes, the sink tree along
                # residual arcs into them
                if (rcap[a] if t == 1 else rcap[sister[a]]) > 0.0:
                    j = head[a]
                    if tree[j] == 0:
                        tree[j] = t
                        parent[j] = sister[a]
                        stamp[j] = stamp[i]
                        dist[j] = dist[i] + 1
                        if not queued[j]:
                            queue[qt] = j
                            qt = qt + 1 if qt < n else 0
                            queued[j] = True
                    elif tree[j] != t:
                        mid = a if t == 1 else sister[a]
                        break
            if mid < 0:
                cur = -1  # every arc of this node has been looked at
        if mid < 0:
            break

        time += 1
        ot = _augment(mid, head, sister, parent, rcap, tr, orphans)
        qt, cur = _adopt(first, head, sister, rcap, parent, tree, stamp, dist, queue, queued, orphans, ot, qt, cur,
                         time)
    return tree == 2


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _augment(mid, head, sister, parent, rcap, tr, orphans):  # pragma: no cover
    """BK augmentation along source -> ... -> s_end -> ``mid`` -> t_end -> ... -> sink by the path's
    bottleneck; the nodes whose parent arc (or terminal link) it saturates become orphans, written
    from the start of ``orphans``. Returns how many (the orphan FIFO's tail)."""
    n = len(tr)
    s_end = head[sister[mid]]
    t_end = head[mid]
    bottleneck = rcap[mid]
    k = s_end
    while parent[k] != _TERMINAL:
        a = sister[parent[k]]
        if rcap[a] < bottleneck:
            bottleneck = rcap[a]
        k = head[parent[k]]
    if tr[k] < bottleneck:
        bottleneck = tr[k]
    k = t_end
    while parent[k] != _TERMINAL:
        a = parent[k]
        if rcap[a] < bottleneck:
            bottleneck = rcap[a]
        k = head[a]
    if -tr[k] < bottleneck:
        bottleneck = -tr[k]
    rcap[mid] -= bottleneck
    rcap[sister[mid]] += bottleneck
    ot = 0
    k = s_end
    while parent[k] != _TERMINAL:
        a = parent[k]
        up = head[a]
        rcap[a] += bottleneck
        rcap[sister[a]] -= bottleneck
        if rcap[sister[a]] <= 0.0:
            rcap[sister[a]] = 0.0
            parent[k] = _ORPHAN
            orphans[ot] = k
            ot = ot + 1 if ot < n else 0
        k = up
    tr[k] -= bottleneck
    if tr[k] <= 0.0:
        tr[k] = 0.0
        parent[k] = _ORPHAN
        orphans[ot] = k
        ot = ot + 1 if ot < n else 0
    k = t_end
    while parent[k] != _TERMINAL:
        a = parent[k]
        up = head[a]
        rcap[sister[a]] += bottleneck
        rcap[a] -= bottleneck
        if rcap[a] <= 0.0:
            rcap[a] = 0.0
            parent[k] = _ORPHAN
            orphans[ot] = k
            ot = ot + 1 if ot < n else 0
        k = up
    tr[k] += bottleneck
    if tr[k] >= 0.0:
        tr[k] = 0.0
        parent[k] = _ORPHAN
        orphans[ot] = k
        ot = ot + 1 if ot < n else 0
    return ot


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def _adopt(first, head, sister, rcap, parent, tree, stamp, dist, queue, queued, orphans, ot, qt, cur,
           time):  # pragma: no cover
    """BK adoption of the ``ot`` orphans: each takes the parent in its own tree nearest a terminal
    (distances cached by ``stamp``/``dist`` at ``time``), or becomes free, its tree neighbours
    re-activated and its children orphaned. Returns the active queue's tail and the node being
    grown (-1 when that node became free)."""
    n = len(tree)
    oh = 0
    while oh != ot:
        i = orphans[oh]
        oh = oh + 1 if oh < n else 0
        t = tree[i]
        best = -1
        best_d = _FAR
        for a in range(first[i], first[i + 1]):
            ok = rcap[sister[a]] > 0.0 if t == 1 else rcap[a] > 0.0
            if not ok:
                continue
            j = head[a]
            if tree[j] != t or parent[j] == _NONE:
                continue
            d = 0
            k = j
            while True:
                if stamp[k] == time:
                    d += dist[k]
                    break
                d += 1
                if parent[k] == _TERMINAL:
                    stamp[k] = time
                    dist[k] = 1
                    break
                if parent[k] == _ORPHAN:
                    d = _FAR
                    break
                k = head[parent[k]]
            if d < _FAR:
                if d < best_d:
                    best = a
                    best_d = d
                k = j
                while stamp[k] != time:
                    stamp[k] = time
                    dist[k] = d
                    d -= 1
                    k = head[parent[k]]
        if best >= 0:
            parent[i] = best
            stamp[i] = time
            dist[i] = best_d + 1
            continue
        # no parent: i becomes free; its neighbours in the tree may grow into it again
        tree[i] = 0
        parent[i] = _NONE
        for a in range(first[i], first[i + 1]):
            j = head[a]
            if tree[j] != t:
                continue
            feeds = rcap[sister[a]] > 0.0 if t == 1 else rcap[a] > 0.0
            if feeds and not queued[j]:
                queue[qt] = j
                qt = qt + 1 if qt < n else 0
                queued[j] = True
            pa = parent[j]
            if pa >= 0 and head[pa] == i:
                parent[j] = _ORPHAN
                orphans[ot] = j
                ot = ot + 1 if ot < n else 0
        if cur == i:
            cur = -1
    return qt, cur


@numba.njit(cache=NUMBA_CACHE, nogil=True)
def saturate_greedy(first, head, sister, rcap, tr, rounds):  # pragma: no cover
    """Greedy pushes that are part of some maximum flow: a node whose source residual covers all
    its outgoing residual arcs sends their full capacity (it stays on the source side in every
    minimum cut), and a node whose sink residual covers all its incoming arcs takes theirs."""
    n = len(tr)
    for _ in range(rounds):
        moved = 0
        for i in range(n):
            t = tr[i]
            if t > 0.0:
                out = 0.0
                for a in range(first[i], first[i + 1]):
                    out += rcap[a]
                if out > 0.0 and t >= out:
                    for a in range(first[i], first[i + 1]):
                        c = rcap[a]
                        if c > 0.0:
                            tr[head[a]] += c
                            rcap[sister[a]] += c
                            rcap[a] = 0.0
                    tr[i] = t - out
                    moved += 1
            elif t < 0.0:
                inn = 0.0
                for a in range(first[i], first[i + 1]):
                    inn += rcap[sister[a]]
                if inn > 0.0 and -t >= inn:
                    for a in range(first[i], first[i + 1]):
                        c = rcap[sister[a]]
                        if c > 0.0:
                            tr[head[a]] -= c
                            rcap[a] += c
                            rcap[sister[a]] = 0.0
                    tr[i] = t + inn
                    moved += 1
        if moved == 0:
            break
