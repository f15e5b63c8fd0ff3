"""Portals of pieces and their assembly into a chain (paper section 5), over ``V (#V, 3)`` arrays.

A portal is a set of vertices at a piece's end: the vertices on one face of its bounding box
(``x-``, ``x+``, ``y-``, ``y+``, ``z-``, ``z+``, detected) or vertices given by index. Its size is
the number of distinct positions. Two portals are compatible when their sizes agree and, once
piece b is translated so that the portal centroids coincide, every position of one has a partner
in the other within the tolerance. Joined portal vertices then weld into shared graph nodes, so
the pieces coincide there exactly and a deformation propagates along the chain.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["PLANE_PORTALS", "detect_portals", "portal_positions", "align_portals"]

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
