"""Portals of pieces and their assembly into a chain (paper section 5), over ``V (#V, 3)`` arrays.

A portal is a set of vertices at a piece's end: the vertices on one face of its bounding box
(``x-``, ``x+``, ``y-``, ``y+``, ``z-``, ``z+``, detected), the vertices of one boundary loop of the
welded mesh (an open end: ``loop0``, ``loop1``, ... ordered by their lowest vertex; detected) or
vertices given by index. Its size is
the number of distinct positions. Two portals are compatible when their sizes agree and, once
piece b is translated so that the portal centroids coincide, every position of one has a partner
in the other within the tolerance. Joined portal vertices then weld into shared graph nodes, so
the pieces coincide there exactly and a deformation propagates along the chain.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.core.mesh import weld

__all__ = ["PLANE_PORTALS", "detect_portals", "boundary_portals", "portal_positions", "align_portals"]

PLANE_PORTALS = ("x-", "x+", "y-", "y+", "z-", "z+")


def detect_portals(V, *, tol: float) -> dict[str, np.ndarray]:
    """End-plane portals of ``V (#V, 3)``: name -> indices ``(k,)`` of the vertices within ``tol``
    (model units) of each bounding-box face."""
    V = np.asarray(V, np.float64)
    lo, hi = V.min(axis=0), V.max(axis=0)
    found = {}
    for axis in range(3):
        found[f"{'xyz'[axis]}-"] = np.flatnonzero(np.abs(V[:, axis] - lo[axis]) <= tol)
        found[f"{'xyz'[axis]}+"] = np.flatnonzero(np.abs(V[:, axis] - hi[axis]) <= tol)
    return found


def boundary_portals(V, F, *, tol: float) -> dict[str, np.ndarray]:
    """Boundary loops of ``V (#V, 3)``, ``F (#F, 3)`` once co-located vertices are welded (within
    ``tol``): ``"loop<k>"`` -> render-vertex indices ``(k,)``. A boundary edge is used by one triangle."""
    _, F2, old_to_new = weld(V, F, tol, return_index=True)
    e = np.sort(F2[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    b = uniq[count == 1]
    n = int(old_to_new.max()) + 1
    G = sp.coo_matrix((np.ones(len(b)), (b[:, 0], b[:, 1])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    on_loop = np.zeros(n, bool)
    on_loop[b.reshape(-1)] = True
    loops = sorted({int(label[v]) for v in np.flatnonzero(on_loop)}, key=lambda c: np.flatnonzero(label == c)[0])
    in_loop = label[old_to_new]
    return {f"loop{k}": np.flatnonzero(on_loop[old_to_new] & (in_loop == c)) for k, c in enumerate(loops)}


def portal_positions(V, idx, *, tol: float) -> np.ndarray:
    """Distinct positions ``(k, 3)`` of the vertices ``idx`` of ``V`` (merged within ``tol``)."""
    P = np.asarray(V, np.float64)[np.asarray(idx, np.int64)]
    if not len(P):
        return P.reshape(0, 3)
    key = np.round(P / max(tol, 1e-300)).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    return P[np.sort(first)]


def align_portals(Pa, Pb, *, tol: float) -> tuple[np.ndarray, float]:
    """Translation ``t (3,)`` taking portal positions ``Pb (k, 3)`` onto ``Pa (k, 3)`` and the largest
    gap left. Raises ValueError when the sizes differ or the shapes do not match within ``tol``."""
    if len(Pa) != len(Pb):
        raise ValueError(f"portals have different vertex counts ({len(Pa)} and {len(Pb)})")
    if not len(Pa):
        raise ValueError("portal has no vertex")
    t = Pa.mean(axis=0) - Pb.mean(axis=0)
    dist, j = cKDTree(Pa).query(Pb + t)
    if len(np.unique(j)) != len(Pa) or dist.max() > tol:
        raise ValueError(f"portal shapes do not match (largest gap {dist.max():.3g} after aligning centroids)")
    return t, float(dist.max())
