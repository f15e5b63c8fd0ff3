"""Construction space (paper section 2.2, Algorithm 1 and eq. 2): hexahedral cells along a curve.

Axes of the construction space: ``a`` along the curve (cells i), ``b`` across it (cells j, the
offset lines), ``c`` the sweep axis (cells k). ``PLANE_AXES[plane]`` maps them to the example's
world/lattice axes. A straight curve along +a with side "left" maps every lattice axis onto itself,
and a turn of the curve is a rotation in the plane, so a piece is never mirrored.

Choices where the paper is open (written here as promised):

- Normals ``n_i`` are the left normals of the segments (tangent turned +90 degrees in the plane).
  At an interior point the direction is the mitre ``d_i = 2 (n_{i-1} + n_i) / |n_{i-1} + n_i|^2``:
  the paper's ``n_{i-1} + n_i`` scaled so that every offset line stays at the same distance from
  both segments (a true parallel curve). Ends use their segment's normal; a closed curve has no ends.
- Offset line ``j`` (0..S_Y) lies at signed distance ``(j - j0) * unit_b`` along ``d``, with ``j0 = 0``
  (side "left"), ``S_Y`` ("right") or ``S_Y / 2`` ("center"), so j always grows to the curve's left.
- ``S_X = floor(l / unit_a + 1/2)`` (the paper's ``l / l_X * N_X`` rounded to the nearest integer,
  halves up); each tangential line is resampled by arc length into S_X equal parts (S_X + 1 points,
  or S_X for a closed curve), so the cells are ``l / S_X`` long along the curve: a piece is stretched
  or shrunk along the curve by the factor ``l / (S_X unit_a)``, in [0.75, 1.5) and within
  ``1 +- 1 / (2 S_X)``. A curve shorter than one unit (``l < unit_a``) is refused (ConfigError) rather
  than stretched to one unit.
- Points must all differ (a repeated point, consecutive or not, is a ConfigError naming both
  indices); a closed curve may repeat its first point as its last (dropped), an open curve may not
  (the error points to ``construction.closed``).
- Cells must be strictly convex and counter-clockwise in the plane, and the boundary of the
  construction plane must not cross itself; otherwise the cells self-intersect (ConfigError).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.errors import ConfigError

PLANE_AXES = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}
"""Plane -> world (and lattice) axes of (a, b, c): the curve's two point axes, then the sweep axis."""

PLANE_POINT_AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
"""Plane -> world axes of the config's 2-D curve points (first, second coordinate)."""


@dataclass
class ConstructionSpace:
    """The construction space: plane grid, sweep, axes and unit sizes.

    ``grid (nI, S_Y + 1, 2)``: points p_ij in the plane's (first, second) world coordinates,
    ``nI = S_X + 1`` for an open curve and ``S_X`` for a closed one (index i wraps).
    ``axes``: world axes of (a, b, c); ``sweep (S_Z + 1,)`` world coordinates along c.
    """

    grid: np.ndarray
    sweep: np.ndarray
    closed: bool
    axes: tuple[int, int, int]
    point_axes: tuple[int, int]
    units: np.ndarray
    curve: np.ndarray
    directions: np.ndarray
    j0: float

    @property
    def shape(self) -> tuple[int, int, int]:
        """(S_X, S_Y, S_Z)."""
        nI = self.grid.shape[0]
        return (nI if self.closed else nI - 1, self.grid.shape[1] - 1, len(self.sweep) - 1)

    def world(self, uv: np.ndarray, w: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` from plane points ``uv (..., 2)`` and sweep coordinates ``w (...)``."""
        return plane_to_world(uv, w, self.point_axes, self.axes[2])

    def hex_corners(self) -> np.ndarray:
        """Eight control points per cell, ``(S_X * S_Y * S_Z, 8, 3)`` world, cells in C order of (i, j, k).

        Corner ``ia + 2 jb + 4 kc`` is grid point ``(i + ia, j + jb)`` at sweep ``k + kc``: the
        trilinear FFD corner order of :func:`synthkit.core.ffd.trilinear_ffd` in (a, b, c).
        """
        SX, SY, SZ = self.shape
        nI = self.grid.shape[0]
        i, j, k = np.meshgrid(np.arange(SX), np.arange(SY), np.arange(SZ), indexing="ij")
        i, j, k = i.ravel(), j.ravel(), k.ravel()
        out = np.empty((len(i), 8, 3))
        for c in range(8):
            ia, jb, kc = c & 1, (c >> 1) & 1, (c >> 2) & 1
            out[:, c] = self.world(self.grid[(i + ia) % nI, j + jb], self.sweep[k + kc])
        return out

    def offset_polyline(self, t: float) -> np.ndarray:
        """The curve offset by ``t`` (world units, along the mitre directions): ``(m, 2)``."""
        return self.curve + t * self.directions

    def center_deviation(self) -> np.ndarray:
        """Per cell ``(S_X, S_Y)``: plane distance from the cell centre to the offset curve at the cell's
        middle offset ``(j + 0.5 - j0) * unit_b``, divided by the cell size across (``unit_b``)."""
        SX, SY, _ = self.shape
        nI = self.grid.shape[0]
        i = np.arange(SX)
        dev = np.zeros((SX, SY))
        for j in range(SY):
            c = (
                self.grid[i, j] + self.grid[(i + 1) % nI, j] + self.grid[i, j + 1] + self.grid[(i + 1) % nI, j + 1]
            ) / 4
            line = self.offset_polyline((j + 0.5 - self.j0) * self.units[1])
            if self.closed:
                line = np.vstack([line, line[:1]])
            dev[:, j] = point_polyline_distance(c, line) / self.units[1]
        return dev


def point_polyline_distance(P: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance ``(n,)`` from points ``P (n, 2)`` to the polyline ``line (m, 2)``."""
    A, B = line[:-1], line[1:]
    AB = B - A
    L2 = np.maximum((AB**2).sum(axis=1), 1e-300)
    t = np.clip(((P[:, None, :] - A[None]) * AB[None]).sum(-1) / L2[None], 0, 1)
    Q = A[None] + t[..., None] * AB[None]
    return np.sqrt(((P[:, None, :] - Q) ** 2).sum(-1)).min(axis=1)


def resample_polyline(line: np.ndarray, n_seg: int, closed: bool) -> np.ndarray:
    """``n_seg`` equal arc-length parts of ``line (m, 2)``: ``n_seg + 1`` points (``n_seg`` if closed)."""
    pts = np.vstack([line, line[:1]]) if closed else line
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    targets = np.linspace(0.0, s[-1], n_seg + 1)
    if closed:
        targets = targets[:-1]
    return np.stack([np.interp(targets, s, pts[:, 0]), np.interp(targets, s, pts[:, 1])], axis=1)


def polyline_problem(points, closed: bool) -> tuple[str | None, list]:
    """Check a user polyline: ``(message, points)``; ``message`` is None when the points are usable.

    Refused (message): fewer than 2 points, an open curve whose last point is its first (the message
    says to set ``construction.closed``), any point given twice (consecutive or not; the message
    names both indices and the point), a closed curve with fewer than 3 distinct points. A closed
    curve's repeated first point at the end is dropped from the returned points.
    """
    pts = [tuple(float(v) for v in p) for p in points]
    if len(pts) < 2:
        return f"need at least 2 points, got {len(pts)}", pts
    if len(pts) > 2 and pts[-1] == pts[0]:
        if not closed:
            return (
                f"the last point (index {len(pts) - 1}) repeats the first {list(pts[0])}: an open curve cannot "
                f"end where it starts; for a closed curve set 'construction.closed: true'",
                pts,
            )
        pts = pts[:-1]
    seen: dict[tuple[float, float], int] = {}
    for j, p in enumerate(pts):
        i = seen.setdefault(p, j)
        if i != j:
            return f"points {i} and {j} repeat the point {list(p)} (every point must be distinct)", pts
    if closed and len(pts) < 3:
        return "a closed curve needs at least 3 distinct points", pts
    return None, pts


def units_along(length: float, unit: float) -> int:
    """S_X for a curve of ``length`` and the lattice unit ``unit`` along it: ``floor(length / unit + 1/2)``
    (nearest integer, halves up); 0 when the curve is shorter than one unit (refused by the caller)."""
    if length < unit:
        return 0
    return max(1, int(np.floor(length / unit + 0.5)))


def plane_to_world(uv: np.ndarray, w: np.ndarray, point_axes, sweep_axis: int) -> np.ndarray:
    """World points ``(..., 3)``: plane points ``uv (..., 2)`` on the world axes ``point_axes`` and
    sweep coordinates ``w (...)`` on ``sweep_axis``."""
    out = np.zeros(uv.shape[:-1] + (3,))
    out[..., point_axes[0]] = uv[..., 0]
    out[..., point_axes[1]] = uv[..., 1]
    out[..., sweep_axis] = w
    return out


def mitre_directions(P: np.ndarray, closed: bool, key: str):
    """Unit tangents ``T (s, 2)``, left normals ``N (s, 2)`` and lengths ``(s,)`` of the ``s``
    segments of the polyline ``P (m, 2)`` (``s = m`` when closed), and the offset direction ``D (m,
    2)`` at every point (Algorithm 1's normals at articulation points): the segment normal at an
    open curve's ends, else the mitre ``2 (N_prev + N_next) / |N_prev + N_next|^2``, whose offset lines
    stay parallel to both segments at unit distance. Returns ``(T, N, D, lengths)``; a curve that
    folds back on itself (opposite segments) is a ConfigError naming ``key`` and the point.
    """
    ends = np.vstack([P[1:], P[:1]]) if closed else P[1:]
    T = ends - P[: len(ends)]
    seg_len = np.linalg.norm(T, axis=1)
    T = T / seg_len[:, None]
    N = np.stack([-T[:, 1], T[:, 0]], axis=1)
    m = len(P)
    D = np.empty((m, 2))
    for i in range(m):
        if not closed and i == 0:
            D[i] = N[0]
        elif not closed and i == m - 1:
            D[i] = N[-1]
        else:
            s = N[i - 1] + N[i % len(N)]
            s2 = float(s @ s)
            if s2 < 1e-12:
                raise ConfigError(f"{key}: the curve folds back on itself at point {i} {P[i].tolist()}")
            D[i] = 2.0 * s / s2
    return T, N, D, seg_len


def build_construction_space(
    points,
    *,
    plane: str,
    closed: bool,
    side: str,
    units,
    size_y: int,
    size_z: int,
    sweep_origin: float,
    unit_key: str = "the lattice unit along the curve",
    cells: int | None = None,
) -> ConstructionSpace:
    """Algorithm 1 plus eq. (2): the hexahedral cells along the polyline ``points (m, 2)``.

    ``units (3,)`` are the lattice unit sizes along (a, b, c); ``unit_key`` names where ``units[0]``
    comes from in the config (for messages). ``cells`` is S_X (None: :func:`units_along`). Raises
    ConfigError for the polylines :func:`polyline_problem` refuses, a curve shorter than one unit, a
    curve folding back on itself, and self-intersecting cells.
    """
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 2:
        raise ConfigError(f"construction.points: need a list of 2-D points (x, y), got shape {list(P.shape)}")
    problem, kept = polyline_problem(P.tolist(), closed)
    if problem is not None:
        raise ConfigError(f"construction.points: {problem}")
    P = np.asarray(kept, dtype=np.float64)
    units = np.asarray(units, dtype=np.float64)
    length = float(np.linalg.norm(np.diff(np.vstack([P, P[:1]]) if closed else P, axis=0), axis=1).sum())
    SX = units_along(length, float(units[0]))
    if SX >= 1 and cells is not None:
        SX = int(cells)
    if SX < 1:
        raise ConfigError(
            f"construction.points: the curve is {length:.6g} long, shorter than one unit along it "
            f"({units[0]:.6g}, {unit_key}); a curve must be at least one unit long"
        )
    _, _, D, _ = mitre_directions(P, closed, "construction.points")
    j0 = {"left": 0.0, "right": float(size_y), "center": size_y / 2.0}[side]
    grid = np.stack(
        [resample_polyline(P + (j - j0) * units[1] * D, SX, closed) for j in range(size_y + 1)],
        axis=1,
    )
    sweep = sweep_origin + units[2] * np.arange(size_z + 1)
    space = ConstructionSpace(
        grid=grid,
        sweep=sweep,
        closed=closed,
        axes=PLANE_AXES[plane],
        point_axes=PLANE_POINT_AXES[plane],
        units=units,
        curve=P,
        directions=D,
        j0=j0,
    )
    check_cells(space)
    return space


def check_cells(space: ConstructionSpace) -> None:
    """ConfigError unless every plane cell is strictly convex and counter-clockwise and the boundary of
    the construction plane does not cross itself."""
    G = space.grid
    nI = G.shape[0]
    SX, SY, _ = space.shape
    i = np.arange(SX)
    q = [G[i, :-1], G[(i + 1) % nI, :-1], G[(i + 1) % nI, 1:], G[i, 1:]]  # CCW quad corners
    tol = 1e-9 * float(np.prod(space.units[:2]))
    for c in range(4):
        a, b, d = q[c], q[(c + 1) % 4], q[(c + 3) % 4]
        e1, e2 = b - a, d - a
        cross = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
        bad = np.argwhere(cross <= tol)
        if len(bad):
            ci, cj = (int(v) for v in bad[0])
            raise ConfigError(
                f"construction.points with construction.size_y = {SY}: self-intersecting construction cells: "
                f"cell (i={ci}, j={cj}) is folded or inverted ({len(bad)} corners); reduce construction.size_y "
                f"or smooth the curve"
            )
    loops = (
        [np.vstack([G[:, 0], G[:1, 0]]), np.vstack([G[:, -1], G[:1, -1]])]
        if space.closed
        else [np.vstack([G[:, 0], G[-1, 1:], G[::-1, -1][1:], G[0, ::-1][1:]])]
    )
    segs = np.concatenate([np.stack([L[:-1], L[1:]], axis=1) for L in loops])
    hit = first_crossing(segs)
    if hit is not None:
        raise ConfigError(
            f"construction.points with construction.size_y = {SY}: self-intersecting construction cells: the "
            f"boundary of the construction plane crosses itself near {np.round(segs[hit[0], 0], 4).tolist()}"
        )


def first_crossing(segs: np.ndarray):
    """First pair of segments ``segs (n, 2, 2)`` that cross properly (not at shared end points)."""
    n = len(segs)
    A, B = segs[:, 0], segs[:, 1]
    lo, hi = np.minimum(A, B), np.maximum(A, B)
    for start in range(0, n, 512):
        s = slice(start, min(start + 512, n))
        ov = np.all((lo[s, None] <= hi[None]) & (lo[None] <= hi[s, None]), axis=-1)
        ii, jj = np.nonzero(ov)
        ii = ii + start
        keep = jj > ii + 1
        ii, jj = ii[keep], jj[keep]
        if len(ii) == 0:
            continue

        def orient(p, q, r):
            return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

        o1, o2 = orient(A[ii], B[ii], A[jj]), orient(A[ii], B[ii], B[jj])
        o3, o4 = orient(A[jj], B[jj], A[ii]), orient(A[jj], B[jj], B[ii])
        cross = (o1 * o2 < 0) & (o3 * o4 < 0)
        if cross.any():
            k = int(np.argmax(cross))
            return int(ii[k]), int(jj[k])
    return None
