"""Region costs (section 3.4): per-node, per-region terminal weights ``(n, L)``.

Both models turn a per-region distance ``d (n, L)`` into the Lazy Snapping form
``E(p, l) = d_l / (d_l + min_{k != l} d_k)`` (0 at the region's own evidence, 1/2 where two regions
are equally likely, 1 far away), scaled by ``weight`` and the node's normalised area:

- ``geodesic``: d_l is the shortest-path length over the graph to region l's fixed nodes, an
  edge costing the Euclidean distance between its node points plus, where the mesh edge it
  crosses is concave, ``concavity * d_mean * (1 - cos(bend))`` (the angular distance of Katz and
  Tal 2003), so that distances grow across concave creases; a region absent from a node's
  connected component is infinitely far.
- ``color``: d_l is the distance of the node's colour to the nearest of the k-means centres of
  region l's fixed nodes' colours (Li et al. 2004, K = 64).

The geodesic term is trusted only where the strokes decide (:func:`trust_weights`): at a node whose
nearest region's strokes are not clearly nearer than the next region's, it fades to zero and the
boundary term alone places the cut.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

__all__ = ["normalised_cost", "geodesic_distances", "color_distances", "trust_weights", "walled_off"]


def normalised_cost(d) -> np.ndarray:
    """``d_l / (d_l + min_{k != l} d_k)`` of ``d (n, L)`` (infinite distances allowed; 0/0 -> 1/2)."""
    d = np.asarray(d, dtype=np.float64)
    order = np.partition(d, 1, axis=1) if d.shape[1] > 2 else np.sort(d, axis=1)
    other = np.where(d == order[:, :1], order[:, 1:2], order[:, :1])
    with np.errstate(invalid="ignore", divide="ignore"):
        out = d / (d + other)
    out = np.where(np.isinf(d) & np.isinf(other), 0.5, out)
    out = np.where(np.isinf(d) & np.isfinite(other), 1.0, out)
    out = np.where(np.isfinite(d) & np.isinf(other), 0.0, out)
    return np.where((d == 0) & (other == 0), 0.5, out)


def trust_weights(d, trust: float) -> np.ndarray:
    """Per-node weight ``(n,)`` in [0, 1] of the region term from the distances ``d (n, L)``: with
    ``rho = d_2 / d_1`` (the second nearest region's distance over the nearest's), 0 where
    ``rho <= trust``, 1 where ``rho >= 1.5 trust``, linear between; ``trust = 0`` gives 1 everywhere.

    Why: the Lazy Snapping cost pulls every cut towards the geodesic Voronoi boundary of the
    strokes. Where a region's strokes are a dab, the boundary term alone would wrap the cut tightly
    around it (the shrinking bias), and the nodes there are clearly nearer to that dab than to any
    other stroke, so the region term holds them. Where the strokes cover their regions (strokes
    along each part's body), the true boundary lies in the band where two regions' strokes are about
    equally near, and there the Voronoi pull only drags the cut off the crease or neck the boundary
    term would follow. So the weight falls, node by node, with how ambiguous the strokes leave it:
    the better the strokes cover their regions, the wider the band left to the boundary term. A
    crease crossed on the way to a region multiplies its distance (the concavity), so a node beyond a
    strong crease is clearly nearer to the strokes on its own side and the region term keeps the
    other side's regions from leaking over it.
    """
    d = np.asarray(d, dtype=np.float64)
    if trust <= 0 or d.shape[1] < 2:
        return np.ones(len(d))
    two = np.sort(d, axis=1)[:, :2]
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(two[:, 0] > 0, two[:, 1] / two[:, 0], np.inf)
    rho = np.where(np.isinf(two[:, 0]), 1.0, rho)  # no stroke reachable: no evidence
    return np.clip((rho - trust) / (0.5 * trust), 0.0, 1.0)


def walled_off(n: int, edges, walls, seeds, n_labels: int) -> np.ndarray:
    """``(n, L) bool``: the labels each node may not take. ``walls (E,) bool`` marks the edges across
    strong concave creases; a part the walls close off (a connected component of the graph without
    them) that holds strokes takes only the regions stroked in it, so no region crosses a strong
    crease to swallow a part whose strokes it does not touch. A part without strokes is free."""
    e = np.asarray(edges)[~np.asarray(walls, bool)]
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    n_parts, part = connected_components(A, directed=False)
    held = np.zeros((n_parts, n_labels), bool)
    s = seeds >= 0
    held[part[s], seeds[s]] = True
    return held.any(axis=1)[part][:, None] & ~held[part]


def geodesic_distances(points, edges, seeds, n_labels: int, *, extra=None) -> np.ndarray:
    """Shortest-path distance ``(n, L)`` from every node to each region's fixed nodes; ``extra (E,)``
    lengthens the edges (the concavity penalty)."""
    n = len(points)
    w = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1) + 1e-12
    if extra is not None:
        w = w + extra
    G = sp.csr_matrix((w, (edges[:, 0], edges[:, 1])), shape=(n, n))
    out = np.full((n, n_labels), np.inf)
    for label in range(n_labels):
        src = np.flatnonzero(seeds == label)
        if len(src):
            out[:, label] = dijkstra(G, directed=False, indices=src, min_only=True)
    return out


def color_distances(colors, seeds, n_labels: int, *, clusters: int, rng) -> np.ndarray:
    """Distance ``(n, L)`` of ``colors (n, C)`` to the nearest k-means centre of each region's
    fixed-node colours. Randomness enters through the k-means initialisation (``rng``)."""
    colors = np.asarray(colors, dtype=np.float64)
    out = np.full((len(colors), n_labels), np.inf)
    for label in range(n_labels):
        sample = colors[seeds == label]
        if not len(sample):
            continue
        k = min(clusters, len(np.unique(sample, axis=0)))
        centres = kmeans2(sample, k, minit="++", seed=rng)[0] if k > 1 else sample[:1]
        out[:, label] = cKDTree(centres).query(colors)[0]
    return out
