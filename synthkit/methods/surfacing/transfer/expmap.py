"""A local log map: the discrete exponential map of Schmidt, Grimm and Wyvill (2006, "Interactive
decal compositing with discrete exponential maps"), computed only over the vertices within the
radius a patch needs.

Vertices are finalized in Dijkstra order of their estimated geodesic distance ``|u|``. A
vertex ``q`` reached from a finalized vertex ``p`` gets the estimate ``u_p + T_p(q - p)``: the
edge projected on ``p``'s tangent plane, rescaled to the edge's length and written in ``p``'s
frame, which is the seed's frame carried along the shortest-path tree (each frame is the parent's
turned by the smallest rotation taking the parent's normal to the child's). When ``q`` is
finalized its coordinates are the upwind average of the estimates from all its finalized
neighbours, weighted by ``1 / |q - p|^2`` (the paper's averaging, which keeps the map from
following the mesh's edge directions); where faces around ``q`` have both other corners final,
``q`` is instead the mean of those faces unfolded rigidly onto their corners' coordinates (an
intrinsic placement, without the tangent-plane projection: spot's radial error p95 0.030 of a
0.15 sqrt(area) reach against 0.077 by projected edges; docs/findings/surface-by-numbers.md).
No estimate is nearer the seed than the vertex's chord to it (:func:`_at_least`). The walk stops
at the first vertex farther than ``stop``: the cost is that of the disc the patch needs, not of
the whole surface, and nothing is factored. Vertices not reached are NaN.
"""

from __future__ import annotations

import heapq

import numba
import numpy as np

from synthkit.core.numba_cache import NUMBA_CACHE

__all__ = ["vertex_graph", "exp_map"]


def vertex_graph(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex adjacency of ``F (#F, 3)`` over ``n`` vertices in CSR form ``(indptr (n + 1,),
    indices (2 #edges,))``, sorted and without repeats."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.unique(np.sort(E, axis=1), axis=0)
    both = np.concatenate([E, E[:, ::-1]])
    both = both[np.lexsort((both[:, 1], both[:, 0]))]
    indptr = np.zeros(n + 1, np.int64)
    np.add.at(indptr, both[:, 0] + 1, 1)
    return np.cumsum(indptr), both[:, 1].astype(np.int64)


@numba.njit(cache=NUMBA_CACHE)
def _transported(a: np.ndarray, n0: np.ndarray, n1: np.ndarray) -> np.ndarray:  # pragma: no cover
    """``a (3,)`` turned by the smallest rotation taking unit ``n0`` to unit ``n1`` (Rodrigues)."""
    k = np.cross(n0, n1)
    s = np.sqrt(k @ k)
    c = n0 @ n1
    if s < 1e-12:
        return a.copy()
    k = k / s
    return a * c + np.cross(k, a) * s + k * (k @ a) * (1.0 - c)


@numba.njit(cache=NUMBA_CACHE)
def _step(V, N, E1, E2, p, q):  # pragma: no cover
    """The edge ``q - p`` in ``p``'s frame: projected on ``p``'s tangent plane, rescaled to its length."""
    w = V[q] - V[p]
    length = np.sqrt(w @ w)
    t = w - (w @ N[p]) * N[p]
    lt = np.sqrt(t @ t)
    if lt > 1e-300:
        t = t * (length / lt)
    return np.array([t @ E1[p], t @ E2[p]]), length


def vertex_faces(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Faces around each of ``n`` vertices of ``F (#F, 3)`` in CSR form ``(indptr (n + 1,), faces (3 #F,))``."""
    order = np.argsort(F.ravel(), kind="stable")
    indptr = np.zeros(n + 1, np.int64)
    np.add.at(indptr, F.ravel() + 1, 1)
    return np.cumsum(indptr), (order // 3).astype(np.int64)


@numba.njit(cache=NUMBA_CACHE)
def _unfolded(V, F, U, done, f, q):  # pragma: no cover
    """Domain position of ``q`` from face ``f`` laid rigidly on its other two corners' domain positions
    (midpoint of the edge kept, the face's winding kept counter-clockwise), and whether both were final."""
    k = 0
    while F[f, k] != q:
        k += 1
    a, b = F[f, (k + 1) % 3], F[f, (k + 2) % 3]  # q, a, b counter-clockwise: q left of a -> b
    if not (done[a] and done[b]):
        return np.zeros(2), False
    e = V[b] - V[a]
    length = max(np.sqrt(e @ e), 1e-300)
    w = V[q] - V[a]
    x = (w @ e) / length
    h = w - x * e / length
    y = np.sqrt(h @ h)
    d = U[b] - U[a]
    u = d / max(np.sqrt(d @ d), 1e-300)
    m = 0.5 * (U[a] + U[b])
    return m + (x - 0.5 * length) * u + y * np.array([-u[1], u[0]]), True


@numba.njit(cache=NUMBA_CACHE)
def _at_least(u: np.ndarray, chord: np.ndarray) -> np.ndarray:  # pragma: no cover
    """``u (2,)`` lengthened to the chord ``|chord (3,)|`` where it is shorter: no geodesic is shorter
    than the straight segment, and an estimate that is has folded back (a front gone round a bump),
    which would otherwise pull the vertices after it towards the seed and past the stop."""
    lu, lc = np.sqrt(u @ u), np.sqrt(chord @ chord)
    if lu >= lc or lu < 1e-300:
        return u
    return u * (lc / lu)


@numba.njit(cache=NUMBA_CACHE)
def exp_map(V: np.ndarray, indptr: np.ndarray, indices: np.ndarray, N: np.ndarray, seed: int,
            e1: np.ndarray, e2: np.ndarray, stop: float, F: np.ndarray, fptr: np.ndarray,
            faces: np.ndarray, unfold: bool) -> np.ndarray:  # pragma: no cover
    """Discrete exponential map ``(#V, 2)`` from ``seed`` in the tangent frame ``(e1, e2)`` (unit,
    orthogonal to ``N[seed]``) over the vertex graph ``(indptr, indices)`` of ``V (#V, 3)`` with unit
    vertex normals ``N (#V, 3)``; vertices farther than ``stop`` (estimated) are NaN. ``unfold``: a
    vertex with faces whose two other corners are final is placed by unfolding those faces
    (``F (#F, 3)``, faces around each vertex ``(fptr, faces)`` in CSR form) instead of by projected edges."""
    n = len(V)
    U = np.full((n, 2), np.nan)
    dist = np.full(n, np.inf)
    parent = np.full(n, -1, np.int64)
    done = np.zeros(n, np.bool_)
    E1 = np.zeros((n, 3))
    E2 = np.zeros((n, 3))
    E1[seed], E2[seed] = e1, e2
    dist[seed] = 0.0
    heap = [(0.0, seed)]
    while heap:
        d, q = heapq.heappop(heap)
        if done[q] or d > dist[q]:
            continue
        if d > stop:
            break
        if q != seed:
            p = parent[q]
            a = _transported(E1[p], N[p], N[q])
            a = a - (a @ N[q]) * N[q]
            a = a / max(np.sqrt(a @ a), 1e-300)
            E1[q], E2[q] = a, np.cross(N[q], a)
            acc = np.zeros(2)
            wsum = 0.0
            if unfold:
                for j in range(fptr[q], fptr[q + 1]):
                    c, ok = _unfolded(V, F, U, done, faces[j], q)
                    if ok:
                        acc += c
                        wsum += 1.0
            for j in range(indptr[q], indptr[q + 1] if wsum == 0.0 else indptr[q]):
                r = indices[j]
                if done[r]:
                    t, length = _step(V, N, E1, E2, r, q)
                    w = 1.0 / max(length * length, 1e-300)
                    acc += w * (U[r] + t)
                    wsum += w
            U[q] = _at_least(acc / wsum, V[q] - V[seed])
        else:
            U[q] = 0.0
        done[q] = True
        for j in range(indptr[q], indptr[q + 1]):
            r = indices[j]
            if done[r]:
                continue
            t, _ = _step(V, N, E1, E2, q, r)
            u = _at_least(U[q] + t, V[r] - V[seed])
            du = np.sqrt(u @ u)
            if du < dist[r]:
                dist[r] = du
                parent[r] = q
                heapq.heappush(heap, (du, r))
    return U
