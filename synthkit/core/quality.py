"""Mesh-quality figures every mesh output is checked with (input and output side by side).

Positions are first welded within :data:`WELD_REL_TOL` of the bounding-box diagonal, so that the
copies of a vertex an asset keeps for its UV, normal or material seams do not count as open
edges. A face is *degenerate* when one of its edges, or its height over its longest edge, is
shorter than :data:`DEGENERATE_REL_TOL` of the diagonal (zero area, or a needle that no renderer
can shade); such faces are never written by synthkit.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from synthkit.core.mesh import as_mesh_arrays, weld
from synthkit.core.tol import tol

__all__ = ["mesh_quality", "degenerate_faces", "QUALITY_FIGURES", "WELD_REL_TOL", "DEGENERATE_REL_TOL"]

WELD_REL_TOL = tol.weld
"""Positions closer than this fraction of the bounding-box diagonal are one vertex for the figures."""

DEGENERATE_REL_TOL = tol.degenerate_face
"""An edge or a height shorter than this fraction of the bounding-box diagonal makes a face degenerate."""

QUALITY_FIGURES = ("faces", "open_edges", "nonmanifold_edges", "degenerate_faces", "duplicate_faces", "components",
                   "loose_vertices")
"""The figures :func:`mesh_quality` returns, in report order."""


def _diagonal(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) if len(V) else 0.0


def degenerate_faces(V, F, *, diagonal: float | None = None) -> np.ndarray:
    """``(#F,) bool``: faces of ``V (#V, 3)``, ``F (#F, 3)`` with an edge or a height shorter than
    :data:`DEGENERATE_REL_TOL` times ``diagonal`` (default: the bounding-box diagonal of ``V``)."""
    V, F = as_mesh_arrays(V, F)
    if len(F) == 0:
        return np.zeros(0, bool)
    tol = DEGENERATE_REL_TOL * (_diagonal(V) if diagonal is None else float(diagonal))
    T = V[F]
    edges = np.linalg.norm(T[:, [1, 2, 0]] - T, axis=2)
    double_area = np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    longest = edges.max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        height = np.where(longest > 0, double_area / longest, 0.0)
    return (edges.min(axis=1) <= tol) | (height <= tol)


def _welded_index(V: np.ndarray, tol: float) -> np.ndarray:
    """``(#V,)`` welded vertex of each vertex: exact copies (an asset's seam vertices) are merged
    first by their bytes, then the remaining positions within ``tol`` by :func:`weld`."""
    P = np.ascontiguousarray(V, dtype=np.float64) + 0.0  # -0.0 -> 0.0: equal positions, equal bytes
    _, first, inverse = np.unique(P.view(np.dtype((np.void, 24))).ravel(), return_index=True, return_inverse=True)
    _, _, unique_to_welded = weld(P[first], np.zeros((0, 3), np.int64), tol, return_index=True)
    return unique_to_welded[inverse.reshape(-1)]


def mesh_quality(V, F, *, weld_tol: float | None = None) -> dict:
    """Cleanliness figures of ``V (#V, 3)``, ``F (#F, 3)`` (see :data:`QUALITY_FIGURES`):

    - ``faces``: the faces given;
    - ``open_edges``: welded edges used by exactly one non-collapsed face;
    - ``nonmanifold_edges``: welded edges used by more than two faces;
    - ``degenerate_faces``: :func:`degenerate_faces` (collapsed by the weld included);
    - ``duplicate_faces``: faces beyond the first over the same welded vertices in the same
      orientation (a surface stored twice; back-to-back faces of double-sided walls are not);
    - ``components``: connected components of the welded faces (sharing a vertex);
    - ``loose_vertices``: vertices of ``V`` no face uses (a DCC keeps them as stray points).

    ``weld_tol`` defaults to :data:`WELD_REL_TOL` times the bounding-box diagonal.
    """
    V, F = as_mesh_arrays(V, F)
    figures = dict.fromkeys(QUALITY_FIGURES, 0)
    figures["faces"] = int(len(F))
    figures["loose_vertices"] = int(len(V) - len(np.unique(F)))
    if len(F) == 0:
        return figures
    diag = _diagonal(V)
    tol = WELD_REL_TOL * diag if weld_tol is None else float(weld_tol)
    Fw = _welded_index(V, tol)[F]
    alive = (Fw[:, 0] != Fw[:, 1]) & (Fw[:, 1] != Fw[:, 2]) & (Fw[:, 2] != Fw[:, 0])
    figures["degenerate_faces"] = int((degenerate_faces(V, F, diagonal=diag) | ~alive).sum())
    Fa = Fw[alive]
    if len(Fa) == 0:
        return figures
    E = np.sort(np.concatenate([Fa[:, [0, 1]], Fa[:, [1, 2]], Fa[:, [2, 0]]]), axis=1)
    _, counts = np.unique(E[:, 0] * (int(Fa.max()) + 1) + E[:, 1], return_counts=True)  # 1-D keys: fast
    figures["open_edges"] = int((counts == 1).sum())
    figures["nonmanifold_edges"] = int((counts > 2).sum())
    rolled = np.stack([np.roll(Fa, -k, axis=1) for k in range(3)])  # the three rotations of each face
    first = np.argmin(Fa, axis=1)
    canonical = rolled[first, np.arange(len(Fa))]
    _, fcounts = np.unique(np.ascontiguousarray(canonical).view(np.dtype((np.void, 24))).ravel(), return_counts=True)
    figures["duplicate_faces"] = int((fcounts - 1).sum())
    used, Fc = np.unique(Fa, return_inverse=True)
    Fc = Fc.reshape(-1, 3)
    n = len(used)
    rows = np.concatenate([Fc[:, 0], Fc[:, 1]])
    cols = np.concatenate([Fc[:, 1], Fc[:, 2]])
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    figures["components"] = int(connected_components(graph, directed=False)[0])
    return figures
