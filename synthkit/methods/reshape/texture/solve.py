"""Corner and interior solves of the texture reshape (Cabral et al. 2009, eqs. 10-13 and 4.4).

Both are weighted least squares over ``(n, 2)`` texel positions, factored once
(:class:`synthkit.core.lsq.LeastSquares`: CHOLMOD through cholespy, or a tuned SuperLU): a reshape
step only rebuilds ``b``. Strict rows carry ``STRICT_WEIGHT`` on their squared residual [Loa85].

- :class:`CornerSolver`: eq. 10 per triangle corner, ``|N_T(c_i)| c_i' - sum_k (c_k' + r_ki (c_i -
  c_k)) = 0``, plus the contour's 2-D eq. 1 in its per-edge form (each contour segment keeps its
  direction: ``n_ki . (c_i' - c_k') = 0``), and corner 0 fixed.
- :class:`InteriorSolver`: eq. 11 keeps boundary nodes on their contour segment; eq. 12 per grid
  edge and direction with the stiffness of eq. 13; corners are known (moved to the right side).
  Toroidal tiles also tie the boundary nodes of opposite sides together, so the tile stays
  periodic.

The paper reads ``T_dir`` at each grid edge's midpoint only; a feature thinner than the grid
spacing (a 3-texel door frame under a 32-texel grid) then falls between midpoints and is stretched.
:func:`edge_stiffness` takes the largest ``T_dir`` over ``samples`` points along the edge
(``samples=1`` is the paper's midpoint).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.ndimage import map_coordinates

from synthkit.core.lsq import LeastSquares
from synthkit.methods.reshape.texture.grid import BOUNDARY, CORNER, DeformationGrid

__all__ = ["CornerSolver", "InteriorSolver", "edge_stiffness", "toroidal_repetitions", "STRICT_WEIGHT"]

STRICT_WEIGHT = 1e4
"""Weight of strict rows on their squared residual (as the geometry reshape's default)."""


def _rows(entries, m, n):
    r, c, v = (np.concatenate(x) for x in zip(*entries, strict=True))
    return sp.csr_matrix((v, (r, c)), shape=(m, n))


class CornerSolver:
    """Texture-space polygon solve for one surface (eq. 10 and the contour's 2-D eq. 1).

    Parameters
    ----------
    C : (c, 2) float64 corner positions (texels)
    F : (t, 3) int64 triangles over corners
    segments : (S, 2) int64 contour segments over corners
    form : "contour" (default) or "triangles" (the paper's eq. 10 over triangle corners)
    backend : least-squares backend (see :class:`synthkit.core.lsq.LeastSquares`)

    Eq. 10 over the triangles scales every triangle edge by its ``r_ki`` without turning it; under
    an anisotropic stretch the diagonals of a quad must turn, so the literal form compromises: a
    100 x 50 quad (two triangles) stretched 2x horizontally comes out 192 x 71 (height +42 %).
    The paper's text says the solve replicates the changes of the *polygon* edges: ``"contour"``
    writes ``c_k' - c_i' = r_ki (c_k - c_i)`` for each contour segment (exactly 200 x 50 there)
    and keeps the triangle rows of eq. 10 with weight ``TRIANGLE_WEIGHT`` only so that corners
    inside the polygon stay determined.

    Attributes: ``equations``, ``factor_ms``, ``solve_ms`` (last solve).
    """

    TRIANGLE_WEIGHT = 1e-6

    def __init__(self, C, F, segments, *, form: str = "contour", backend: str = "auto"):
        if form not in ("contour", "triangles"):
            raise ValueError(f"unknown corner form {form!r}")
        self.C = np.asarray(C, np.float64)
        self.F = np.asarray(F, np.int64)
        self.segments = np.asarray(segments, np.int64)
        c, t, s = len(self.C), len(self.F), len(self.segments)
        corner = self.F.reshape(-1)
        nb1, nb2 = self.F[:, [1, 2, 0]].reshape(-1), self.F[:, [2, 0, 1]].reshape(-1)
        m10 = 3 * t
        ent = []
        for ax in range(2):  # eq. 10: row (tri, corner j, axis) = 2 c_j - c_{j+1} - c_{j+2}
            rows = 2 * np.arange(m10) + ax
            ent += [(rows, 2 * corner + ax, np.full(m10, 2.0)), (rows, 2 * nb1 + ax, -np.ones(m10)),
                    (rows, 2 * nb2 + ax, -np.ones(m10))]
            rows = 2 * m10 + 2 * np.arange(s) + ax  # contour form: c_k - c_i
            ent += [(rows, 2 * self.segments[:, 1] + ax, np.ones(s)), (rows, 2 * self.segments[:, 0] + ax, -np.ones(s))]
        d = self.C[self.segments[:, 1]] - self.C[self.segments[:, 0]]
        length = np.linalg.norm(d, axis=1)
        if s == 0 or length.min() <= 0:
            raise ValueError("the contour needs segments of positive length in texture space")
        nrm = np.column_stack([-d[:, 1], d[:, 0]]) / length[:, None]
        rows = 2 * m10 + 2 * s + np.arange(s)  # 2-D eq. 1, per contour edge
        for ax in range(2):
            ent += [(rows, 2 * self.segments[:, 1] + ax, nrm[:, ax]), (rows, 2 * self.segments[:, 0] + ax, -nrm[:, ax])]
        m = 2 * m10 + 3 * s
        self._A = _rows(ent, m, 2 * c)
        self._free = np.arange(2, 2 * c)  # corner 0 fixed
        w_tri, w_con = (self.TRIANGLE_WEIGHT, 1.0) if form == "contour" else (1.0, 0.0)
        w = np.concatenate([np.full(2 * m10, w_tri), np.full(2 * s, w_con), np.full(s, STRICT_WEIGHT)])
        self.equations = int((w > 0).sum())
        start = time.perf_counter()
        self._lsq = LeastSquares(self._A[:, self._free], weights=w, backend=backend)
        self.factor_ms = 1e3 * (time.perf_counter() - start)
        self.solve_ms = 0.0
        self._nb = (corner, nb1, nb2)

    def solve(self, ratio) -> np.ndarray:
        """New corners ``(c, 2)`` for the edge length ratios ``ratio``: a callable ``(i, k) -> r_ki``
        over corner index arrays ``(m,)``, or a ``(c, c)`` sparse or dense matrix."""
        start = time.perf_counter()
        corner, nb1, nb2 = self._nb
        r1, r2 = _ratio(ratio, corner, nb1), _ratio(ratio, corner, nb2)
        tri = r1[:, None] * (self.C[corner] - self.C[nb1]) + r2[:, None] * (self.C[corner] - self.C[nb2])
        i, k = self.segments[:, 0], self.segments[:, 1]
        con = _ratio(ratio, i, k)[:, None] * (self.C[k] - self.C[i])
        b = np.concatenate([tri.reshape(-1), con.reshape(-1), np.zeros(len(self.segments))])
        b = b - self._A[:, :2] @ self.C[0]
        X = np.empty_like(self.C)
        X[0] = self.C[0]
        X[1:] = self._lsq.solve(b).reshape(-1, 2)
        self.solve_ms = 1e3 * (time.perf_counter() - start)
        return X


def _ratio(ratio, i, k) -> np.ndarray:
    if callable(ratio):
        return np.asarray(ratio(i, k), np.float64)
    R = ratio.tocsr() if sp.issparse(ratio) else np.asarray(ratio)
    return np.asarray(R[i, k]).reshape(-1)


def edge_stiffness(T, X, edges, *, s_min: float, s_align: float, samples: int = 9, wrap: bool = False,
                   t_max: float | None = None) -> np.ndarray:
    """Eq. 13 per grid edge and direction: ``(D, E)`` stiffness ``s_min + T_dir (1 + s_align (1 -
    |e . dir|))`` for maps ``T (D, H, W)`` (directions as :data:`autosim.DIRECTIONS` order: x, y),
    nodes ``X (n, 2)`` texels, ``edges (E, 2)``; ``T_dir`` is the largest of ``samples`` bilinear
    reads along the edge (``samples=1``: the midpoint), clipped at ``t_max`` when given: above it a
    texel is simply rigid, and rigid texels share the stretch evenly (why: docs/findings/reshape.md)."""
    a, b = X[edges[:, 0]], X[edges[:, 1]]
    t = np.array([0.5]) if samples == 1 else np.linspace(0, 1, samples)
    P = a[None] + t[:, None, None] * (b - a)[None]  # (s, E, 2)
    e = (b - a) / np.maximum(np.linalg.norm(b - a, axis=1), 1e-12)[:, None]
    out = np.empty((len(T), len(edges)))
    for k in range(len(T)):
        coords = [P[..., 1].ravel() - 0.5, P[..., 0].ravel() - 0.5]
        val = map_coordinates(T[k], coords, order=1, mode="grid-wrap" if wrap else "nearest")
        Td = val.reshape(len(t), -1).max(axis=0)
        if t_max is not None:
            Td = np.minimum(Td, t_max)
        align = 1.0 - np.abs(e[:, k])
        out[k] = s_min + Td * (1.0 + s_align * align)
    return out


class InteriorSolver:
    """Boundary and interior node solve of one grid (eqs. 11-13), factored once.

    Parameters
    ----------
    grid : the :class:`DeformationGrid`
    stiffness : (2, E) eq. 13 weights per direction (x, y) and grid edge
    periodic : (p, 3) int64 rows ``(node a, node b, axis)``: boundary nodes on opposite sides of a
        toroidal tile whose coordinate ``axis`` must stay equal (None: not toroidal)
    backend : least-squares backend

    Attributes: ``equations``, ``vars``, ``A (m, vars)`` the rows over the free coordinates and
    their ``weights (m,)``, ``factor_ms``, ``solve_ms`` (last solve).
    """

    def __init__(self, grid: DeformationGrid, stiffness, *, periodic=None, backend: str = "auto"):
        self.grid = grid
        n = len(grid.X)
        E = grid.edges
        i, j = E[:, 0], E[:, 1]
        ent, w, m = [], [], 0
        for ax in range(2):  # eq. 12: (g_i - g_j) . dir
            rows = m + np.arange(len(E))
            ent += [(rows, 2 * i + ax, np.ones(len(E))), (rows, 2 * j + ax, -np.ones(len(E)))]
            w.append(np.asarray(stiffness[ax], np.float64) ** 2)
            m += len(E)
        self._m12 = m
        bn = np.flatnonzero(grid.kind == BOUNDARY)
        seg = grid.segments[grid.segment[bn]]
        d = grid.X[seg[:, 1]] - grid.X[seg[:, 0]]
        self._normal = np.column_stack([-d[:, 1], d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
        self._bn, self._bseg = bn, seg
        rows = m + np.arange(len(bn))  # eq. 11: b . N = c_i . N
        ent += [(rows, 2 * bn + ax, self._normal[:, ax]) for ax in range(2)]
        w.append(np.full(len(bn), STRICT_WEIGHT))
        m += len(bn)
        per = np.zeros((0, 3), np.int64) if periodic is None else np.asarray(periodic, np.int64).reshape(-1, 3)
        rows = m + np.arange(len(per))
        ones = np.ones(len(per))
        ent += [(rows, 2 * per[:, 0] + per[:, 2], ones), (rows, 2 * per[:, 1] + per[:, 2], -ones)]
        w.append(np.full(len(per), STRICT_WEIGHT))
        m += len(per)
        A = _rows(ent, m, 2 * n)
        known = np.flatnonzero(grid.kind == CORNER)
        kc = (2 * known[:, None] + np.arange(2)).ravel()
        free = np.setdiff1d(np.arange(2 * n), kc)
        self._A_k, self._kc, self._free = A[:, kc], kc, free
        self._rest = np.concatenate([(grid.X[i] - grid.X[j])[:, ax] for ax in range(2)])
        self.equations, self.vars = m, len(free)
        self.A, self.weights = A[:, free].tocsr(), np.concatenate(w)
        start = time.perf_counter()  # a polygon smaller than a grid cell has corners only
        self._lsq = LeastSquares(self.A, weights=self.weights, backend=backend) if len(free) else None
        self.factor_ms = 1e3 * (time.perf_counter() - start)
        self.solve_ms = 0.0

    def solve(self, corners) -> np.ndarray:
        """All node positions ``(n, 2)`` given the new corners ``(c, 2)`` (the grid's first nodes)."""
        start = time.perf_counter()
        corners = np.asarray(corners, np.float64)
        c0 = corners[self._bseg[:, 0]]
        b = np.zeros(self.equations)
        b[: self._m12] = self._rest
        b[self._m12: self._m12 + len(self._bn)] = np.einsum("ij,ij->i", c0, self._normal)
        b -= self._A_k @ corners.reshape(-1)
        x = np.empty(2 * len(self.grid.X))
        x[self._kc] = corners.reshape(-1)
        if self._lsq is not None:
            x[self._free] = self._lsq.solve(b)
        self.solve_ms = 1e3 * (time.perf_counter() - start)
        return x.reshape(-1, 2)


def toroidal_repetitions(UV, UV_new) -> tuple[np.ndarray, np.ndarray]:
    """Repetitions ``(2,)`` and per-tile scale ``(2,)`` of a toroidal surface (4.4) from the
    bounding boxes of its original and solved corners ``UV``, ``UV_new (c, 2)`` (in tiles).

    Along an axis where the original surface held a whole number of tiles (within 1e-3), the new
    extent is rounded to whole tiles (at least one) and the tile stretches by ``extent /
    repetitions``, as the paper does. Along an axis where it held a fraction of a tile (a 0.2-wide
    window reveal of a 1-tile brick texture), rounding would squeeze the tile fivefold; there the
    tile keeps its size (scale 1) and the surface shows as much of the repeating texture as its new
    extent covers. Repetitions are then ``extent`` (not whole)."""
    ext0 = UV.max(axis=0) - UV.min(axis=0)
    ext = UV_new.max(axis=0) - UV_new.min(axis=0)
    whole = (np.abs(ext0 - np.round(ext0)) < 1e-3) & (np.round(ext0) >= 1)
    reps = np.where(whole, np.maximum(np.round(ext), 1.0), ext)
    return reps, np.where(whole, ext / reps, 1.0)
