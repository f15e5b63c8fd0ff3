"""Resize in one line: ``scale: {x: 1.3}`` or ``size: {x: 12.0}``.

The user's intent is the model scaled along the given axes, as if a wall were dragged: the rest
shape of the solve becomes ``R (n, 3)``, the model scaled about its lower corner, except that a
part (face-connected component, :func:`parts.mesh_parts`) shorter than ``rigid_share`` of the
model along an axis keeps its size along that axis (doors, windows, frames) and is carried
there by the point of its host surface under its centroid (:func:`parts.attach_clusters`:
a window on a side wall stays on that wall). The largest part (the walls and roof) is never
rigid, nor is a part along an axis where it forms the model's upper end (a chimney topping the
ridge; docs/findings/reshape.md). Parts that touch one
another move as one group (:func:`touching_groups`); the root's nodes around a rigid group (the
rim of the hole a window fills) move with it, and a group at the lower end (a door on the
ground) stays there. The solve (pipeline) then writes every constraint of section 3.2 against
``R`` but keeps the rest lengths of the model's rigid edges (shorter than ``l_min``): a thin
slab or a wall's thickness does not take the raise, and the stretch spreads over the long edges.
Beyond the paper, which only drags handles.

Handles and fixed vertices are the nodes within ``end_tol`` of the extent of either end of each
scaled axis, moved to their place in ``R``. The factors are corrected once so that the extent of
``R`` is the one asked even when a rigid part (a barrel beside the house) forms an end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from synthkit.methods.reshape.parts import attach_clusters, closest_points, mesh_parts

__all__ = ["Resize", "axis_factors", "plan_resize", "touching_groups", "resize_metrics"]


END_BAND = 0.02
"""A rigid group this close to the lower end of the model (share of the extent) stays at that end (a
garage door a little above the lowest vertex)."""


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

    def node_factors(self) -> np.ndarray:
        """Scale ``(n, 3)`` of the rest shape at each node: the factors, 1 along a rigid axis."""
        rigid = self.rigid[np.maximum(self.part, 0)] & (self.part >= 0)[:, None]
        return np.where(rigid, 1.0, self.factors)


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


def touching_groups(X0, Fn, part, *, tol: float) -> np.ndarray:
    """Group label ``(n,)``: parts other than the root (the part with most nodes) that touch one
    another (a node within ``tol`` of the other's triangles: the four panes of a bay window) form
    one group, which moves as one; the root is a group of its own; -1 stays -1."""
    n_parts = int(part.max()) + 1
    root = int(np.argmax(np.bincount(part[part >= 0])))
    face_part = part[Fn[:, 0]]
    pairs = []
    for k in range(n_parts):
        other = (face_part != k) & (face_part != root)
        if k == root or not other.any():
            continue
        d, t, _ = closest_points(X0[part == k], X0[Fn[other]])
        touched = np.unique(face_part[other][t[d <= tol]])
        pairs += [(k, int(j)) for j in touched]
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n_parts, n_parts))
    _, label = connected_components(G, directed=False)
    return np.where(part >= 0, label[np.maximum(part, 0)], -1)


def _rest(X0, Fn, part, rigid, f, lo, margin: float) -> np.ndarray:
    """Rest shape ``(n, 3)``: scaled about ``lo``, rigid axes of groups translated with their host;
    the root's nodes inside a rigid group's box grown by ``margin`` (the rim of the hole a window
    fills) move with the group, so the hole keeps the window's size. A group within ``END_BAND`` of
    the extent from the lower end of the model along an axis (a door or garage door on the ground)
    keeps its place there; at the upper end a group (a chimney) rides on its host like any other."""
    R = lo + f * (X0 - lo)
    root = part == int(np.argmax(np.bincount(part[part >= 0])))
    used = np.flatnonzero(part >= 0)
    _, lead = np.unique(part[used], return_index=True)
    tie = np.column_stack([used, used[lead][part[used]]])
    pairs = np.vstack([Fn[:, [0, 1]], Fn[:, [1, 2]], tie])
    att = attach_clusters(X0, Fn, pairs, np.flatnonzero(root))
    for nodes, t, lam in zip(att.nodes, att.tri, att.bary, strict=True):
        move = lam @ R[Fn[t]] - lam @ X0[Fn[t]]
        axes = np.flatnonzero(rigid[part[nodes[0]]])
        lo_g, hi_g = X0[nodes].min(axis=0) - margin, X0[nodes].max(axis=0) + margin
        band = END_BAND * (X0[part >= 0].max(axis=0) - lo)
        g_lo = X0[nodes].min(axis=0)
        move = np.where(g_lo <= lo + band, 0.0, move)
        rim = np.flatnonzero(root & np.all((X0 >= lo_g) & (X0 <= hi_g), axis=1))
        moved = np.concatenate([nodes, rim])
        R[np.ix_(moved, axes)] = X0[np.ix_(moved, axes)] + move[axes]
    return R


def plan_resize(X0, Fn, factors, asked, *, rigid_share: float, end_tol: float, touch_tol: float = 1e-4,
                rim_margin: float = 2e-3) -> Resize:
    """The :class:`Resize` of nodes ``X0 (n, 3)`` with triangles ``Fn (F, 3)`` for ``factors (3,)``
    and ``asked (3,)`` extents (:func:`axis_factors`); parts within ``touch_tol`` (share of the
    model size) of each other move as one group (:func:`touching_groups`); ``rim_margin`` (share of
    the model size) grows a rigid group's box to find the rim of its hole."""
    n = len(X0)
    used = np.zeros(n, bool)
    used[Fn.reshape(-1)] = True
    lo, hi = X0[used].min(axis=0), X0[used].max(axis=0)
    extent = hi - lo
    size = float(np.linalg.norm(extent))
    part = touching_groups(X0, Fn, mesh_parts(Fn, n), tol=touch_tol * size)
    n_parts = int(part.max()) + 1
    plo = np.full((n_parts, 3), np.inf)
    phi = np.full((n_parts, 3), -np.inf)
    np.minimum.at(plo, part[used], X0[used])
    np.maximum.at(phi, part[used], X0[used])
    rigid = ((phi - plo) < rigid_share * extent) & (phi < hi - end_tol * extent)
    rigid[int(np.argmax(np.bincount(part[used])))] = False
    f = factors.astype(np.float64).copy()
    for _ in range(2):
        R = _rest(X0, Fn, part, rigid, f, lo, rim_margin * size)
        got = R[used].max(axis=0) - R[used].min(axis=0)
        fix = np.isfinite(asked) & (f != 1) & (np.abs(got - asked) > 1e-12 * extent)
        slope = (got[fix] - extent[fix]) / (f[fix] - 1)
        f[fix] = 1 + (asked[fix] - extent[fix]) / slope
    R = _rest(X0, Fn, part, rigid, f, lo, rim_margin * size)
    scaled = np.flatnonzero(np.isfinite(asked))
    tol = end_tol * extent
    ends = (X0[:, scaled] <= (lo + tol)[scaled]) | (X0[:, scaled] >= (hi - tol)[scaled])
    known = np.flatnonzero(used & ends.any(axis=1))
    return Resize(f, asked, R, known, part, rigid)


def resize_metrics(resize: Resize, X0: np.ndarray, Fn: np.ndarray, X: np.ndarray) -> dict:
    """Factors applied, extent ratios reached (``X (n, 3)`` against ``X0 (n, 3)``, per axis, over
    the nodes triangles ``Fn`` use) and rigid parts of a resize."""
    used = np.unique(Fn)
    before = X0[used].max(axis=0) - X0[used].min(axis=0)
    after = X[used].max(axis=0) - X[used].min(axis=0)
    return {"resize": {"factors": resize.factors.tolist(), "asked_extent": [None if np.isnan(a) else float(a)
                                                                          for a in resize.asked],
                       "extent_ratio": (after / np.maximum(before, 1e-300)).tolist(),
                       "parts": int(resize.part.max()) + 1, "rigid_parts": resize.rigid.any(axis=1).sum().item()}}
