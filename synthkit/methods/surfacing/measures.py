"""Segmentation scores of the Princeton Segmentation Benchmark (Chen, Golovinskiy, Funkhouser 2009).

Two face labellings ``a (#F,)`` and ``b (#F,)`` of one mesh are compared through their
contingency table, every face counting once (not by area):

- Rand Index error ``1 - RI``: the share of face pairs grouped differently;
- Hamming distance: ``Rm`` and ``Rf``, the directional Hamming distances b => a and a => b over
  #F, and their mean;
- consistency errors ``GCE`` and ``LCE`` (local refinement error, global and per face);
- cut discrepancy: mean geodesic (edge-graph) distance from the cut vertices of one to the cut of
  the other, both ways, averaged and divided by the mean distance of the vertices to their centroid.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from synthkit.core.mesh import face_adjacency, vertex_graph_edges

__all__ = ["contingency", "rand_index_error", "hamming", "consistency_errors", "cut_discrepancy", "scores"]


def contingency(a, b) -> np.ndarray:
    """Counts ``(|A|, |B|)`` of faces with label pair (i, j), labels renumbered densely."""
    _, ai = np.unique(np.asarray(a), return_inverse=True)
    _, bi = np.unique(np.asarray(b), return_inverse=True)
    table = np.zeros((ai.max() + 1, bi.max() + 1))
    np.add.at(table, (ai, bi), 1.0)
    return table


def _pairs(x):
    return x * (x - 1) / 2.0


def rand_index_error(a, b) -> float:
    """``1 - RI`` from the contingency table (0 for identical partitions)."""
    t = contingency(a, b)
    n = t.sum()
    total = _pairs(n)
    if total == 0:
        return 0.0
    agree = total - _pairs(t.sum(axis=1)).sum() - _pairs(t.sum(axis=0)).sum() + 2 * _pairs(t).sum()
    return float(1.0 - agree / total)


def hamming(a, b) -> tuple[float, float, float]:
    """``(Hamming, Rm, Rf)``: Rm = D_H(b => a) / #F, Rf = D_H(a => b) / #F, Hamming their mean
    (a the computed labelling, b the reference)."""
    t = contingency(a, b)
    n = t.sum()
    rm = (t.sum() - t.max(axis=0).sum()) / n
    rf = (t.sum() - t.max(axis=1).sum()) / n
    return float((rm + rf) / 2), float(rm), float(rf)


def consistency_errors(a, b) -> tuple[float, float]:
    """``(GCE, LCE)`` of two labellings."""
    _, ai = np.unique(np.asarray(a), return_inverse=True)
    _, bi = np.unique(np.asarray(b), return_inverse=True)
    t = contingency(ai, bi)
    nij = t[ai, bi]
    e1 = (t.sum(axis=1)[ai] - nij) / t.sum(axis=1)[ai]
    e2 = (t.sum(axis=0)[bi] - nij) / t.sum(axis=0)[bi]
    n = len(ai)
    return float(min(e1.sum(), e2.sum()) / n), float(np.minimum(e1, e2).sum() / n)


def _cut_vertices(F, labels) -> np.ndarray:
    pairs, edges = face_adjacency(F)
    cut = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    return np.unique(edges[cut])


def cut_discrepancy(V, F, a, b) -> float:
    """Symmetric cut discrepancy over the mean radius; NaN when either labelling has no cut."""
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    ca, cb = _cut_vertices(F, np.asarray(a)), _cut_vertices(F, np.asarray(b))
    if not len(ca) or not len(cb):
        return float("nan")
    E = vertex_graph_edges(F)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1) + 1e-12
    G = sp.csr_matrix((w, (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    da = dijkstra(G, directed=False, indices=ca, min_only=True)
    db = dijkstra(G, directed=False, indices=cb, min_only=True)
    used = np.unique(F)
    radius = np.linalg.norm(V[used] - V[used].mean(axis=0), axis=1).mean()
    finite = np.isfinite(db[ca]).all() and np.isfinite(da[cb]).all()
    if not finite:
        return float("nan")
    return float((db[ca].mean() + da[cb].mean()) / 2 / radius)


def scores(V, F, a, b) -> dict[str, float]:
    """All four measures of labelling ``a`` against reference ``b``."""
    h, rm, rf = hamming(a, b)
    gce, lce = consistency_errors(a, b)
    return {"rand_index_error": rand_index_error(a, b), "cut_discrepancy": cut_discrepancy(V, F, a, b),
            "hamming": h, "hamming_rm": rm, "hamming_rf": rf, "gce": gce, "lce": lce}
