"""Static level-of-detail hierarchy of ``V (#V, 3)``, ``F (#F, 3)`` with fine-to-coarse node maps (3.5).

Each level is a quadric-error simplification (Garland and Heckbert) of the previous one by
fast-simplification, whose replayed collapse sequence gives every vertex the coarse vertex it
merged into. Unreferenced vertices are stripped before simplifying and then mapped to their
nearest coarse vertex. On the face graph, a face belongs to the coarse vertex held by at least two
of its corners' images (else the smallest of them). Coarse vertices that receive no node are
dropped, so every map is onto ``0..n_{k+1}-1``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from synthkit.core.mesh import remove_unreferenced
from synthkit.methods.surfacing.graph import face_labels_from_vertices

__all__ = ["collapse", "lod_maps", "level_sizes"]


def collapse(V, F, keep: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadric simplification keeping about ``keep`` of the faces: ``(Vc, Fc, vertex_map (#V,))``."""
    import fast_simplification

    Vs, Fs, old = remove_unreferenced(np.asarray(V, np.float64), np.asarray(F, np.int64))
    _, _, collapses = fast_simplification.simplify(Vs, Fs, target_reduction=1.0 - keep, return_collapses=True)
    Vc, Fc, mapping = fast_simplification.replay_simplification(Vs, Fs.astype(np.int64), collapses)
    full = np.empty(len(V), np.int64)
    full[old] = mapping
    rest = np.setdiff1d(np.arange(len(V)), old)
    if len(rest):
        full[rest] = cKDTree(Vc).query(np.asarray(V)[rest])[1]
    return np.asarray(Vc, np.float64), np.asarray(Fc, np.int64), full


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
    for target in level_sizes(len(np.unique(Fk)), coarsest=coarsest, ratio=ratio, max_levels=max_levels):
        Vn, Fn, vmap = collapse(Vk, Fk, target / max(len(np.unique(Fk)), 1))
        if ids is None:
            up = face_labels_from_vertices(Fk, vmap) if kind == "face" else vmap
        else:
            up = vmap[ids]
        ids, inv = np.unique(up, return_inverse=True)
        maps.append(inv.astype(np.int64))
        Vk, Fk = Vn, Fn
    return maps
