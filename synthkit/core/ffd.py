"""Free-form deformation (Sederberg and Parry 1986) of points given in local box coordinates.

``points (n, 3)`` are local coordinates ``(s, t, u)`` in the undeformed box ``[0, 1]^3`` (use
:func:`box_coordinates` to get them from world positions). A trivariate Bernstein volume of degree
``(l, m, n)`` maps them through the control lattice ``P (l+1, m+1, n+1, 3)``; degree (1, 1, 1) is
trilinear interpolation of a hexahedron's eight corners, the deformation of the Petri-net paper.
"""

from __future__ import annotations

import numpy as np
from scipy.special import comb

__all__ = ["box_coordinates", "trilinear_weights", "trilinear_ffd", "bernstein_ffd"]


def _points(points) -> np.ndarray:
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {P.shape}")
    return P


def box_coordinates(points, lo, hi) -> np.ndarray:
    """Local coordinates ``(n, 3)`` of world ``points (n, 3)`` in the box ``[lo, hi]``: ``(x - lo) / (hi - lo)``.

    Raises ValueError for a box with zero or negative extent.
    """
    P = _points(points)
    lo = np.asarray(lo, dtype=np.float64).reshape(3)
    hi = np.asarray(hi, dtype=np.float64).reshape(3)
    if np.any(hi <= lo):
        raise ValueError(f"box must have positive extent, got lo={lo.tolist()} hi={hi.tolist()}")
    return (P - lo) / (hi - lo)


def trilinear_weights(points) -> np.ndarray:
    """Weights ``(n, 8)`` of the eight corners for local ``points (n, 3)``; corner ``i + 2j + 4k`` sits at
    ``(i, j, k)``. Rows sum to 1; points outside [0, 1]^3 extrapolate linearly."""
    P = _points(points)
    s, t, u = P[:, 0], P[:, 1], P[:, 2]
    s0, t0, u0 = 1.0 - s, 1.0 - t, 1.0 - u
    W = np.empty((len(P), 8))
    for k, uk in ((0, u0), (1, u)):
        for j, tj in ((0, t0), (1, t)):
            tu = tj * uk
            W[:, 4 * k + 2 * j] = s0 * tu
            W[:, 4 * k + 2 * j + 1] = s * tu
    return W


def trilinear_ffd(points, corners) -> np.ndarray:
    """Map local ``points (n, 3)`` in [0, 1]^3 into the hexahedron with ``corners (8, 3)``.

    Corner order: index ``i + 2j + 4k`` is the image of local corner ``(i, j, k)``. Returns ``(n, 3)``.
    """
    C = np.asarray(corners, dtype=np.float64)
    if C.shape != (8, 3):
        raise ValueError(f"corners must have shape (8, 3), got {C.shape}")
    return trilinear_weights(points) @ C


def bernstein_ffd(points, control) -> np.ndarray:
    """Map local ``points (n, 3)`` through the Bernstein control lattice ``control (l+1, m+1, n+1, 3)``.

    ``X(s, t, u) = sum_ijk B_i^l(s) B_j^m(t) B_k^n(u) P_ijk``. With a (2, 2, 2, 3) lattice whose entry
    ``[i, j, k]`` is corner ``i + 2j + 4k`` this equals :func:`trilinear_ffd`.
    """
    P = _points(points)
    C = np.asarray(control, dtype=np.float64)
    if C.ndim != 4 or C.shape[3] != 3 or min(C.shape[:3]) < 2:
        raise ValueError(f"control must have shape (l+1, m+1, n+1, 3) with each >= 2, got {C.shape}")

    def basis(x, deg):
        r = np.arange(deg + 1)
        return comb(deg, r)[None, :] * x[:, None] ** r[None, :] * (1 - x[:, None]) ** (deg - r)[None, :]

    Bs = basis(P[:, 0], C.shape[0] - 1)
    Bt = basis(P[:, 1], C.shape[1] - 1)
    Bu = basis(P[:, 2], C.shape[2] - 1)
    return np.einsum("ni,nj,nk,ijkd->nd", Bs, Bt, Bu, C, optimize=True)
