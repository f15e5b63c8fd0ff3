"""Laplacian baseline: gradient-based (edge-vector) deformation with the same handles.

Botsch and Sorkine (2008): minimise ``sum over mesh edges ||(x_i - x_k) - (v_i - v_k)||^2`` over
every edge of the triangles (flat ones included), with the handle and fixed nodes known. It is the
linear differential deformation the paper compares against in its related work: smooth, but it
spreads a motion over every edge, so edge directions and short edges change.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from synthkit.methods.reshape.solver import ReshapeSolver

__all__ = ["mesh_edges", "laplacian_rows", "laplacian_deform", "angle_errors_deg"]


def mesh_edges(Fn) -> np.ndarray:
    """Unique node pairs ``(E, 2)`` (i < k) of the triangles ``Fn (#F, 3)``, degenerate ones dropped."""
    e = np.sort(Fn[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    e = e[e[:, 0] != e[:, 1]]
    return np.unique(e, axis=0)


def laplacian_rows(X0, edges) -> tuple[sp.csr_matrix, np.ndarray]:
    """``A (3 E, 3 n)``, ``b (3 E,)`` of the edge-vector energy."""
    E = len(edges)
    r = np.arange(3 * E)
    c_hi = (3 * edges[:, 1, None] + np.arange(3)).ravel()
    c_lo = (3 * edges[:, 0, None] + np.arange(3)).ravel()
    A = sp.csr_matrix(
        (np.r_[np.ones(3 * E), -np.ones(3 * E)], (np.r_[r, r], np.r_[c_hi, c_lo])), shape=(3 * E, 3 * len(X0))
    )
    return A, (X0[edges[:, 1]] - X0[edges[:, 0]]).ravel()


def laplacian_deform(X0, Fn, known, X_known, *, backend: str = "auto") -> np.ndarray:
    """Node positions ``(n, 3)`` of the baseline with ``known (k,)`` nodes at ``X_known (k, 3)``."""
    A, b = laplacian_rows(X0, mesh_edges(Fn))
    return ReshapeSolver(A, known, backend=backend).solve(b, X_known)


def angle_errors_deg(X0, X, edges) -> np.ndarray:
    """Angle in degrees ``(E,)`` between each edge's rest and new direction."""
    a = X0[edges[:, 1]] - X0[edges[:, 0]]
    b = X[edges[:, 1]] - X[edges[:, 0]]
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    cos = np.einsum("ij,ij->i", a, b) / np.maximum(na * nb, 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
