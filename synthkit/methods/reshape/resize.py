"""Resize in one line (issue 23): ``scale: {x: 1.3}`` or ``size: {x: 12.0}``.

The user's intent is the model scaled along the given axes, as if a wall were dragged: the rest
shape of the solve becomes ``R (n, 3)``, the model scaled about its lower corner, except that a
part (face-connected component, :func:`parts.mesh_parts`) shorter than ``rigid_share`` of the
model along an axis keeps its size along that axis (doors, windows, frames, chimneys) and is
carried there by the point of its host surface under its centroid (:func:`parts.attach_clusters`:
a window on a side wall stays on that wall). The largest part (the walls and roof) is never
rigid. The solve (pipeline) then writes every constraint of section 3.2 against ``R`` but keeps
the rest lengths of the model's rigid edges (shorter than ``l_min``): a thin slab or a wall's
thickness does not take the raise, and the stretch spreads over the long edges.

Handles and fixed vertices are the nodes within ``end_tol`` of the extent of either end of each
scaled axis, moved to their place in ``R``. The factors are corrected once so that the extent of
``R`` is the one asked even when a rigid part (a barrel beside the house) forms an end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.methods.reshape.parts import attach_clusters, mesh_parts

__all__ = ["Resize", "axis_factors", "plan_resize"]


@dataclass
class Resize:
    """A resolved resize: ``factors (3,)`` actually applied, the asked extents ``asked (3,)``
    (NaN where not asked), rest shape ``R (n, 3)``, ``known (k,)`` end nodes, ``part (n,)``
    labels and ``rigid (p, 3)`` (part keeps its size along the axis)."""

    factors: np.ndarray
    asked: np.ndarray
    R: np.ndarray
    known: np.ndarray
    part: np.ndarray
    rigid: np.ndarray


def axis_factors(scale, size, extent) -> tuple[np.ndarray, np.ndarray]:
    """Factors ``(3,)`` (1 where not asked) and asked extents ``(3,)`` (NaN where not asked) from a
    config's ``scale`` or ``size`` (AxisValues) and the model's ``extent (3,)``. Raises ValueError
    for a size along an axis where the model is flat."""
    f, asked = np.ones(3), np.full(3, np.nan)
    given = (scale or size).values()
    for a, v in enumerate(given):
        if v is None:
            continue
        key = f"{'scale' if scale else 'size'}.{'xyz'[a]}"
        if extent[a] <= 0:
            raise ValueError(f"{key}: the model is flat along {'xyz'[a]} (extent 0); it cannot be resized there")
        f[a] = v if scale else v / extent[a]
        asked[a] = f[a] * extent[a]
    return f, asked


def _rest(X0, Fn, part, rigid, f, lo) -> np.ndarray:
    """Rest shape ``(n, 3)``: scaled about ``lo``, rigid axes of parts translated with their host."""
    R = lo + f * (X0 - lo)
    root = part == int(np.argmax(np.bincount(part[part >= 0])))
    pairs = np.vstack([Fn[:, [0, 1]], Fn[:, [1, 2]]])
    att = attach_clusters(X0, Fn, pairs, np.flatnonzero(root))
    for nodes, t, lam in zip(att.nodes, att.tri, att.bary, strict=True):
        move = lam @ R[Fn[t]] - lam @ X0[Fn[t]]
        axes = rigid[part[nodes[0]]]
        R[np.ix_(nodes, np.flatnonzero(axes))] = X0[np.ix_(nodes, np.flatnonzero(axes))] + move[axes]
    return R


def plan_resize(X0, Fn, factors, asked, *, rigid_share: float, end_tol: float) -> Resize:
    """The :class:`Resize` of nodes ``X0 (n, 3)`` with triangles ``Fn (F, 3)`` for ``factors (3,)``
    and ``asked (3,)`` extents (:func:`axis_factors`)."""
    n = len(X0)
    part = mesh_parts(Fn, n)
    used = part >= 0
    lo, hi = X0[used].min(axis=0), X0[used].max(axis=0)
    extent = hi - lo
    n_parts = int(part.max()) + 1
    plo = np.full((n_parts, 3), np.inf)
    phi = np.full((n_parts, 3), -np.inf)
    np.minimum.at(plo, part[used], X0[used])
    np.maximum.at(phi, part[used], X0[used])
    rigid = (phi - plo) < rigid_share * extent
    rigid[int(np.argmax(np.bincount(part[used])))] = False
    f = factors.astype(np.float64).copy()
    for _ in range(2):
        R = _rest(X0, Fn, part, rigid, f, lo)
        got = R[used].max(axis=0) - R[used].min(axis=0)
        fix = np.isfinite(asked) & (f != 1) & (np.abs(got - asked) > 1e-12 * extent)
        slope = (got[fix] - extent[fix]) / (f[fix] - 1)
        f[fix] = 1 + (asked[fix] - extent[fix]) / slope
    R = _rest(X0, Fn, part, rigid, f, lo)
    scaled = np.flatnonzero(np.isfinite(asked))
    tol = end_tol * extent
    ends = (X0[:, scaled] <= (lo + tol)[scaled]) | (X0[:, scaled] >= (hi - tol)[scaled])
    known = np.flatnonzero(used & ends.any(axis=1))
    return Resize(f, asked, R, known, part, rigid)
