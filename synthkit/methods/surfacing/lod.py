"""Static level-of-detail hierarchy of ``V (#V, 3)``, ``F (#F, 3)`` with fine-to-coarse node maps (3.5).

Each level is a quadric-error simplification (Garland and Heckbert) of the previous one by
fast-simplification, whose collapse sequence gives every vertex the coarse vertex it merged into.
Unreferenced vertices are stripped before simplifying and then mapped to their nearest coarse
vertex. On the face graph, a face belongs to the coarse vertex held by at least two of its corners'
images (else the smallest of them). Coarse vertices that receive no node are dropped, so every map
is onto ``0..n_{k+1}-1``.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial import cKDTree

from synthkit.core.mesh import remove_unreferenced
from synthkit.core.numba_cache import NUMBA_CACHE
from synthkit.methods.surfacing.graph import face_labels_from_vertices

__all__ = ["collapse", "lod_maps", "level_sizes"]


def collapse(V, F, keep: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadric simplification keeping about ``keep`` of the faces: ``(Vc, Fc, vertex_map (#V,))``."""
    import fast_simplification

    Vs, Fs, old = remove_unreferenced(np.asarray(V, np.float64), np.asarray(F, np.int64))
    Vc, Fc, collapses = fast_simplification.simplify(Vs, Fs, target_reduction=1.0 - keep, return_collapses=True)
    mapping = _collapse_map(collapses, Vs, Fs)
    full = np.empty(len(V), np.int64)
    full[old] = mapping
    unused = np.ones(len(V), bool)
    unused[old] = False
    rest = np.flatnonzero(unused)
    if len(rest):
        full[rest] = cKDTree(Vc).query(np.asarray(V)[rest])[1]
    return np.asarray(Vc, np.float64), np.asarray(Fc, np.int64), full


@numba.njit(cache=NUMBA_CACHE)
def _roots(collapses, n):  # pragma: no cover (compiled)
    root = np.arange(n)
    for k in range(len(collapses) - 1, -1, -1):
        root[collapses[k, 1]] = root[collapses[k, 0]]
    return root


def _collapse_map(collapses: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Coarse vertex ``(#V,)`` of every vertex of ``V``, ``F`` from the collapse sequence ``(k, 2)``
    (row ``(a, b)``: ``b`` merged into ``a``), numbered as the simplified mesh numbers its vertices
    (the surviving vertices some face still uses, in their original order); a survivor no face uses
    any more goes to the nearest used one, as fast-simplification's ``replay_simplification`` does."""
    n = len(V)
    root = _roots(np.asarray(collapses, np.int64), n)
    R = root[F]
    keep = (R[:, 0] != R[:, 1]) & (R[:, 1] != R[:, 2]) & (R[:, 0] != R[:, 2])
    used = np.zeros(n, bool)
    used[R[keep].ravel()] = True
    lost = np.flatnonzero(~used[root])
    if len(lost):
        ids = np.flatnonzero(used)
        root[lost] = ids[cKDTree(V[ids]).query(V[lost])[1]]
    rank = np.cumsum(used) - 1
    return rank[root]


def level_sizes(n_vertices: int, *, coarsest: int, ratio: float, max_levels: int) -> list[int]:
    """Target vertex counts of the levels coarser than the input (empty: single level)."""
    sizes = []
    n = n_vertices
    while n > coarsest and len(sizes) + 1 < max_levels:
        n = max(int(n * ratio), coarsest)
        sizes.append(n)
    return sizes


def lod_maps(V, F, kind: str, *, coarsest: int, ratio: float, max_levels: int) -> list[np.ndarray]:
    """Maps from the nodes of each level to those of the next coarser one (finest first)."""
    maps: list[np.ndarray] = []
    Vk, Fk = np.asarray(V, np.float64), np.asarray(F, np.int64)
    ids = None  # level-k node -> vertex of the level-k mesh
    sizes = level_sizes(_n_used(Fk, len(Vk)), coarsest=coarsest, ratio=ratio, max_levels=max_levels)
    for target in sizes:
        Vn, Fn, vmap = collapse(Vk, Fk, target / max(_n_used(Fk, len(Vk)), 1))
        if ids is None:
            up = face_labels_from_vertices(Fk, vmap) if kind == "face" else vmap
        else:
            up = vmap[ids]
        ids, inv = _compact(up, len(Vn))
        maps.append(inv)
        Vk, Fk = Vn, Fn
    return maps


def _n_used(F: np.ndarray, n: int) -> int:
    """Number of vertices ``F`` references."""
    return int(np.count_nonzero(np.bincount(F.ravel(), minlength=n)))


def _compact(values: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_inverse=True)`` for integers in ``[0, n)``, by counting."""
    used = np.bincount(values, minlength=n) > 0
    remap = np.cumsum(used) - 1
    return np.flatnonzero(used), remap[values].astype(np.int64)
