"""Geodesic fans (Zelinka and Garland 2004) and the source search structure of section 4.2.

A fan at a face is ``k`` spokes at angles ``2 pi i / k`` from the face's frame axis ``X`` with the
signal at ``m`` equal steps ``r_l = radius (l + 1) / m`` along each: ``(k, m, C)`` values and a
``(k, m) bool`` mask of the samples that exist. Spokes are read off the tangent plane (the first-
order exponential map): the sample at ``c + r (cos a X + sin a Y)`` is the nearest point of a dense
cloud on the surface (the centroid and three inner points of every face), and it is missing when
that point lies farther than one step away (off the region, or not yet covered on the target). On
a surface of curvature radius rho the geodesic length of a spoke is off by ``O(r^3 / rho^2)``.

Matching is orientation independent: a target fan is compared with every source fan under every
cyclic shift ``j`` of its spokes, over the samples present in both (a partial fan compares what it
has), by mean squared difference. :class:`FanIndex` holds all shifted source fans as one matrix
``A (N k, k m C)``, so one partial-fan query is two matrix-vector products; the answer is a source
face and the rotation ``2 pi j / k`` that maps target directions to source directions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from synthkit.methods.surfacing.transfer.surface import Surface

__all__ = ["Cloud", "make_cloud", "fan_points", "FanIndex", "build_index"]

_INNER = np.array([[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


@dataclass
class Cloud:
    """Dense points on a surface: ``points (4 #F, 3)``, their ``faces (4 #F,)`` and ``bary (4 #F, 3)``,
    with a KD-tree."""

    points: np.ndarray
    faces: np.ndarray
    bary: np.ndarray
    tree: cKDTree


def make_cloud(surface: Surface) -> Cloud:
    """Four points per face of ``surface`` (centroid and three inner points)."""
    tri = surface.V[surface.F]
    pts = np.einsum("qk,fkc->fqc", _INNER, tri).reshape(-1, 3)
    faces = np.repeat(np.arange(len(surface.F)), len(_INNER))
    bary = np.tile(_INNER, (len(surface.F), 1))
    return Cloud(pts, faces, bary, cKDTree(pts))


def fan_points(surface: Surface, cloud: Cloud, faces, *, spokes: int, steps: int, radius: float):
    """Cloud indices ``(n, k, m)`` of the fan samples at ``faces (n,)`` and their mask ``(n, k, m)``."""
    faces = np.asarray(faces, np.int64)
    c = surface.centroids[faces]
    a = 2 * np.pi * np.arange(spokes) / spokes
    r = radius * (np.arange(steps) + 1) / steps
    X, Y = surface.X[faces][:, None, :], surface.Y[faces][:, None, :]
    d = np.cos(a)[None, :, None] * X + np.sin(a)[None, :, None] * Y
    P = c[:, None, None, :] + r[None, None, :, None] * d[:, :, None, :]
    dist, idx = cloud.tree.query(P.reshape(-1, 3))
    shape = (len(faces), spokes, steps)
    return idx.reshape(shape), (dist <= radius / steps).reshape(shape)


@dataclass
class FanIndex:
    """Shifted source fans ``A (n k, D) float32`` with ``A2 = A * A``, their source ``faces (n,)``;
    ``spokes``, ``steps``."""

    A: np.ndarray
    A2: np.ndarray
    faces: np.ndarray
    spokes: int
    steps: int

    def distances(self, fan: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Mean squared difference ``(n, k)`` of the target ``fan (k, m, C)`` over ``mask (k, m)``
        with each source fan under each shift."""
        C = fan.shape[2]
        w = np.repeat(mask.astype(np.float32)[..., None], C, axis=2).ravel()
        t = np.nan_to_num(fan.astype(np.float32)).ravel() * w
        d = self.A2 @ w - 2.0 * (self.A @ t) + float(t @ t)
        return np.maximum(d, 0.0).reshape(len(self.faces), self.spokes) / max(float(w.sum()), 1.0)

    def match(self, fan, mask, *, rng, tolerance: float = 0.1, fixed: bool = False) -> tuple[int, float]:
        """Source face and rotation (radians) of a good match of ``fan (k, m, C)``, ``mask (k, m)``:
        uniformly among the (face, shift) pairs within ``(1 + tolerance)`` of the best distance,
        or uniformly at random when the mask is empty. ``fixed``: shift 0 only (frames already
        aligned by an up direction). Randomness enters through ``rng``."""
        if not mask.any():
            return self.random(rng, fixed=fixed)
        d = self.distances(fan, mask)
        if fixed:
            d = np.where(np.arange(self.spokes)[None, :] == 0, d, np.inf)
        d = d.ravel()
        best = float(d.min())
        near = np.flatnonzero(d <= best * (1 + tolerance) + 1e-12)
        pick = int(near[rng.integers(len(near))])
        return int(self.faces[pick // self.spokes]), 2 * np.pi * (pick % self.spokes) / self.spokes

    def random(self, rng, *, fixed: bool = False) -> tuple[int, float]:
        """A uniformly random source face and rotation (``matching: random``; rotation 0 when
        ``fixed``)."""
        face = int(self.faces[rng.integers(len(self.faces))])
        theta = float(rng.uniform(0, 2 * np.pi))
        return face, 0.0 if fixed else theta


def build_index(surface: Surface, cloud: Cloud, values: np.ndarray, *, spokes: int, steps: int,
                radius: float) -> FanIndex:
    """One fan per source face, all shifts stacked. Faces whose fan is complete are the candidates
    (a patch anchored near the region's border would be cut short); when fewer than 16 are complete,
    every face is, with missing samples set to the region's mean signal. ``values (4 #F, C)`` is
    the signal at the cloud's points."""
    idx, mask = fan_points(surface, cloud, np.arange(len(surface.F)), spokes=spokes, steps=steps, radius=radius)
    full = mask.all(axis=(1, 2))
    faces = np.flatnonzero(full) if full.sum() >= 16 else np.arange(len(surface.F))
    fans = values[idx[faces]]
    fans = np.where(mask[faces][..., None], fans, values.mean(axis=0))
    shifted = np.stack([np.roll(fans, -j, axis=1) for j in range(spokes)], axis=1)
    A = np.ascontiguousarray(shifted.reshape(len(faces) * spokes, -1), dtype=np.float32)
    return FanIndex(A, A * A, faces, spokes, steps)
