"""Straighter boundary curves: the cut's polylines smoothed over the surface (section 5).

The segmentation cuts along mesh edges, so no triangle is partly covered and the boundary follows
the triangulation's zig-zags. The paper notes that "it would be straightforward to smooth the cut
in a post-process to produce straighter boundary curves"; this is that post-process, for the
exported curves only (the face labels, and so every region mesh, stay as cut):

- Taubin's lambda/mu smoothing (lambda 0.5, mu -0.53) of each chain's points, which straightens a
  polyline without shrinking a closed loop as plain Laplacian smoothing does;
- chain ends and junctions (cut vertices of degree other than 2) stay where they are; a closed loop
  (first point repeated last) is smoothed all round;
- after every step each point is projected to the closest point of the faces around the cut (the
  faces within ``band_rings`` rings of a cut vertex), so the curve stays on the surface and cannot
  jump to a nearby sheet of the mesh.
"""

from __future__ import annotations

import numpy as np
import trimesh

__all__ = ["smooth_chains", "polyline_length", "TAUBIN_LAMBDA", "TAUBIN_MU"]

TAUBIN_LAMBDA = 0.5
TAUBIN_MU = -0.53
"""Taubin's pass-band pair (k_PB = 1 / lambda + 1 / mu ~ 0.11): straightens without shrinkage."""


def polyline_length(points: np.ndarray) -> float:
    """Length of a polyline ``points (m, 3)``."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def smooth_chains(V, F, chains: list[np.ndarray], iterations: int, *, band_rings: int = 2) -> list[np.ndarray]:
    """Smoothed copies ``(m_i, 3)`` of the cut's ``chains`` (vertex index arrays of ``V (#V, 3)``,
    :func:`synthkit.methods.surfacing.segment.chain_edges`) after ``iterations`` lambda/mu steps,
    each followed by a projection onto the faces of ``F (#F, 3)`` near the cut."""
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    if iterations < 0:
        raise ValueError(f"iterations must be >= 0, got {iterations}")
    points = [V[c].copy() for c in chains]
    if iterations == 0 or not chains:
        return points
    surface = _surface_near(V, F, np.unique(np.concatenate(chains)), band_rings)
    moving = _moving_points(chains)
    for _ in range(iterations):
        for factor in (TAUBIN_LAMBDA, TAUBIN_MU):
            points = [_step(p, m, factor, _closed(c)) for p, m, c in zip(points, moving, chains, strict=True)]
        flat = np.concatenate(points)
        flat = surface.nearest.on_surface(flat)[0]
        points = np.split(flat, np.cumsum([len(p) for p in points])[:-1])
        points = [_pin(p, m, V[c]) for p, m, c in zip(points, moving, chains, strict=True)]
    return points


def _closed(chain: np.ndarray) -> bool:
    return len(chain) > 2 and chain[0] == chain[-1]


def _moving_points(chains: list[np.ndarray]) -> list[np.ndarray]:
    """Per chain, ``(m,) bool``: the points that may move (not an end, not a junction)."""
    ends = np.concatenate([c[[0, -1]] for c in chains if not _closed(c)] or [np.zeros(0, np.int64)])
    degree = np.bincount(np.concatenate([np.concatenate([c[:-1], c[1:]]) for c in chains]))
    out = []
    for c in chains:
        m = (degree[c] == 2) & ~np.isin(c, ends)
        if not _closed(c):
            m[[0, -1]] = False
        else:
            m[-1] = m[0]
        out.append(m)
    return out


def _step(p: np.ndarray, moving: np.ndarray, factor: float, closed: bool) -> np.ndarray:
    """One umbrella step ``p += factor (mean of the two neighbours - p)`` on the moving points."""
    if len(p) < 3:
        return p
    if closed:
        ring = p[:-1]
        target = 0.5 * (np.roll(ring, 1, axis=0) + np.roll(ring, -1, axis=0))
        new = ring + factor * (target - ring) * moving[:-1, None]
        return np.vstack([new, new[:1]])
    target = p.copy()
    target[1:-1] = 0.5 * (p[:-2] + p[2:])
    return p + factor * (target - p) * moving[:, None]


def _pin(p: np.ndarray, moving: np.ndarray, original: np.ndarray) -> np.ndarray:
    """Fixed points back exactly at their vertices (the projection moves them by rounding)."""
    return np.where(moving[:, None], p, original)


def _surface_near(V: np.ndarray, F: np.ndarray, vertices: np.ndarray, rings: int) -> trimesh.Trimesh:
    """The faces within ``rings`` rings of ``vertices`` as a mesh (for closest-point queries)."""
    near = np.zeros(len(V), bool)
    near[vertices] = True
    for _ in range(rings):
        touching = near[F].any(axis=1)
        near[F[touching].ravel()] = True
    faces = F[near[F].any(axis=1)]
    return trimesh.Trimesh(V, faces, process=False)
