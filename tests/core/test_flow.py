"""The kept residual graph: cold and warm (capacities changed after a solve) cuts against
enumeration and PyMaxflow."""

import itertools

import numpy as np
import pytest

from synthkit.core.flow import ResidualGraph
from synthkit.core.graphcut import mincut


def cut_value(side, p, q, cap_pq, cap_qp, term):
    """Cut of ``side`` (True = sink side): a sink-side node pays its source link ``max(term, 0)``,
    a source-side node its sink link ``max(-term, 0)``, ``p -> q`` is cut from source to sink."""
    c = float(np.sum(np.where(side, np.maximum(term, 0.0), np.maximum(-term, 0.0))))
    return c + float(np.sum(cap_pq[~side[p] & side[q]]) + np.sum(cap_qp[side[p] & ~side[q]]))


def brute_min(n, p, q, cap_pq, cap_qp, term):
    return min(cut_value(np.array(bits), p, q, cap_pq, cap_qp, term)
               for bits in itertools.product([False, True], repeat=n))


def random_problem(rng, n, m):
    pairs = np.array([(a, b) for a in range(n) for b in range(n) if a < b])
    edges = pairs[rng.choice(len(pairs), size=min(m, len(pairs)), replace=False)]
    return edges[:, 0].copy(), edges[:, 1].copy()


def random_caps(rng, m, n):
    cap_pq = rng.random(m) * 2
    cap_qp = rng.random(m) * 2
    cap_pq[rng.random(m) < 0.3] = 0.0
    term = rng.normal(size=n) * 1.5
    term[rng.random(n) < 0.3] = 0.0
    return cap_pq, cap_qp, term


def pymaxflow_side(n, p, q, cap_pq, cap_qp, term):
    side, _ = mincut(n, np.stack([p, q], axis=1), cap_pq, cap_qp, np.maximum(term, 0.0), np.maximum(-term, 0.0))
    return side


def test_chain_exact():
    # source -3-> 0 -1-> 1 -1-> 2 -> sink 2: the min cut is one unit edge, and of the two, the
    # largest source side puts only node 2 on the sink side.
    g = ResidualGraph.build(3, np.array([0, 1]), np.array([1, 2]))
    g.set_capacities(np.array([1.0, 1.0]), np.array([0.0, 0.0]), np.array([3.0, 0.0, -2.0]))
    assert g.solve().tolist() == [False, False, True]
    # the flow of 1 is kept: node 0 has 2 units of source capacity left, node 2 one to the sink
    assert g.tr.tolist() == [2.0, 0.0, -1.0]
    assert sorted(g.rcap.tolist()) == [0.0, 0.0, 1.0, 1.0]


@pytest.mark.parametrize("seed", range(12))
def test_cold_cut_is_minimal_and_pymaxflows(seed):
    rng = np.random.default_rng(300 + seed)
    n = 8
    p, q = random_problem(rng, n, 14)
    cap_pq, cap_qp, term = random_caps(rng, len(p), n)
    g = ResidualGraph.build(n, p, q)
    g.set_capacities(cap_pq, cap_qp, term)
    side = g.solve(rounds=seed % 3)
    assert cut_value(side, p, q, cap_pq, cap_qp, term) == pytest.approx(brute_min(n, p, q, cap_pq, cap_qp, term),
                                                                       abs=1e-12)
    # the largest source side of all minimum cuts is unique: PyMaxflow's result exactly
    assert side.tolist() == pymaxflow_side(n, p, q, cap_pq, cap_qp, term).tolist()


@pytest.mark.parametrize("seed", range(8))
def test_warm_cuts_after_capacity_changes_equal_cold_ones(seed):
    # Capacities fall below the kept flow, terminal values change sign, edges drop to 0 and come
    # back: every warm cut must be the cold cut of the same capacities.
    rng = np.random.default_rng(700 + seed)
    n = 60
    p, q = random_problem(rng, n, 240)
    g = ResidualGraph.build(n, p, q)
    cap_pq, cap_qp, term = random_caps(rng, len(p), n)
    for step in range(10):
        g.set_capacities(cap_pq, cap_qp, term)
        side = g.solve(rounds=step % 2)
        assert side.tolist() == pymaxflow_side(n, p, q, cap_pq, cap_qp, term).tolist()
        assert (g.rcap >= 0).all()
        change = rng.random(len(p)) < 0.2
        new_pq, new_qp, new_term = random_caps(rng, len(p), n)
        cap_pq = np.where(change, new_pq, cap_pq)
        cap_qp = np.where(change, new_qp, cap_qp)
        term = np.where(rng.random(n) < 0.2, new_term, term)


def test_warm_cut_when_a_saturated_edge_shrinks():
    # source -2-> 0 -2.5-> 1 -3-> sink carries 2 units, cut at the source link. The edge then falls
    # to 0.5: the 1.5 units 0 can no longer send become source capacity of 0 and a demand of 1,
    # and the cut is the edge.
    g = ResidualGraph.build(2, np.array([0]), np.array([1]))
    g.set_capacities(np.array([2.5]), np.array([0.0]), np.array([2.0, -3.0]))
    assert g.solve().tolist() == [True, True]
    assert g.tr.tolist() == [0.0, -1.0]
    g.set_capacities(np.array([0.5]), np.array([0.0]), np.array([2.0, -3.0]))
    assert g.tr.tolist() == [1.5, -2.5]
    assert g.solve().tolist() == [False, True]
    assert g.tr.tolist() == [1.5, -2.5]  # the cut 0.5 is the whole edge: nothing else moved
