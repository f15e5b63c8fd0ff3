"""The coloured Petri net of the paper (sections 2.3, 2.4): places, transitions, tokens, inference.

Per cell (subspace) there are three places, candidate ``Pc``, filled ``Pf``, deformed ``Pd``, and
three transitions, updating ``U``, selecting ``S``, deforming ``D``, in the flow order
``U -> Pc -> S -> Pf -> D -> Pd``. ``U`` reads and rewrites its own candidate place, and the
candidate place of every cell feeds the updating transitions of its (up to six) neighbours: that
is how a changed candidate set "sends messages to adjacent nodes". Each cell carries one token
``T = {s, s_u, C, S_c, l, H}`` (eq. 3): state flag, six updating flags, lattice coordinate,
candidate label set, filled label and the eight control points of its hexahedron.

The token fields are stored column-wise (Python lists of ints, label sets as bit masks) so that
inference on 10^4 cells stays fast; :meth:`ColouredPetriNet.token` returns one token as an object,
:meth:`ColouredPetriNet.places`, :meth:`transitions` and :meth:`arcs` enumerate the net, and
:func:`to_pnml` / :func:`to_dot` export it.

Inference (Algorithm 2) is :meth:`ColouredPetriNet.infer`: transitions fire by priority (updating,
selecting, deforming, then a forced seeded choice); where the paper is open: ``docs/findings/petri-synth.md``.
"""

from __future__ import annotations

import heapq
import xml.etree.ElementTree as ET
from collections import deque
from dataclasses import dataclass

import numpy as np

from synthkit.errors import KeyedError

STATES = ("selectable", "fillable", "filled", "deformed")
SELECTABLE, FILLABLE, FILLED, DEFORMED = range(4)
DIRECTIONS = ("+a", "-a", "+b", "-b", "+c", "-c")
"""Direction d = 2 * axis + (0 for +, 1 for -); the paper's s_u = {f_u, f_d, f_l, f_r, f_b, f_t}."""


def _bits(mask: int) -> list[int]:
    out = []
    while mask:
        low = mask & -mask
        out.append(low.bit_length() - 1)
        mask ^= low
    return out


@dataclass
class Token:
    """One token T = {s, s_u, C, S_c, l, H} (eq. 3)."""

    s: str
    s_u: tuple[int, int, int, int, int, int]
    C: tuple[int, int, int]
    S_c: list[int]
    l: int
    H: np.ndarray


_AXIS_NAMES = ("a (along the curve)", "b (across it)", "c (the sweep)")
"""The construction space's axes in messages, by index."""


def _shown(labels: list[int], most: int = 8) -> str:
    """``labels`` for a message: the list, or its count when longer than ``most``."""
    return str(labels) if len(labels) <= most else f"({len(labels)} labels)"


class Unfillable(KeyedError):
    """The example's adjacency constraints cannot fill the construction space (an input error: a
    :class:`KeyedError` without a key)."""

    def __init__(self, message: str):
        super().__init__(None, message)


class Contradiction(Exception):
    """An empty candidate set at ``cell`` (flat index), after ``choices`` random forced selections."""

    def __init__(self, cell: int, choices: int = 0):
        super().__init__(cell)
        self.cell = cell
        self.choices = choices


class ColouredPetriNet:
    """A coloured Petri net over a grid of ``shape = (SX, SY, SZ)`` cells.

    Parameters
    ----------
    shape : cells along (a, b, c); cells are numbered in C order of (i, j, k).
    allowed : (3, L + 1, L + 1) bool adjacency constraints per axis (index L = outside), see
        :class:`synthkit.methods.petri.analysis.Constraints`.
    n_labels : L.
    boundary : whether the outside counts as label L (unary constraints at the space's faces).
    periodic : (3,) bool; a periodic axis wraps (a closed curve makes axis a periodic).
    corners : (N, 8, 3) control points H of every cell, or None.
    graph : None (a grid of ``shape``) or ``(neighbours, back, coords, describe)`` for a curve network
        (:mod:`synthkit.methods.petri.network`): ``neighbours (N, 6)`` the cell in each direction of a
        cell's own frame (-1: none), ``back (N, 6)`` the direction, in the neighbour's frame, that
        points back (``d ^ 1`` within one frame; another direction across a junction where two
        curves' frames meet), ``coords (N, 3)`` the token coordinates C and ``describe(cell)`` a name
        for messages. A pair of neighbours across frames must satisfy the example's constraints in
        both frames: label ``a`` at ``c`` and ``b`` at ``n = neighbours[c, d]`` need
        ``allowed_d(a, b)`` seen from ``c`` and ``allowed_back(b, a)`` seen from ``n``.
    """

    def __init__(
        self,
        shape,
        allowed,
        n_labels: int,
        *,
        boundary: bool = True,
        periodic=(False, False, False),
        corners=None,
        graph=None,
    ):
        self.shape = tuple(int(s) for s in shape)
        self.n_cells = int(np.prod(self.shape))
        self.n_labels = int(n_labels)
        self.boundary = bool(boundary)
        self.periodic = tuple(bool(p) for p in periodic)
        self.allowed = np.asarray(allowed, bool)
        self.corners = None if corners is None else np.asarray(corners, np.float64)
        self.describe = None
        self.unfillable_hint: str | None = None
        """What to change when the space cannot be filled before any random choice (set by the caller)."""
        if graph is not None:
            nbr, back, coords, self.describe = graph
            nbr = np.asarray(nbr, np.int64)
            back = np.asarray(back, np.int64)
            self.n_cells = len(nbr)
            self.coords = np.asarray(coords, np.int64)
        else:
            self.coords = np.stack(np.unravel_index(np.arange(self.n_cells), self.shape), axis=1)
            nbr = np.full((self.n_cells, 6), -1, np.int64)
            for axis in range(3):
                for sign, d in ((1, 2 * axis), (-1, 2 * axis + 1)):
                    c = self.coords.copy()
                    c[:, axis] += sign
                    if self.periodic[axis]:
                        c[:, axis] %= self.shape[axis]
                    ok = (c[:, axis] >= 0) & (c[:, axis] < self.shape[axis])
                    if self.periodic[axis] and self.shape[axis] == 1:
                        ok[:] = False
                    nbr[ok, d] = np.ravel_multi_index(c[ok].T, self.shape)
            back = np.tile(np.arange(6) ^ 1, (self.n_cells, 1))
        self.neighbours = nbr
        self.back = back
        L = self.n_labels
        # support[d][b]: labels a allowed in a cell whose neighbour in direction d holds b
        self._support = []
        for axis in range(3):
            A = self.allowed[axis]
            plus = [self._mask(A[:L, b]) for b in range(L + 1)]  # neighbour at +axis holds b: A[a, b]
            minus = [self._mask(A[b, :L]) for b in range(L + 1)]  # neighbour at -axis holds b: A[b, a]
            self._support += [plus, minus]
        # table per (cell, direction): d itself within one frame, 6 + 6 d + back across frames
        tab = np.where(back == (np.arange(6) ^ 1)[None], np.arange(6)[None], 6 + 6 * np.arange(6)[None] + back)
        for d in range(6):
            for e in range(6):
                if e == d ^ 1 or graph is None:
                    self._support.append(None)
                    continue
                # a at c (neighbour at d holds b) and b at n (c seen from n at e holds a)
                self._support.append(
                    [
                        sum(1 << a for a in _bits(self._support[d][b]) if b == L or (self._support[e][a] >> b) & 1)
                        for b in range(L + 1)
                    ]
                )
        self._tab = tab.tolist()
        self._back = back.tolist()
        self.full = (1 << L) - 1
        init = []
        nbr_list = nbr.tolist()
        for c in range(self.n_cells):
            m = self.full
            if self.boundary:
                for d, n in enumerate(nbr_list[c]):
                    if n < 0:
                        m &= self._support[d][L]
            init.append(m)
        self.initial = init
        self._nbr = nbr_list
        self.reset()

    def conflict(self, cell: int) -> tuple[int, int, list[int], list[int]] | None:
        """Why ``cell``'s candidate set ran empty: ``(d, neighbour, neighbour_labels, own_labels)`` for
        the first direction ``d`` (2 axis: the neighbour at +axis, 2 axis + 1: at -axis) whose
        support, with the directions before it, leaves none of ``own_labels``; None when the outside
        alone leaves none. Read right after a :class:`Contradiction`, before :meth:`reset`."""
        m = self.cand[cell]
        own = _bits(m)
        tc = self._tab[cell]
        for d, n in enumerate(self._nbr[cell]):
            if n < 0:
                continue
            s = 0
            for b in _bits(self.cand[n]):
                s |= self._support[tc[d]][b]
            if m & s == 0:
                return d, n, _bits(self.cand[n]), own
            m &= s
        return None

    def _describe_conflict(self, cell: int) -> str:
        """``conflict(cell)`` in words, for the error line."""
        found = self.conflict(cell)
        if found is None:
            return "no label may touch the outside on all of its open sides"
        d, n, theirs, own = found
        where = self.describe(n) if self.describe is not None else tuple(int(v) for v in self.coords[n])
        side = f"{'+-'[d & 1]}{_AXIS_NAMES[d >> 1]}"
        return f"none of its labels {_shown(own)} may have label(s) {_shown(theirs)} of cell {where} at {side}"

    @staticmethod
    def _mask(column) -> int:
        m = 0
        for a in np.flatnonzero(column):
            m |= 1 << int(a)
        return m

    def reset(self) -> None:
        """Initial marking: every token 'selectable' with the boundary-restricted candidate sets."""
        self.state = [SELECTABLE] * self.n_cells
        self.cand = list(self.initial)
        self.label = [-1] * self.n_cells
        self.su = [0] * self.n_cells
        self.fired = {"updating": 0, "selecting": 0, "deforming": 0, "forced_selecting": 0}
        self.choices: list[tuple[int, int, int]] = []
        """Random forced selections of this attempt, in order: (cell, size of its candidate set, label);
        the origin's (not random) selection is not included."""

    # ------------------------------------------------------------------ inspection
    def token(self, cell: int) -> Token:
        """The token of ``cell`` (flat index) as an object."""
        su = self.su[cell]
        return Token(
            s=STATES[self.state[cell]],
            s_u=tuple((su >> d) & 1 for d in range(6)),
            C=tuple(int(v) for v in self.coords[cell]),
            S_c=_bits(self.cand[cell]),
            l=self.label[cell],
            H=None if self.corners is None else self.corners[cell],
        )

    def places(self):
        """(id, kind, cell) of every place: kinds 'candidate', 'filled', 'deformed'."""
        for c in range(self.n_cells):
            for kind in ("candidate", "filled", "deformed"):
                yield f"P{kind[0]}_{c}", kind, c

    def transitions(self):
        """(id, kind, cell) of every transition: kinds 'updating', 'selecting', 'deforming'."""
        for c in range(self.n_cells):
            for kind in ("updating", "selecting", "deforming"):
                yield f"T{kind[0]}_{c}", kind, c

    def arcs(self):
        """(source id, target id) of every arc: the per-cell chain and the messages to neighbours."""
        for c in range(self.n_cells):
            yield f"Tu_{c}", f"Pc_{c}"
            yield f"Pc_{c}", f"Tu_{c}"
            yield f"Pc_{c}", f"Ts_{c}"
            yield f"Ts_{c}", f"Pf_{c}"
            yield f"Pf_{c}", f"Td_{c}"
            yield f"Td_{c}", f"Pd_{c}"
            for n in self._nbr[c]:
                if n >= 0:
                    yield f"Pc_{c}", f"Tu_{n}"

    def label_grid(self) -> np.ndarray:
        """Filled labels ``(SX, SY, SZ)`` (-1 where a cell is not filled)."""
        return np.asarray(self.label, np.int64).reshape(self.shape)

    # ------------------------------------------------------------------ firing
    def _notify(self, cell: int, queue: deque, queued: bytearray) -> None:
        su = self.su
        back = self._back[cell]
        for d, n in enumerate(self._nbr[cell]):
            if n >= 0:
                su[n] |= 1 << back[d]
                if not queued[n]:
                    queued[n] = 1
                    queue.append(n)

    def fill(self, cell: int, label: int, queue: deque, queued: bytearray, *, forced: bool) -> None:
        """Fire the selecting transition of ``cell`` with ``label``."""
        self.cand[cell] = 1 << label
        self.label[cell] = label
        self.state[cell] = FILLED
        self.fired["selecting"] += 1
        if forced:
            self.fired["forced_selecting"] += 1
        self._notify(cell, queue, queued)

    def _run(self, rng, origin_labels, deform, filled: deque) -> None:
        try:
            self._fire_all(rng, origin_labels, deform, filled)
        except Contradiction as exc:
            exc.choices = self.fired["forced_selecting"] - 1  # the origin's choice is not random
            raise

    def _start(self) -> tuple[deque, bytearray, deque]:
        """Every cell's updating flags set and queued; cells with one candidate fillable. Returns
        ``(queue, queued, fillable)``."""
        cand, state, su, nbr = self.cand, self.state, self.su, self._nbr
        queue: deque = deque(range(self.n_cells))
        queued = bytearray(b"\x01" * self.n_cells)
        for c in range(self.n_cells):
            su[c] = sum(1 << d for d, n in enumerate(nbr[c]) if n >= 0)
        fillable: deque = deque()
        for c in range(self.n_cells):
            m = cand[c]
            if m == 0:
                raise Contradiction(c)
            if m & (m - 1) == 0:
                state[c] = FILLABLE
                fillable.append(c)
        return queue, queued, fillable

    def _fill_origin(self, origin_labels, queue: deque, queued: bytearray, fillable: deque, heap: list) -> None:
        """Fire the origin's selecting transition with the first of ``origin_labels`` it may take, then
        put every selectable cell on the ``heap`` of forced choices."""
        cand, state = self.cand, self.state
        m0 = cand[0]
        choice = next((lab for lab in origin_labels if (m0 >> lab) & 1), None)
        if choice is None:
            raise Contradiction(0)
        if state[0] == FILLABLE:
            fillable.remove(0)
        self.fill(0, choice, queue, queued, forced=True)
        for c in range(self.n_cells):
            if state[c] == SELECTABLE:
                heapq.heappush(heap, (cand[c].bit_count(), c))

    def _fire_all(self, rng, origin_labels, deform, filled: deque) -> None:
        """Fire transitions by priority until none is enabled (module docstring): updating (inline,
        the hot loop), the origin's selection, selecting, deforming, then a forced seeded choice."""
        cand, state, su, nbr, support, tab = self.cand, self.state, self.su, self._nbr, self._support, self._tab
        fired = self.fired
        queue, queued, fillable = self._start()
        heap: list = []
        cache: dict = {}
        origin_done = False
        while True:
            if queue:
                c = queue.popleft()
                queued[c] = 0
                flags, su[c] = su[c], 0
                m = old = cand[c]
                nb = nbr[c]
                tc = tab[c]
                while flags:
                    low = flags & -flags
                    d = low.bit_length() - 1
                    flags ^= low
                    t = tc[d]
                    key = (t, cand[nb[d]])
                    s = cache.get(key)
                    if s is None:
                        s = 0
                        for b in _bits(key[1]):
                            s |= support[t][b]
                        cache[key] = s
                    m &= s
                fired["updating"] += 1
                if m != old:
                    if m == 0:
                        raise Contradiction(c)
                    cand[c] = m
                    self._notify(c, queue, queued)
                    if state[c] == SELECTABLE:
                        if m & (m - 1) == 0:
                            state[c] = FILLABLE
                            fillable.append(c)
                        else:
                            heapq.heappush(heap, (m.bit_count(), c))
                continue
            if not origin_done:
                origin_done = True
                self._fill_origin(origin_labels, queue, queued, fillable, heap)
                filled.append(0)
                continue
            if fillable:
                c = fillable.popleft()
                self.fill(c, cand[c].bit_length() - 1, queue, queued, forced=False)
                filled.append(c)
                continue
            if filled:
                c = filled.popleft()
                state[c] = DEFORMED
                fired["deforming"] += 1
                if deform is not None:
                    deform(c, self.label[c])
                continue
            while heap and (state[heap[0][1]] != SELECTABLE or cand[heap[0][1]].bit_count() != heap[0][0]):
                heapq.heappop(heap)
            if not heap:
                break
            c = heapq.heappop(heap)[1]
            labels = _bits(cand[c])
            label = labels[int(rng.integers(len(labels)))]
            self.choices.append((c, len(labels), label))
            self.fill(c, label, queue, queued, forced=True)
            filled.append(c)

    def infer(
        self, rng: np.random.Generator, *, origin_labels, deform=None, max_restarts: int = 20, on_restart=None
    ) -> int:
        """Run Algorithm 2 until every token is 'deformed'; return the number of restarts.

        ``origin_labels``: labels to try at the origin cell, best first (the example's e_000 first).
        ``deform(cell, label)`` is called by every deforming transition. ``on_restart()`` is called
        before each restart (to discard deformed pieces). Raises :class:`Unfillable` naming the cell of the
        last contradiction when ``max_restarts`` restarts all fail, or at once when the contradiction
        came before any random choice (then every restart would fail the same way).
        """
        restarts = 0
        attempt_rng = rng
        while True:
            self.reset()
            try:
                self._run(attempt_rng, list(origin_labels), deform, deque())
                return restarts
            except Contradiction as exc:
                cell = (
                    tuple(int(v) for v in self.coords[exc.cell]) if self.describe is None else self.describe(exc.cell)
                )
                if exc.choices <= 0:
                    raise Unfillable(
                        f"petri-synth: the example's adjacency constraints cannot fill the construction space: "
                        f"contradiction (empty candidate set) at cell {cell} before any random choice: "
                        f"{self._describe_conflict(exc.cell)}, so no restart can help "
                        f"({self.unfillable_hint or 'check the sizes S_Y, S_Z and labels.boundary'})"
                    ) from None
                if restarts >= max_restarts:
                    raise Unfillable(
                        f"petri-synth: the example's adjacency constraints cannot fill the construction space: "
                        f"contradiction (empty candidate set) at cell {cell} after {restarts} restarts "
                        f"(inference.max_restarts)"
                    ) from None
                restarts += 1
                if on_restart is not None:
                    on_restart()
                attempt_rng = np.random.default_rng(int(rng.integers(2**63)))


def ac3_solve(
    shape, allowed, n_labels: int, *, boundary=True, periodic=(False, False, False), rng, origin_labels
) -> np.ndarray:
    """Plain AC-3 model synthesis on the same constraints (the benchmark's reference).

    Domains are Python sets; a queue of arcs (cell, neighbour) revises a cell's domain by testing
    every label against every label of the neighbour (the textbook REVISE), re-queuing the arcs into
    the cell on change. Same search as :meth:`ColouredPetriNet.infer` (origin label, then the smallest
    domain forced to a uniformly drawn label, no restarts). Returns labels ``shape``; raises
    :class:`Contradiction` on an empty domain.
    """
    net = ColouredPetriNet(shape, allowed, n_labels, boundary=boundary, periodic=periodic)
    A = np.asarray(allowed, bool)
    ok = [[[bool(A[axis, a, b]) for b in range(n_labels + 1)] for a in range(n_labels + 1)] for axis in range(3)]
    nbr = net._nbr
    dom = [set(_bits(m)) for m in net.initial]
    N = net.n_cells

    def compatible(d, a, b):
        axis = d >> 1
        return ok[axis][a][b] if d & 1 == 0 else ok[axis][b][a]

    def revise(c, d):
        n = nbr[c][d]
        removed = [a for a in dom[c] if not any(compatible(d, a, b) for b in dom[n])]
        for a in removed:
            dom[c].discard(a)
        return bool(removed)

    def propagate(arcs):
        queue = deque(arcs)
        inq = set(arcs)
        while queue:
            c, d = queue.popleft()
            inq.discard((c, d))
            if revise(c, d):
                if not dom[c]:
                    raise Contradiction(c)
                for d2, n in enumerate(nbr[c]):
                    if n >= 0 and (n, d2 ^ 1) not in inq:
                        inq.add((n, d2 ^ 1))
                        queue.append((n, d2 ^ 1))

    def arcs_into(c):
        return [(n, d ^ 1) for d, n in enumerate(nbr[c]) if n >= 0]

    propagate([(c, d) for c in range(N) for d, n in enumerate(nbr[c]) if n >= 0])
    choice = next((lab for lab in origin_labels if lab in dom[0]), None)
    if choice is None:
        raise Contradiction(0)
    dom[0] = {choice}
    propagate(arcs_into(0))
    while True:
        best, best_c = None, -1
        for c in range(N):
            k = len(dom[c])
            if k > 1 and (best is None or k < best):
                best, best_c = k, c
        if best is None:
            break
        labels = sorted(dom[best_c])
        dom[best_c] = {labels[int(rng.integers(len(labels)))]}
        propagate(arcs_into(best_c))
    return np.array([next(iter(s)) for s in dom], np.int64).reshape(net.shape)


def adjacency_violations(
    label_grid: np.ndarray, allowed: np.ndarray, n_labels: int, *, boundary: bool = True, periodic=(False, False, False)
) -> int:
    """Neighbouring label pairs (and, with ``boundary``, labels at the space's faces) not allowed by
    the example, counted independently of the inference; unfilled cells (-1) count as violations."""
    g = np.asarray(label_grid, np.int64)
    bad = int((g < 0).sum())
    g = np.where(g < 0, n_labels, g)
    A = np.asarray(allowed, bool)
    for axis in range(3):
        x = np.moveaxis(g, axis, 0)
        first, second = x[:-1], x[1:]
        bad += int((~A[axis][first, second]).sum())
        if periodic[axis] and x.shape[0] > 1:
            bad += int((~A[axis][x[-1], x[0]]).sum())
        elif boundary:
            bad += int((~A[axis][n_labels, x[0]]).sum()) + int((~A[axis][x[-1], n_labels]).sum())
    return bad


def graph_violations(labels, neighbours, back, allowed: np.ndarray, n_labels: int, *, boundary: bool = True) -> int:
    """:func:`adjacency_violations` on a curve network's neighbour graph, independently of the inference.

    Every pair of neighbours is counted once, as one violation when the label pair does not occur
    in the example in that direction seen from either cell's frame (``allowed_d(a, b)`` from the cell,
    ``allowed_back(b, a)`` from the neighbour); with ``boundary`` every cell face without a neighbour
    is a violation when its label never ends the example on that side; unfilled cells (-1) count.
    """
    lab = np.asarray(labels, np.int64).ravel()
    nbr = np.asarray(neighbours, np.int64)
    back = np.asarray(back, np.int64)
    A = np.asarray(allowed, bool)
    L = int(n_labels)
    bad = int((lab < 0).sum())
    g = np.where(lab < 0, L, lab)

    for d in range(6):
        n = nbr[:, d]
        has = n >= 0
        c = np.flatnonzero(has & (np.arange(len(g)) < np.where(has, n, -1)))
        if len(c):
            e = back[c, d]
            a, b = g[c], g[nbr[c, d]]
            axis_d, axis_e = d >> 1, e >> 1
            first = A[axis_d, a, b] if d & 1 == 0 else A[axis_d, b, a]
            second = np.where(e & 1 == 0, A[axis_e, b, a], A[axis_e, a, b])
            bad += int((~(first & second)).sum())
        if boundary:
            c = np.flatnonzero(~has)
            axis = d >> 1
            ends = A[axis, g[c], L] if d & 1 == 0 else A[axis, L, g[c]]
            bad += int((~ends).sum())
    return bad


def to_pnml(net: ColouredPetriNet, *, net_id: str = "target") -> bytes:
    """The net as PNML (ISO/IEC 15909-2, place/transition grammar), tokens in ``toolspecific`` elements."""
    root = ET.Element("pnml", xmlns="http://www.pnml.org/version-2009/grammar/pnml")
    n = ET.SubElement(root, "net", id=net_id, type="http://www.pnml.org/version-2009/grammar/ptnet")
    ET.SubElement(ET.SubElement(n, "name"), "text").text = f"petri-synth {net_id} net {list(net.shape)}"
    page = ET.SubElement(n, "page", id="page0")
    for pid, kind, c in net.places():
        p = ET.SubElement(page, "place", id=pid)
        ET.SubElement(ET.SubElement(p, "name"), "text").text = f"{kind} {tuple(int(v) for v in net.coords[c])}"
        holds = {"candidate": SELECTABLE, "filled": FILLED, "deformed": DEFORMED}[kind]
        st = net.state[c]
        marked = st == holds or (kind == "candidate" and st == FILLABLE)
        ET.SubElement(ET.SubElement(p, "initialMarking"), "text").text = "1" if marked else "0"
        if marked:
            t = net.token(c)
            ts = ET.SubElement(p, "toolspecific", tool="synthkit", version="1")
            ET.SubElement(
                ts,
                "token",
                s=t.s,
                s_u="".join(map(str, t.s_u)),
                C=" ".join(map(str, t.C)),
                S_c=" ".join(map(str, t.S_c)),
                l=str(t.l),
                H="" if t.H is None else " ".join(f"{v:.6g}" for v in np.ravel(t.H)),
            )
    for tid, kind, c in net.transitions():
        t = ET.SubElement(page, "transition", id=tid)
        ET.SubElement(ET.SubElement(t, "name"), "text").text = f"{kind} {tuple(int(v) for v in net.coords[c])}"
    for k, (s, t) in enumerate(net.arcs()):
        ET.SubElement(page, "arc", id=f"a{k}", source=s, target=t)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def to_dot(net: ColouredPetriNet, *, name: str = "target") -> str:
    """The net as a Graphviz digraph: places as circles (label = state and filled label), transitions
    as boxes."""
    lines = [f"digraph {name} {{", "  rankdir=LR;"]
    for pid, kind, c in net.places():
        st = STATES[net.state[c]]
        lines.append(f'  {pid} [shape=circle, label="{kind}\\n{st} l={net.label[c]}"];')
    for tid, kind, _ in net.transitions():
        lines.append(f'  {tid} [shape=box, label="{kind}"];')
    for s, t in net.arcs():
        lines.append(f"  {s} -> {t};")
    lines.append("}")
    return "\n".join(lines) + "\n"
