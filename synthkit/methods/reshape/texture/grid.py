"""Deformation grid of one textured surface (Cabral et al. 2009, 4.3), in ``(n, 2)`` texel form.

The surface's contour is a set of segments ``(S, 2)`` over its texture-space corners ``C (c, 2)``
(texel coordinates). Grid lines sit at ``x = i hx`` and ``y = j hy``. Each contour segment is
walked by a DDA (Amanatides and Woo): the parameters at which it crosses a vertical and a
horizontal grid line are merged in order, which visits the cells it passes through one after the
other; each crossing is a *boundary node*. Lattice points strictly inside the contour (even-odd
rule, so holes work) are *interior nodes*; the contour's corners are *corner nodes*.

Grid edges join consecutive nodes along every grid line where the joining segment lies inside the
contour, and consecutive nodes along every contour segment. A triangulation of the nodes (Delaunay,
triangles whose centroid is inside) carries the distortion map and the stretch measure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay

__all__ = ["DeformationGrid", "build_grid", "dda_crossings", "inside_contour", "CORNER", "BOUNDARY", "INTERIOR"]

CORNER, BOUNDARY, INTERIOR = 0, 1, 2
"""Node kinds."""


@dataclass
class DeformationGrid:
    """Nodes, edges and triangles of a deformation grid.

    Attributes
    ----------
    X : (n, 2) float64 node positions (texels); the first ``c`` nodes are the corners ``C``
    kind : (n,) int64 ``CORNER``, ``BOUNDARY`` or ``INTERIOR``
    segment : (n,) int64 contour segment of a boundary node (-1 otherwise)
    edges : (E, 2) int64 grid edges
    triangles : (t, 3) int64 triangles over nodes
    segments : (S, 2) int64 contour segments over corners
    spacing : (2,) float64 ``(hx, hy)`` in texels
    """

    X: np.ndarray
    kind: np.ndarray
    segment: np.ndarray
    edges: np.ndarray
    triangles: np.ndarray
    segments: np.ndarray
    spacing: np.ndarray

    @property
    def counts(self) -> dict:
        return {"nodes": len(self.X), "corners": int((self.kind == CORNER).sum()),
                "boundary": int((self.kind == BOUNDARY).sum()), "interior": int((self.kind == INTERIOR).sum()),
                "edges": len(self.edges), "triangles": len(self.triangles)}


def dda_crossings(a, b, spacing) -> np.ndarray:
    """Parameters ``t (k,)`` in (0, 1), increasing, where segment ``a (2,) -> b (2,)`` crosses a grid
    line ``x = i hx`` or ``y = j hy`` (``spacing = (hx, hy)``): the DDA's cell-boundary events."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ts = []
    for ax in range(2):
        lo, hi = sorted((a[ax], b[ax]))
        h = spacing[ax]
        k = np.arange(np.floor(lo / h) + 1, np.ceil(hi / h))
        if len(k) and b[ax] != a[ax]:
            ts.append((k * h - a[ax]) / (b[ax] - a[ax]))
    t = np.sort(np.concatenate(ts)) if ts else np.zeros(0)
    t = t[(t > 1e-9) & (t < 1 - 1e-9)]
    if len(t) > 1:  # a crossing at a lattice point meets both lines: one event
        t = t[np.concatenate([[True], np.diff(t) > 1e-9])]
    return t


def inside_contour(P, C, segments) -> np.ndarray:
    """``(m,) bool``: points ``P (m, 2)`` inside the contour (even-odd rule over ``segments (S, 2)``
    of ``C (c, 2)``)."""
    P = np.asarray(P, float).reshape(-1, 2)
    A, B = C[segments[:, 0]], C[segments[:, 1]]
    px, py = P[:, None, 0], P[:, None, 1]
    straddle = (A[None, :, 1] > py) != (B[None, :, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = A[None, :, 0] + (py - A[None, :, 1]) * (B[None, :, 0] - A[None, :, 0]) / (B[None, :, 1] - A[None, :, 1])
    return ((straddle & (px < xc)).sum(axis=1) % 2) == 1


def _boundary_nodes(C, segments, spacing):
    """Boundary node positions ``(b, 2)``, their segment ``(b,)`` and parameter ``(b,)``."""
    X, seg, par = [], [], []
    for s, (i, k) in enumerate(segments):
        t = dda_crossings(C[i], C[k], spacing)
        X.append(C[i] + t[:, None] * (C[k] - C[i]))
        seg.append(np.full(len(t), s))
        par.append(t)
    return np.vstack(X), np.concatenate(seg), np.concatenate(par)


def _line_edges(X, on_line, order_axis, C, segments) -> list[np.ndarray]:
    """Edges between consecutive nodes of one grid line whose midpoint is inside the contour."""
    idx = np.flatnonzero(on_line)
    if len(idx) < 2:
        return []
    idx = idx[np.argsort(X[idx, order_axis], kind="stable")]
    pairs = np.column_stack([idx[:-1], idx[1:]])
    keep = inside_contour(0.5 * (X[pairs[:, 0]] + X[pairs[:, 1]]), C, segments)
    return [pairs[keep]]


def build_grid(C, segments, spacing) -> DeformationGrid:
    """The deformation grid of the contour ``segments (S, 2)`` over corners ``C (c, 2)`` (texels)
    with line spacing ``(hx, hy)`` texels. Raises ValueError on an empty contour or a spacing below
    one texel."""
    C = np.asarray(C, np.float64).reshape(-1, 2)
    segments = np.asarray(segments, np.int64).reshape(-1, 2)
    spacing = np.asarray(spacing, np.float64)
    if len(segments) < 3:
        raise ValueError(f"a contour needs at least 3 segments, got {len(segments)}")
    if spacing.min() < 1:
        raise ValueError(f"grid spacing {spacing.min():.3g} texels is below one texel")
    Xb, seg_b, par_b = _boundary_nodes(C, segments, spacing)
    lo, hi = C.min(axis=0), C.max(axis=0)
    ii = np.arange(np.ceil(lo[0] / spacing[0]), np.floor(hi[0] / spacing[0]) + 1) * spacing[0]
    jj = np.arange(np.ceil(lo[1] / spacing[1]), np.floor(hi[1] / spacing[1]) + 1) * spacing[1]
    L = np.stack(np.meshgrid(ii, jj), axis=-1).reshape(-1, 2)
    L = L[inside_contour(L, C, segments)]
    if len(L):  # lattice points on (or a hair from) the contour are boundary nodes already
        near = np.min(np.linalg.norm(L[:, None] - np.vstack([C, Xb])[None], axis=2), axis=1) < 1e-6
        L = L[~near]
    X = np.vstack([C, Xb, L])
    c, b = len(C), len(Xb)
    kind = np.concatenate([np.full(c, CORNER), np.full(b, BOUNDARY), np.full(len(L), INTERIOR)])
    segment = np.concatenate([np.full(c, -1), seg_b, np.full(len(L), -1)])
    edges = _contour_edges(segments, seg_b, par_b, c)
    q = X / spacing
    for ax in range(2):
        on = np.abs(q[:, ax] - np.round(q[:, ax])) < 1e-6
        for line in np.unique(np.round(q[on, ax])):
            edges += _line_edges(X, on & (np.round(q[:, ax]) == line), 1 - ax, C, segments)
    E = np.unique(np.sort(np.vstack(edges), axis=1), axis=0)
    E = E[E[:, 0] != E[:, 1]]
    return DeformationGrid(X, kind.astype(np.int64), segment.astype(np.int64), E, _triangulate(X, C, segments),
                           segments, spacing)


def _contour_edges(segments, seg_b, par_b, c) -> list[np.ndarray]:
    """Consecutive nodes along each contour segment (corners then boundary nodes by parameter)."""
    out = []
    for s, (i, k) in enumerate(segments):
        mine = np.flatnonzero(seg_b == s)
        chain = np.concatenate([[i], c + mine[np.argsort(par_b[mine])], [k]])
        out.append(np.column_stack([chain[:-1], chain[1:]]))
    return out


def _triangulate(X, C, segments) -> np.ndarray:
    """Delaunay triangles ``(t, 3)`` of ``X (n, 2)`` whose centroid is inside the contour."""
    tri = Delaunay(X, qhull_options="QJ Pp").simplices.astype(np.int64)
    P = X[tri]
    d1, d2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    keep = (area > 1e-9) & inside_contour(P.mean(axis=1), C, segments)
    return tri[keep]
