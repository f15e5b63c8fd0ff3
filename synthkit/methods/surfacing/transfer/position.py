"""Target position selection (section 4.1).

Each face is graded by the sum of the seam costs of all edges whose midpoint lies within
``radius`` of its centroid (Euclidean, a stand-in for the geodesic distance at patch scale); an
edge between a covered and an uncovered face counts as a seam of maximal signal difference
(``max_difference * length``). The new position is drawn uniformly among the allowed faces graded
at least ``(1 - tolerance)`` of the best; when no face has a grade (the first patch, or an
uncovered piece far from any patch) it is drawn among the uncovered faces. The synthesis allows
only uncovered faces while any is left (so every patch covers a new face: on meshes of large
triangles a patch may not reach past its seed), then every face.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

__all__ = ["grading_matrix", "edge_grades", "choose_position"]


def grading_matrix(centroids: np.ndarray, midpoints: np.ndarray, radius: float) -> sp.csr_matrix:
    """``(#F, E)`` 0/1 matrix: edge midpoint ``midpoints (E, 3)`` within ``radius`` of face
    centroid ``centroids (#F, 3)``."""
    D = cKDTree(centroids).sparse_distance_matrix(cKDTree(midpoints), radius, output_type="coo_matrix")
    W = sp.coo_matrix((np.ones(D.nnz, np.float32), (D.row.astype(np.int32), D.col.astype(np.int32))),
                      shape=(len(centroids), len(midpoints)))
    return W.tocsr()


def edge_grades(patch_of: np.ndarray, pairs: np.ndarray, seams: np.ndarray, lengths: np.ndarray,
                max_difference: float) -> np.ndarray:
    """Grade contribution ``(E,)`` of each edge: its seam cost ``seams (E,)`` between covered faces
    of different patches, ``max_difference * length`` between a covered and an uncovered face."""
    a, b = patch_of[pairs[:, 0]], patch_of[pairs[:, 1]]
    frontier = (a >= 0) != (b >= 0)
    seam = (a >= 0) & (b >= 0) & (a != b)
    return np.where(frontier, max_difference * lengths, np.where(seam, seams, 0.0))


def choose_position(grades: np.ndarray, uncovered: np.ndarray, allowed: np.ndarray, *, rng,
                    tolerance: float = 0.1) -> int | None:
    """A face drawn among the highest ``grades (#F,)`` of the ``allowed (#F,) bool`` faces (or among
    the allowed uncovered ones when no face has a positive grade); None when none is left."""
    g = np.where(allowed, grades, -np.inf)
    best = float(g.max()) if allowed.any() else -np.inf
    if best > 0:
        pool = np.flatnonzero(g >= (1 - tolerance) * best)
    else:
        pool = np.flatnonzero(uncovered & allowed)
    if not len(pool):
        return None
    return int(pool[rng.integers(len(pool))])
