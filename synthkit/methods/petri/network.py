"""Curve networks (paper Fig. 6d): several polylines on one projection plane whose curves cross.

Every curve is Algorithm 1 of :mod:`synthkit.methods.petri.construction` (offset lines at the
mitre directions, tangential lines resampled by length, swept along the third axis), with the same
plane, ``side``, ``size_y`` (S_Y), ``size_z`` (S_Z) and sweep for all curves. Where two curves
cross, their bands of cells overlap; that overlap becomes one block of *junction cells* shared by
both curves, and the rest of each curve is cut into *arms* ending at the junctions. All cells of all
curves form one construction space whose adjacency the Petri net fills. The choices (locating
crossings, junction hexahedra, trimming, direction labels across a junction, refusals):
``docs/findings/petri-synth.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from synthkit.errors import KeyedError
from synthkit.methods.petri.curves import (
    PLANE_AXES,
    PLANE_POINT_AXES,
    first_crossing,
    mitre_directions,
    plane_to_world,
    point_polyline_distance,
    polyline_problem,
    resample_polyline,
    units_along,
)
from synthkit.methods.petri.options import SpaceOptions

MIN_ANGLE_DEG = 30.0
"""Smallest crossing angle: below it the junction's parallelograms would be longer than about two
units along each curve and their pieces sheared by more than 60 degrees."""


@dataclass
class _Curve:
    index: int
    P: np.ndarray
    closed: bool
    T: np.ndarray  # unit tangents of the segments
    N: np.ndarray  # left normals
    D: np.ndarray  # mitre directions at the points
    seg_len: np.ndarray
    junctions: list = field(default_factory=list)


@dataclass
class _Junction:
    A: int
    B: int
    sa: int
    sb: int
    point: np.ndarray
    X: dict  # (jA, jB) -> corner point
    order: list  # B's offset lines in the order they cross A's tangent
    order_b: list  # A's offset lines in the order they cross B's tangent


@dataclass
class NetworkSpace:
    """The cells of all curves as one construction space.

    ``quads (Q, 4)`` point ids of every plane cell in corner order ``ia + 2 jb`` of its frame,
    ``points (P, 2)`` plane coordinates, ``sweep (S_Z + 1,)``; cell ``q * S_Z + k`` is plane cell q at
    sweep layer k. ``plane_nbr / plane_back / plane_flip (Q, 4)``: the neighbouring plane cell across
    each edge (+a, -a, +b, -b of the cell's frame, the net's direction order), that edge's name in the
    neighbour's frame, and
    whether it runs the other way there. ``parts``: one dict per arm or junction (kind, curves,
    first plane cell, shape (along, across)); ``cell_part / cell_ij (Q,)``: each plane cell's part and
    its (i, j) in it; ``cell_rows``: for each plane cell the (curve, row) pairs of the offset lines
    whose middle line it must follow (two for a junction cell).
    """

    points: np.ndarray
    quads: np.ndarray
    sweep: np.ndarray
    axes: tuple[int, int, int]
    point_axes: tuple[int, int]
    units: np.ndarray
    curves: list
    directions: list
    closed: list
    j0: float
    size_y: int
    parts: list
    cell_part: np.ndarray
    cell_ij: np.ndarray
    cell_rows: list
    plane_nbr: np.ndarray
    plane_back: np.ndarray
    plane_flip: np.ndarray
    junctions: list

    @property
    def n_plane(self) -> int:
        return len(self.quads)

    @property
    def n_cells(self) -> int:
        return self.n_plane * (len(self.sweep) - 1)

    @property
    def size_z(self) -> int:
        return len(self.sweep) - 1

    def world(self, uv: np.ndarray, w: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` from plane points ``uv (..., 2)`` and sweep coordinates ``w (...)``."""
        return plane_to_world(uv, w, self.point_axes, self.axes[2])

    def hex_corners(self) -> np.ndarray:
        """Eight control points per cell ``(n_cells, 8, 3)``, corner ``ia + 2 jb + 4 kc``."""
        SZ = self.size_z
        q = np.repeat(np.arange(self.n_plane), SZ)
        k = np.tile(np.arange(SZ), self.n_plane)
        out = np.empty((len(q), 8, 3))
        for c in range(8):
            p = self.points[self.quads[q, c & 3]]
            out[:, c] = self.world(p, self.sweep[k + (c >> 2)])
        return out

    def graph(self):
        """``(neighbours, back, flip, coords)`` of the 3-D cells for the Petri net and the crack measure."""
        SZ = self.size_z
        Q = self.n_plane
        N = Q * SZ
        cell = np.arange(N)
        q, k = cell // SZ, cell % SZ
        nbr = np.full((N, 6), -1, np.int64)
        back = np.tile(np.arange(6) ^ 1, (N, 1))
        flip = np.zeros((N, 6), bool)
        for d in range(4):
            n = self.plane_nbr[q, d]
            ok = n >= 0
            nbr[ok, d] = n[ok] * SZ + k[ok]
            back[ok, d] = self.plane_back[q[ok], d]
            flip[ok, d] = self.plane_flip[q[ok], d]
        nbr[k < SZ - 1, 4] = cell[k < SZ - 1] + 1
        nbr[k > 0, 5] = cell[k > 0] - 1
        coords = np.stack([self.cell_ij[q, 0], self.cell_ij[q, 1], k], axis=1)
        return nbr, back, flip, coords

    def describe(self, cell: int) -> str:
        """A cell's name for messages: its part (arm or junction of which curves), (i, j) and k."""
        q, k = divmod(int(cell), self.size_z)
        part = self.parts[int(self.cell_part[q])]
        i, j = (int(v) for v in self.cell_ij[q])
        return f"{part['name']} cell (i={i}, j={j}, k={k})"

    def center_deviation(self) -> np.ndarray:
        """Per plane cell: the largest distance from its centre to the middle offset line of each row it
        belongs to (its curve's row; both curves' rows for a junction cell), in units across (``unit_b``)."""
        C = self.points[self.quads].mean(axis=1)
        dev = np.zeros(self.n_plane)
        ub = float(self.units[1])
        lines = {}
        for q, rows in enumerate(self.cell_rows):
            for curve, j in rows:
                key = (curve, j)
                if key not in lines:
                    line = self.curves[curve] + (j + 0.5 - self.j0) * ub * self.directions[curve]
                    if self.closed[curve]:
                        line = np.vstack([line, line[:1]])
                    lines[key] = line
                dev[q] = max(dev[q], float(point_polyline_distance(C[q : q + 1], lines[key])[0]) / ub)
        return dev

    def plane_segments(self) -> np.ndarray:
        """Every plane cell edge once ``(e, 2, 2)``."""
        edges = set()
        for qd in self.quads.tolist():
            for a, b in ((0, 1), (2, 3), (0, 2), (1, 3)):
                edges.add((min(qd[a], qd[b]), max(qd[a], qd[b])))
        E = np.array(sorted(edges), np.int64)
        return self.points[E]


def _segments(c: _Curve) -> np.ndarray:
    P = c.P
    ends = np.vstack([P[1:], P[:1]]) if c.closed else P[1:]
    return np.stack([P[: len(ends)], ends], axis=1)


def _cross2(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _fmt(p) -> list:
    return [round(float(v), 4) for v in p]


def _line_x(p, t, q, s) -> np.ndarray:
    """Intersection of the lines ``p + x t`` and ``q + y s``."""
    den = _cross2(t, s)
    x = _cross2(q - p, s) / den
    return p + x * t


class _Cells:
    """The plane cells of a network as they are added, part by part (:meth:`add`)."""

    def __init__(self):
        self.points: list = []
        self.quads: list = []
        self.parts: list = []
        self.cell_part: list = []
        self.cell_ij: list = []
        self.cell_rows: list = []

    def add(self, grid: np.ndarray, part: dict, rows_of) -> None:
        """Append ``part`` and the cells of its corner ``grid (nI + 1, nJ + 1, 2)``; ``rows_of(i, j)``:
        the (curve, row) pairs cell (i, j) must follow."""
        self.parts.append(part)
        index = len(self.parts) - 1
        nI, nJ = grid.shape[0] - 1, grid.shape[1] - 1
        for i in range(nI):
            for j in range(nJ):
                base = len(self.points)
                self.points.extend([grid[i, j], grid[i + 1, j], grid[i, j + 1], grid[i + 1, j + 1]])
                self.quads.append([base, base + 1, base + 2, base + 3])
                self.cell_part.append(index)
                self.cell_ij.append((i, j))
                self.cell_rows.append(rows_of(i, j))


def offset_origin(side: str, size_y: int) -> float:
    """j0: the offset line on the curve (side "left": 0, "right": S_Y, "center": S_Y / 2)."""
    return {"left": 0.0, "right": float(size_y), "center": size_y / 2.0}[side]


def build_network(curves, opts: SpaceOptions) -> NetworkSpace:
    """The construction space of the curve network ``curves`` (list of ``(points (m, 2), closed)``).

    Raises :class:`KeyedError` (key ``curves[i]``, ``curves[i].points`` or ``curves``) for a bad
    polyline (as :func:`curves.polyline_problem`), curves that touch, overlap along a line, cross
    themselves or at too shallow an angle, junctions too close to a curve's point or end or to each
    other, arms shorter than one unit, and overlapping or folded cells.
    """
    units = np.asarray(opts.units, np.float64)
    ua, ub = float(units[0]), float(units[1])
    SY = int(opts.size_y)
    j0 = offset_origin(opts.side, SY)
    cs: list[_Curve] = []
    for ci, (pts, closed) in enumerate(curves):
        key = f"curves[{ci}].points"
        problem, kept = polyline_problem([list(p) for p in pts], bool(closed))
        if problem is not None:
            raise KeyedError(key, problem)
        P = np.asarray(kept, np.float64)
        T, N, D, seg_len = mitre_directions(P, bool(closed), key)
        cs.append(_Curve(ci, P, bool(closed), T, N, D, seg_len))
    tol = 1e-9 * max(ua, ub)
    junctions = _find_crossings(cs, tol)
    for J in junctions:
        _junction_corners(J, cs, j0, ub, SY)
    cells = _Cells()
    for c in cs:  # each curve cut at its junctions into arms
        _Arms(c, cs, junctions, opts, cells).build()
    if not cells.quads:
        raise KeyedError("curves", "no cells")
    pts = np.asarray(cells.points, np.float64)
    # one id per distinct point (corners are computed once and copied exactly)
    scale = 1e-7 * max(ua, ub)
    keys = np.round(pts / scale).astype(np.int64)
    _, pid, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    Q = np.asarray(inverse, np.int64).reshape(-1)[np.asarray(cells.quads, np.int64)]
    space = NetworkSpace(
        points=pts[pid],
        quads=Q,
        sweep=opts.sweep_origin + units[2] * np.arange(opts.size_z + 1),
        axes=PLANE_AXES[opts.plane],
        point_axes=PLANE_POINT_AXES[opts.plane],
        units=units,
        curves=[c.P for c in cs],
        directions=[c.D for c in cs],
        closed=[c.closed for c in cs],
        j0=j0,
        size_y=SY,
        parts=cells.parts,
        cell_part=np.asarray(cells.cell_part, np.int64),
        cell_ij=np.asarray(cells.cell_ij, np.int64).reshape(-1, 2),
        cell_rows=cells.cell_rows,
        plane_nbr=np.full((len(Q), 4), -1, np.int64),
        plane_back=np.tile(np.array([1, 0, 3, 2]), (len(Q), 1)),
        plane_flip=np.zeros((len(Q), 4), bool),
        junctions=[(J.A, J.B, J.point.tolist()) for J in junctions],
    )
    _check_network_cells(space)
    _connect(space)
    return space


EDGE_CORNERS = ((1, 3), (0, 2), (2, 3), (0, 1))
"""Plane edge d (+a, -a, +b, -b: the net's direction order) as two corners (ia + 2 jb), in increasing
order of the edge's coordinate."""


def _connect(space: NetworkSpace) -> None:
    owners: dict = {}
    for q, qd in enumerate(space.quads.tolist()):
        for d, (e0, e1) in enumerate(EDGE_CORNERS):
            k = (min(qd[e0], qd[e1]), max(qd[e0], qd[e1]))
            owners.setdefault(k, []).append((q, d, qd[e0]))
    for k, lst in owners.items():
        if len(lst) > 2:
            q = lst[0][0]
            raise KeyedError(
                "curves", f"self-intersecting construction cells: {len(lst)} cells share the edge at "
                f"{_fmt(space.points[k[0]])} ({space.describe(q * space.size_z)})"
            )
        if len(lst) == 2:
            (q1, d1, f1), (q2, d2, f2) = lst
            space.plane_nbr[q1, d1], space.plane_back[q1, d1] = q2, d2
            space.plane_nbr[q2, d2], space.plane_back[q2, d2] = q1, d1
            space.plane_flip[q1, d1] = space.plane_flip[q2, d2] = f1 != f2


def _find_crossings(cs: list[_Curve], tol: float) -> list[_Junction]:
    out = []
    segs = [_segments(c) for c in cs]
    for A in range(len(cs)):
        for B in range(A, len(cs)):
            SA, SB = segs[A], segs[B]
            for sa in range(len(SA)):
                for sb in range(len(SB)):
                    if A == B and sb <= sa:
                        continue
                    p, r = SA[sa, 0], SA[sa, 1] - SA[sa, 0]
                    q, s = SB[sb, 0], SB[sb, 1] - SB[sb, 0]
                    den = float(_cross2(r, s))
                    lr, ls = float(np.linalg.norm(r)), float(np.linalg.norm(s))
                    if abs(den) <= 1e-12 * lr * ls:
                        # parallel: collinear and overlapping?
                        if abs(float(_cross2(q - p, r))) <= tol * lr:
                            t0 = float((q - p) @ r) / lr**2
                            t1 = float((q + s - p) @ r) / lr**2
                            lo, hi = max(0.0, min(t0, t1)), min(1.0, max(t0, t1))
                            if hi - lo > 1e-9:
                                where = "itself" if A == B else f"construction.curves[{B}]"
                                raise KeyedError(
                                    f"curves[{A}]", f"overlaps {where} along a common line from "
                                    f"{_fmt(p + lo * r)} to {_fmt(p + hi * r)} (curves may cross, not run on top "
                                    f"of each other)"
                                )
                        continue
                    t = float(_cross2(q - p, s)) / den
                    u = float(_cross2(q - p, r)) / den
                    eps = 1e-9
                    if t < -eps or t > 1 + eps or u < -eps or u > 1 + eps:
                        continue
                    if A == B:
                        adjacent = sb == sa + 1 or (cs[A].closed and sa == 0 and sb == len(SA) - 1)
                        if adjacent:
                            continue
                        raise KeyedError(
                            f"curves[{A}]", f"crosses itself at {_fmt(p + t * r)} (a curve of a network "
                            f"may cross other curves only)"
                        )
                    X = p + t * r
                    if min(t, 1 - t) * lr <= tol or min(u, 1 - u) * ls <= tol:
                        raise KeyedError(
                            f"curves[{A}]", f"meets construction.curves[{B}] at {_fmt(X)} at a point of a "
                            f"polyline: curves must cross inside a straight segment of each"
                        )
                    sin = abs(den) / (lr * ls)
                    if sin < np.sin(np.radians(MIN_ANGLE_DEG)):
                        raise KeyedError(
                            f"curves[{A}]", f"crosses construction.curves[{B}] at {_fmt(X)} at "
                            f"{np.degrees(np.arcsin(min(sin, 1.0))):.3g} degrees, less than {MIN_ANGLE_DEG:g}"
                        )
                    out.append(_Junction(A, B, sa, sb, X, {}, [], []))
    return out


def _junction_corners(J: _Junction, cs, j0: float, ub: float, SY: int) -> None:
    a, b = cs[J.A], cs[J.B]
    pa, ta, na = a.P[J.sa], a.T[J.sa], a.N[J.sa]
    pb, tb, nb = b.P[J.sb], b.T[J.sb], b.N[J.sb]
    for jA in range(SY + 1):
        for jB in range(SY + 1):
            J.X[(jA, jB)] = _line_x(pa + (jA - j0) * ub * na, ta, pb + (jB - j0) * ub * nb, tb)
    # B's lines along A's tangent and A's lines along B's tangent
    J.order = sorted(range(SY + 1), key=lambda jB: float((J.X[(0, jB)] - pa) @ ta))
    J.order_b = sorted(range(SY + 1), key=lambda jA: float((J.X[(jA, 0)] - pb) @ tb))
    # the junction must lie in the straight segments of both curves
    for c, s, own in ((a, J.sa, True), (b, J.sb, False)):
        for jA in range(SY + 1):
            for jB in range(SY + 1):
                X = J.X[(jA, jB)]
                j = jA if own else jB
                t = (j - j0) * ub
                p0 = c.P[s] + t * c.D[s]
                p1 = c.P[(s + 1) % len(c.P)] + t * c.D[(s + 1) % len(c.P)]
                d = p1 - p0
                x = float((X - p0) @ d) / float(d @ d)
                if x < 0 or x > 1:
                    end = s if x < 0 else (s + 1) % len(c.P)
                    other = J.B if own else J.A
                    is_end = not c.closed and end in (0, len(c.P) - 1)
                    what = "the end of the curve" if is_end else f"its point {end} {_fmt(c.P[end])}"
                    raise KeyedError(
                        f"curves[{c.index}]", f"the crossing with construction.curves[{other}] at "
                        f"{_fmt(J.point)} is too close to {what}: a junction needs the curve straight across it "
                        f"(S_Y = {SY} offset lines of {ub:g} each side)"
                    )


def _arc_position(line: np.ndarray, seg: int, X: np.ndarray) -> float:
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))])
    return float(cum[seg] + np.linalg.norm(X - line[seg]))


class _Arms:
    """Curve ``c`` cut at its junctions into arms. ``rows``: the ``SY + 1`` offset lines of ``c``
    (``ub`` apart, line ``j0`` on the curve), ``crossings``: one record per junction on ``c`` sorted
    along it (its entry and exit cut on every row and on the centre line). :meth:`build` adds each
    arm and each junction ``c`` owns (the ones where it is curve A) to ``cells``."""

    def __init__(self, c: _Curve, cs, junctions, opts: SpaceOptions, cells: _Cells):
        self.c, self.ua, self.SY, self.unit_key = c, float(opts.units[0]), int(opts.size_y), opts.unit_key
        self.cells = cells
        self.key = f"curves[{c.index}]"
        j0, ub = offset_origin(opts.side, self.SY), float(opts.units[1])
        rows = [c.P + (j - j0) * ub * c.D for j in range(self.SY + 1)]
        centre = c.P
        if c.closed:
            rows = [np.vstack([r, r[:1]]) for r in rows]
            centre = np.vstack([c.P, c.P[:1]])
        self.rows, self.centre = rows, centre
        steps = [np.linalg.norm(np.diff(r, axis=0), axis=1) for r in rows]
        self.row_len = [float(s.sum()) for s in steps]
        self.cum_rows = [np.concatenate([[0.0], np.cumsum(s)]) for s in steps]
        self.cen_len = float(np.linalg.norm(np.diff(centre, axis=0), axis=1).sum())
        found = (self._crossing(J, cs) for J in junctions)
        self.crossings = sorted((r for r in found if r is not None), key=lambda r: r["cpos"][0])

    def _crossing(self, J, cs) -> dict | None:
        """Where junction ``J`` cuts this curve (None when ``J`` is not on it)."""
        c, SY = self.c, self.SY
        if J.A == c.index:
            seg, other, own_seg = J.sa, J.B, J.sa
            entry = [J.X[(j, J.order[0])] for j in range(SY + 1)]
            exit_ = [J.X[(j, J.order[-1])] for j in range(SY + 1)]
            cross_t = cs[J.B].T[J.sb]
            cut_in, cut_out = (J.X[(0, J.order[0])], cross_t), (J.X[(0, J.order[-1])], cross_t)
        elif J.B == c.index:
            seg, other, own_seg = J.sb, J.A, J.sb
            entry = [J.X[(J.order_b[0], j)] for j in range(SY + 1)]
            exit_ = [J.X[(J.order_b[-1], j)] for j in range(SY + 1)]
            cross_t = cs[J.A].T[J.sa]
            cut_in, cut_out = (J.X[(J.order_b[0], 0)], cross_t), (J.X[(J.order_b[-1], 0)], cross_t)
        else:
            return None
        pa, ta = c.P[own_seg], c.T[own_seg]
        c_in, c_out = _line_x(pa, ta, *cut_in), _line_x(pa, ta, *cut_out)
        pos = [(_arc_position(self.rows[j], seg, entry[j]), _arc_position(self.rows[j], seg, exit_[j]))
               for j in range(SY + 1)]
        cpos = (_arc_position(self.centre, seg, c_in), _arc_position(self.centre, seg, c_out))
        return dict(J=J, seg=seg, other=other, entry=entry, exit=exit_, pos=pos, cpos=cpos, c_in=c_in, c_out=c_out)

    def _piece(self, j, start, end, p_start, p_end):
        """Row ``j`` from arc position ``start`` (point ``p_start``) to ``end`` (``p_end``), wrapping
        once past the end for a closed curve; returns the polyline and its length along the row."""
        line, cum, total = self.rows[j], self.cum_rows[j], self.row_len[j]
        if end < start:
            end += total
        cum2 = np.concatenate([cum, cum[1:] + total]) if self.c.closed else cum
        line2 = np.vstack([line, line[1:]]) if self.c.closed else line
        inner = [line2[i] for i in range(len(line2)) if start + 1e-12 < cum2[i] < end - 1e-12]
        return np.vstack([p_start] + inner + [p_end]), end - start

    def _arm(self, label, a_start, a_end, near):
        """One arm between two cuts; ``a_start / a_end`` = (row positions, row points, centre position);
        ``near``: the :class:`KeyedError` message when the arm is shorter than one unit."""
        lines = []
        for j in range(self.SY + 1):
            ln, length = self._piece(j, a_start[0][j], a_end[0][j], a_start[1][j], a_end[1][j])
            if length <= 0:
                raise KeyedError(self.key, near)
            lines.append(ln)
        length = a_end[2] - a_start[2]
        if self.c.closed and length < 0:
            length += self.cen_len
        SX = units_along(length, self.ua) if length > 0 else 0
        if SX < 1:
            raise KeyedError(self.key, near)
        grid = np.stack([resample_polyline(ln, SX, False) for ln in lines], axis=1)
        for j, ln in enumerate(lines):  # the ends exactly on the cuts
            grid[0, j], grid[-1, j] = ln[0], ln[-1]
        self._add(grid, {"kind": "arm", "name": f"{label}", "curves": [self.c.index], "shape": [SX, self.SY]})

    def _add(self, grid, part) -> None:
        index = self.c.index
        self.cells.add(grid, part, lambda i, j: [(index, j)])

    def _own_junction(self, r) -> None:
        J, SY = r["J"], self.SY
        if J.A != self.c.index:
            return
        G = np.empty((SY + 1, SY + 1, 2))
        for u, jB in enumerate(J.order):
            for jA in range(SY + 1):
                G[u, jA] = J.X[(jA, jB)]
        part = {"kind": "junction", "name": f"junction of curves {J.A} and {J.B} at {_fmt(J.point)}",
                "curves": [J.A, J.B], "point": _fmt(J.point), "shape": [SY, SY]}
        order = J.order
        self.cells.add(G, part, lambda u, j: [(J.A, j), (J.B, min(order[u], order[u + 1]))])

    def _whole_curve(self) -> None:
        """A curve without junctions: one arm (closed: a ring)."""
        c, too_short = self.c, (f"the curve is {self.cen_len:.6g} long, shorter than one unit along "
                                f"it ({self.ua:.6g}, {self.unit_key})")
        if not c.closed:
            self._arm(f"curve {c.index}", self._start_cut(), self._end_cut(), too_short)
            return
        SX = units_along(self.cen_len, self.ua)
        if SX < 1:
            raise KeyedError(self.key, too_short)
        grid = np.stack([resample_polyline(r[:-1], SX, True) for r in self.rows], axis=1)
        self._add(np.concatenate([grid, grid[:1]], axis=0),
                  {"kind": "arm", "name": f"curve {c.index}", "curves": [c.index], "shape": [SX, self.SY]})

    def _start_cut(self):
        return ([0.0] * (self.SY + 1), [r[0] for r in self.rows], 0.0)

    def _end_cut(self):
        return (list(self.row_len), [r[-1] for r in self.rows], self.cen_len)

    @staticmethod
    def _cut_of(r, which):
        k = 0 if which == "entry" else 1
        return ([p[k] for p in r["pos"]], r[which], r["cpos"][k])

    def _check_overlaps(self) -> None:
        mine = self.crossings
        for a, b in zip(mine, mine[1:], strict=False):
            if b["cpos"][0] <= a["cpos"][1] or any(pb[0] <= pa[1] for pa, pb in zip(a["pos"], b["pos"], strict=True)):
                raise KeyedError(
                    self.key, f"its crossings with construction.curves[{a['other']}] at {_fmt(a['J'].point)} and "
                    f"construction.curves[{b['other']}] at {_fmt(b['J'].point)} are too close to each other: their "
                    f"junctions overlap"
                )
        if self.c.closed and len(mine) > 1:
            a, b = mine[-1], mine[0]
            if (b["cpos"][0] + self.cen_len) <= a["cpos"][1]:
                raise KeyedError(self.key, f"its crossings at {_fmt(a['J'].point)} and {_fmt(b['J'].point)} overlap")

    def build(self) -> None:
        mine, ua, c = self.crossings, self.ua, self.c
        if not mine:
            self._whole_curve()
            return
        self._check_overlaps()
        if not c.closed:
            r0 = mine[0]
            self._arm(f"curve {c.index} arm 0", self._start_cut(), self._cut_of(r0, "entry"),
                      f"the crossing with construction.curves[{r0['other']}] at {_fmt(r0['J'].point)} is "
                      f"too close to the start of the curve (the arm before it must be at least one unit, {ua:g}, "
                      f"long)")
        for t, r in enumerate(mine):
            self._own_junction(r)
            nxt = mine[t + 1] if t + 1 < len(mine) else (mine[0] if c.closed else None)
            label = f"curve {c.index} arm {t + 1}"
            if nxt is not None:
                self._arm(label, self._cut_of(r, "exit"), self._cut_of(nxt, "entry"),
                          f"its crossings with construction.curves[{r['other']}] at {_fmt(r['J'].point)} and "
                          f"construction.curves[{nxt['other']}] at {_fmt(nxt['J'].point)} are too close to each "
                          f"other (the arm between them must be at least one unit, {ua:g}, long)")
            else:
                self._arm(label, self._cut_of(r, "exit"), self._end_cut(),
                          f"the crossing with construction.curves[{r['other']}] at {_fmt(r['J'].point)} is "
                          f"too close to the end of the curve (the arm after it must be at least one unit, {ua:g}, "
                          f"long)")


def _check_network_cells(space: NetworkSpace) -> None:
    """:class:`KeyedError` unless every plane cell is strictly convex and counter-clockwise and no two cells overlap."""
    P = space.points[space.quads]  # (Q, 4, 2) in corner order 00, 10, 01, 11
    ccw = P[:, [0, 1, 3, 2]]
    tol = 1e-9 * float(np.prod(space.units[:2]))
    for c in range(4):
        a, b, d = ccw[:, c], ccw[:, (c + 1) % 4], ccw[:, (c + 3) % 4]
        cross = _cross2(b - a, d - a)
        bad = np.flatnonzero(cross <= tol)
        if len(bad):
            raise KeyedError(
                "curves", f"self-intersecting construction cells with construction.size_y = {space.size_y}: "
                f"{space.describe(int(bad[0]) * space.size_z)} is folded or inverted; reduce "
                f"construction.size_y or smooth the curves"
            )
    segs = space.plane_segments()
    hit = first_crossing(segs)
    if hit is not None:
        raise KeyedError(
            "curves", f"self-intersecting construction cells with construction.size_y = {space.size_y}: cells of "
            f"the network overlap near {_fmt(segs[hit[0], 0])} (bands of curves that come close without crossing, "
            f"or a junction too close to a bend)"
        )
    C = P.mean(axis=1)
    radius = float(np.linalg.norm(P - C[:, None], axis=-1).max())
    tree = cKDTree(C)
    for q, near in enumerate(tree.query_ball_point(C, radius)):
        for r in near:
            if r == q:
                continue
            poly = ccw[r]
            e = np.roll(poly, -1, axis=0) - poly
            inside = _cross2(e, C[q] - poly) > tol
            if inside.all():
                raise KeyedError(
                    "curves", f"self-intersecting construction cells with construction.size_y = {space.size_y}: "
                    f"{space.describe(q * space.size_z)} lies inside "
                    f"{space.describe(r * space.size_z)}"
                )
