"""Polylines on a projection plane: checks, resampling, offset directions, crossings (pure functions
the construction space, the curve network and the config's validators share)."""

from __future__ import annotations

import numpy as np

from synthkit.errors import KeyedError

PLANE_AXES = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}
"""Plane -> world (and lattice) axes of (a, b, c): the curve's two point axes, then the sweep axis."""

VIEW_AXES = {"front": (0, 1, 2), "top": (0, 2, 1), "side": (2, 1, 0)}
"""View name -> (rectangle x axis, rectangle y axis, depth axis) as world axis indices."""

PLANE_POINT_AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
"""Plane -> world axes of the config's 2-D curve points (first, second coordinate)."""


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
    folds back on itself (opposite segments) is a :class:`KeyedError` with ``key`` naming the point.
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
                raise KeyedError(key, f"the curve folds back on itself at point {i} {P[i].tolist()}")
            D[i] = 2.0 * s / s2
    return T, N, D, seg_len


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
