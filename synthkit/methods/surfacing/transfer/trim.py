"""Seam costs and patch trimming (section 4.4) on the dual graph of the target faces.

A seam between two faces with different patches costs the integral of the signal difference along
their shared edge, each side mapped through its own patch: the edge's two end points have domain
coordinates in each patch, the straight domain segment between them is the patch's image of the
edge (a piecewise-linear curve on the source), and both curves are sampled at the same ``ns``
arclength fractions ``(i + 1/2) / ns``: ``cost = length * mean_i |phi_A(t_i) - phi_B(t_i)|``
(Euclidean norm over the signal's channels), so longer edges weigh more.

The cut (:func:`trim_cut`): terminals T_E (source side, keep the existing patch) and T_P (sink
side, take the proposed one); only faces of the proposed patch are nodes, every other face is tied
to T_E by an infinite link and enters as terminal costs of its neighbours. Uncovered faces and the
chosen face get infinite links to T_P. An edge between two faces of one existing patch costs the
seam P would make there; an edge on an old seam (patches A1 != A2) gets a seam node ``n`` (Kwatra
et al. 2003): ``f - n`` costs ``M(A1, P)``, ``n - g`` costs ``M(A2, P)`` and ``n - T_P`` costs the
old seam ``M(A1, A2)``, so the old seam can be kept, replaced or removed at its true price.
"""

from __future__ import annotations

import numpy as np

from synthkit.core.graphcut import mincut

__all__ = ["seam_costs", "trim_cut"]


def seam_costs(Sa: np.ndarray, Sb: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``(E,)`` seam cost of signal samples ``Sa``, ``Sb`` ``(E, ns, C)`` along edges of ``lengths (E,)``."""
    return lengths * np.linalg.norm(Sa - Sb, axis=2).mean(axis=1)


def trim_cut(n: int, forced, keep_cost, take_cost, edges, cost_a, cost_b, old, seam) -> tuple[np.ndarray, float]:
    """Min cut over ``n`` proposed faces: ``take (n,) bool`` (True: the face takes the new patch)
    and the cut's cost.

    ``forced (n,) bool`` must take it; ``keep_cost``/``take_cost (n,)`` are terminal costs of
    keeping/taking; ``edges (E, 2)`` between faces ``(f, g)`` cost ``cost_a (E,)`` = M(E_f, P) and
    ``cost_b (E,)`` = M(P, E_g); where ``seam (E,) bool`` the edge lies on an old seam of cost
    ``old (E,)`` and gets a seam node, elsewhere it is one undirected edge of cost ``cost_a``."""
    edges = np.asarray(edges, np.int64).reshape(-1, 2)
    seam = np.asarray(seam, bool)
    k = int(seam.sum())
    plain = ~seam
    nodes = np.arange(n, n + k)
    se = edges[seam]
    E = np.concatenate([edges[plain], np.stack([se[:, 0], nodes], 1), np.stack([nodes, se[:, 1]], 1)])
    cap = np.concatenate([cost_a[plain], cost_a[seam], cost_b[seam]])
    source = np.concatenate([np.asarray(take_cost, np.float64), np.zeros(k)])
    sink = np.concatenate([np.where(forced, np.inf, keep_cost), old[seam]])
    side, flow = mincut(n + k, E, cap, cap, source, sink)
    return np.asarray(side[:n], bool), float(flow)
