"""Graph cuts against exhaustive search on problems small enough to enumerate."""

import itertools

import numpy as np
import pytest

from synthkit.core import graphcut
from synthkit.core.graphcut import (
    INF,
    ExpansionResult,
    alpha_expansion,
    energy,
    grid_mincut,
    mincut,
)

# --------------------------------------------------------------------------------------------------
# references written independently of the module: plain loops over every configuration


def ref_energy(labels, unary, edges, V):
    """V(e, a, b) -> float; python loops."""
    total = 0.0
    for p, lp in enumerate(labels):
        total += unary[p][lp]
    for k, (p, q) in enumerate(edges):
        total += V(k, labels[p], labels[q])
    return total


def all_labelings(n, n_labels):
    return np.array(list(itertools.product(range(n_labels), repeat=n)), dtype=np.int64)


def brute_optimum(unary, edges, V):
    n, n_labels = np.asarray(unary).shape
    return min(ref_energy(lab, unary, edges, V) for lab in all_labelings(n, n_labels))


def best_expansion_move(labels, alpha, unary, edges, V):
    """Lowest energy over every labeling reachable from ``labels`` by one alpha-expansion."""
    n = len(labels)
    best = np.inf
    for switch in itertools.product([False, True], repeat=n):
        lab = np.where(switch, alpha, labels)
        best = min(best, ref_energy(lab, unary, edges, V))
    return best


def brute_cut(n, edges, cap, rev, source, sink):
    best, best_side = np.inf, None
    for bits in itertools.product([False, True], repeat=n):
        side = np.array(bits)
        c = sum(source[p] for p in range(n) if side[p]) + sum(sink[p] for p in range(n) if not side[p])
        for (p, q), a, b in zip(edges, cap, rev, strict=True):
            if not side[p] and side[q]:
                c += a
            if side[p] and not side[q]:
                c += b
        if c < best:
            best, best_side = c, side
    return best, best_side


def cut_value(side, edges, cap, rev, source, sink):
    c = float(np.sum(np.where(side, source, sink)))
    p, q = edges[:, 0], edges[:, 1]
    c += float(np.sum(cap[~side[p] & side[q]]) + np.sum(rev[side[p] & ~side[q]]))
    return c


def random_graph(rng, n, m):
    pairs = [(p, q) for p in range(n) for q in range(n) if p < q]
    idx = rng.choice(len(pairs), size=min(m, len(pairs)), replace=False)
    return np.array([pairs[i] for i in idx], dtype=np.int64)


def metric_table(rng, n_labels, dim=2):
    """Euclidean distances between random label embeddings: a metric with V(a, a) = 0."""
    x = rng.normal(size=(n_labels, dim))
    return np.linalg.norm(x[:, None] - x[None], axis=-1)


def metric_ratio(table):
    off = table[~np.eye(table.shape[-1], dtype=bool)]
    return off.max() / off.min()


def table_fn(table):
    if table.ndim == 2:
        return lambda k, a, b: table[a, b]
    return lambda k, a, b: table[k, a, b]


# --------------------------------------------------------------------------------------------------
# binary min-cut


@pytest.mark.parametrize("seed", range(6))
def test_mincut_matches_enumeration_of_all_cuts(seed):
    rng = np.random.default_rng(seed)
    n = 7
    edges = random_graph(rng, n, 12)
    cap = rng.integers(0, 5, len(edges)).astype(float)
    rev = rng.integers(0, 5, len(edges)).astype(float)
    source = rng.integers(0, 6, n).astype(float)
    sink = rng.integers(0, 6, n).astype(float)
    side, flow = mincut(n, edges, cap, rev, source, sink)
    best, _ = brute_cut(n, edges, cap, rev, source, sink)
    assert side.dtype == bool and side.shape == (n,)
    assert flow == pytest.approx(best, abs=1e-9)
    assert cut_value(side, edges, cap, rev, source, sink) == pytest.approx(best, abs=1e-9)


def test_mincut_exact_chain():
    # s -> 0 -> 1 -> 2 -> t with capacities 5, 2, 3, 4: the bottleneck 0 -> 1 is cut.
    edges = np.array([[0, 1], [1, 2]])
    side, flow = mincut(3, edges, [2.0, 3.0], [0.0, 0.0], [5.0, 0, 0], [0, 0, 4.0])
    assert flow == 2.0
    assert side.tolist() == [False, True, True]


def test_mincut_infinite_seeds_and_infinite_flow():
    edges = np.array([[0, 1], [1, 2]])
    side, flow = mincut(3, edges, [1.5, 3.0], [1.5, 3.0], [np.inf, 0, 0], [0, 0, INF])
    assert flow == pytest.approx(1.5)
    assert side.tolist() == [False, True, True]
    _, flow = mincut(3, edges, [np.inf, np.inf], [0, 0], [np.inf, 0, 0], [0, 0, np.inf])
    assert flow == np.inf


def test_mincut_without_edges():
    side, flow = mincut(2, np.zeros((0, 2), dtype=int), [], [], [1.0, 3.0], [2.0, 1.0])
    assert flow == 2.0
    assert side.tolist() == [True, False]  # node 0 pays source 1 on the sink side, node 1 sink 1


@pytest.mark.parametrize(
    "args, match",
    [
        ((3, [[0, 1]], [-1.0], [0.0], [0, 0, 0], [0, 0, 0]), "cap must be non-negative"),
        ((3, [[0, 1]], [1.0], [0.0], [0, -2.0, 0], [0, 0, 0]), "source must be non-negative"),
        ((3, [[0, 1]], [1.0], [0.0], [0, 0], [0, 0, 0]), r"source must have shape \(3,\)"),
        ((3, [[0, 1]], [1.0, 2.0], [0.0], [0, 0, 0], [0, 0, 0]), r"cap must have shape \(1,\)"),
        ((3, [[0, 3]], [1.0], [0.0], [0, 0, 0], [0, 0, 0]), "out of range"),
        ((3, [[1, 1]], [1.0], [0.0], [0, 0, 0], [0, 0, 0]), "self-loop"),
        ((3, [[0, 1, 2]], [1.0], [0.0], [0, 0, 0], [0, 0, 0]), r"shape \(E, 2\)"),
        ((3, [[0.0, 1.0]], [1.0], [0.0], [0, 0, 0], [0, 0, 0]), "integers"),
        ((3, [[0, 1]], [np.nan], [0.0], [0, 0, 0], [0, 0, 0]), "NaN"),
        ((0, [], [], [], [], []), "at least 1"),
    ],
)
def test_mincut_errors(args, match):
    with pytest.raises(ValueError, match=match):
        mincut(*args)


def test_grid_mincut_matches_general_graph_and_enumeration():
    rng = np.random.default_rng(3)
    shape = (2, 4)
    src = rng.integers(0, 5, shape).astype(float)
    snk = rng.integers(0, 5, shape).astype(float)
    right = rng.integers(0, 4, shape).astype(float)
    down = rng.integers(0, 4, shape).astype(float)
    side, flow = grid_mincut(src, snk, {(0, 1): right, (1, 0): down})
    ids = np.arange(8).reshape(shape)
    edges = np.concatenate([np.stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()], 1),
                            np.stack([ids[:-1].ravel(), ids[1:].ravel()], 1)])
    w = np.concatenate([right[:, :-1].ravel(), down[:-1].ravel()])
    best, _ = brute_cut(8, edges, w, w, src.ravel(), snk.ravel())
    assert side.shape == shape
    assert flow == pytest.approx(best)
    assert cut_value(side.ravel(), edges, w, w, src.ravel(), snk.ravel()) == pytest.approx(best)


def test_grid_mincut_default_structure_list_and_scalar_weights():
    # 1 x 5 strip, seeds at both ends, uniform weight 2: one edge is cut.
    src = np.array([[np.inf, 0, 0, 0, 0]])
    snk = np.array([[0, 0, 0, 0, np.inf]])
    side, flow = grid_mincut(src, snk, [[2.0] * 5])
    assert flow == 2.0
    assert not side[0, 0] and side[0, 4]
    # a structure with diagonal offsets adds edges: 3 x 3 grid, 8-connected.
    st = np.array([[0, 0, 0], [0, 0, 1], [1, 1, 1]])
    src = np.zeros((3, 3))
    src[:, 0] = np.inf
    snk = np.zeros((3, 3))
    snk[:, 2] = np.inf
    _, flow8 = grid_mincut(src, snk, 1.0, structure=st)
    _, flow4 = grid_mincut(src, snk, 1.0)
    assert flow4 == 3.0
    assert flow8 == 7.0  # 3 horizontal + 4 diagonal edges cross any vertical cut


def test_grid_mincut_errors():
    with pytest.raises(ValueError, match="do not broadcast"):
        grid_mincut(np.zeros((2, 3)), np.zeros((2, 3)), np.ones((3, 3)))
    with pytest.raises(ValueError, match="non-zero 2-tuple"):
        grid_mincut(np.zeros((2, 3)), np.zeros((2, 3)), {(0, 0): 1.0})
    with pytest.raises(ValueError, match=r"structure must have shape \(3, 3\)"):
        grid_mincut(np.zeros((2, 3)), np.zeros((2, 3)), 1.0, structure=np.ones((3, 3, 3)))
    with pytest.raises(ValueError, match="sink must be non-negative"):
        grid_mincut(np.zeros((2, 3)), -np.ones((2, 3)), 1.0)


# --------------------------------------------------------------------------------------------------
# energy


def test_energy_exact_value():
    unary = np.array([[0.0, 1.0], [2.0, 0.5], [1.0, 1.0]])
    edges = np.array([[0, 1], [1, 2]])
    table = np.array([[0.0, 3.0], [4.0, 0.0]])
    # labels (0, 1, 1): unary 0 + 0.5 + 1, pairwise V(0,1) = 3 and V(1,1) = 0
    assert energy([0, 1, 1], unary, edges, table) == 4.5
    per_edge = np.stack([table, 2 * table])
    assert energy([0, 1, 0], unary, edges, per_edge) == 0 + 0.5 + 1 + 3 + 8
    assert energy([0, 1, 0], unary, edges, table_fn(per_edge)) == 12.5
    unary[2, 0] = INF
    assert energy([0, 1, 0], unary, edges, table) == np.inf


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(labels=[0, 1]), r"labels must have shape \(3,\)"),
        (dict(labels=[0, 1, 2]), r"labels out of range \[0, 2\)"),
        (dict(labels=[0.0, 1.0, 0.0]), "labels must be integers"),
        (dict(unary=np.zeros(3)), r"unary must have shape \(N, L\)"),
        (dict(unary=np.full((3, 2), np.nan)), "unary contains NaN"),
        (dict(unary=np.full((3, 2), -np.inf)), "unary contains -inf"),
        (dict(pairwise=np.zeros((3, 3))), r"pairwise must be a callable, an \(L, L\)"),
        (dict(pairwise=lambda k, a, b: np.zeros(1)), "pairwise function returned shape"),
        (dict(pairwise=lambda k, a, b: np.full(len(k), np.nan)), "pairwise function returned NaN"),
        (dict(edges=[[0, 5]]), "edges index out of range"),
    ],
)
def test_energy_and_expansion_errors(kwargs, match):
    args = dict(labels=[0, 1, 0], unary=np.zeros((3, 2)), edges=[[0, 1], [1, 2]], pairwise=np.ones((2, 2)))
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        energy(**args)
    if "labels" not in kwargs:
        with pytest.raises(ValueError, match=match):
            alpha_expansion(args["unary"], args["edges"], args["pairwise"])


def test_expansion_argument_errors():
    with pytest.raises(ValueError, match=r"init must have shape \(3,\)"):
        alpha_expansion(np.zeros((3, 2)), [[0, 1]], np.ones((2, 2)), init=[0, 0])
    with pytest.raises(ValueError, match="max_cycles must be at least 1"):
        alpha_expansion(np.zeros((3, 2)), [[0, 1]], np.ones((2, 2)), max_cycles=0)
    unary = np.zeros((3, 2))
    unary[1] = np.inf
    with pytest.raises(ValueError, match="unary row 1 has no finite label"):
        alpha_expansion(unary, [[0, 1]], np.ones((2, 2)))


# --------------------------------------------------------------------------------------------------
# alpha-expansion against exhaustive search


def check_result(res, unary, edges, pairwise, V):
    assert isinstance(res, ExpansionResult)
    assert res.labels.dtype == np.int64
    assert res.energy == energy(res.labels, unary, edges, pairwise)
    assert res.energy == pytest.approx(ref_energy(res.labels, unary, edges, V), rel=1e-12, abs=1e-12)
    assert res.history[-1] == res.energy
    assert all(b <= a for a, b in itertools.pairwise(res.history))
    assert res.cycles == len(res.history) - 1


def check_local_optimum(res, unary, edges, V, n_labels):
    for alpha in range(n_labels):
        assert best_expansion_move(res.labels, alpha, unary, edges, V) >= res.energy - 1e-9


@pytest.mark.parametrize("seed", range(8))
def test_two_labels_submodular_is_exact(seed):
    # With two labels and E00 + E11 <= E01 + E10 a local minimum of both expansion moves is global.
    rng = np.random.default_rng(seed)
    n = 7
    edges = random_graph(rng, n, 11)
    unary = rng.normal(size=(n, 2)) * 2
    per_edge = rng.random((len(edges), 2, 2)) * 2
    per_edge[:, 0, 1] += per_edge[:, 0, 0] + per_edge[:, 1, 1]  # make every edge submodular
    V = table_fn(per_edge)
    init = rng.integers(0, 2, n)
    res = alpha_expansion(unary, edges, per_edge, init=init, rng=seed)
    check_result(res, unary, edges, per_edge, V)
    assert res.energy == pytest.approx(brute_optimum(unary, edges, V), abs=1e-9)


@pytest.mark.parametrize("seed", range(8))
def test_potts_within_factor_two_and_local_optimum(seed):
    rng = np.random.default_rng(100 + seed)
    n, n_labels = 6, 3
    edges = random_graph(rng, n, 9)
    unary = rng.random((n, n_labels)) * 3
    table = (1 - np.eye(n_labels)) * rng.uniform(0.5, 2.0)
    V = table_fn(table)
    res = alpha_expansion(unary, edges, table, rng=seed)
    check_result(res, unary, edges, table, V)
    check_local_optimum(res, unary, edges, V, n_labels)
    opt = brute_optimum(unary, edges, V)
    assert opt - 1e-9 <= res.energy <= 2 * opt + 1e-9


@pytest.mark.parametrize("seed", range(8))
def test_metric_tables_shared_and_per_edge(seed):
    rng = np.random.default_rng(200 + seed)
    n, n_labels = 6, 3
    edges = random_graph(rng, n, 10)
    unary = rng.random((n, n_labels)) * 4
    if seed % 2:
        table = metric_table(rng, n_labels)
        c = metric_ratio(table)
    else:
        table = np.stack([metric_table(rng, n_labels) for _ in edges])
        c = max(metric_ratio(t) for t in table)
    V = table_fn(table)
    res = alpha_expansion(unary, edges, table, rng=seed)
    check_result(res, unary, edges, table, V)
    check_local_optimum(res, unary, edges, V, n_labels)
    opt = brute_optimum(unary, edges, V)
    assert opt - 1e-9 <= res.energy <= 2 * c * opt + 1e-9


@pytest.mark.parametrize("seed", range(4))
def test_callable_matches_table(seed):
    rng = np.random.default_rng(300 + seed)
    n, n_labels = 7, 4
    edges = random_graph(rng, n, 12)
    unary = rng.random((n, n_labels)) * 3
    table = np.stack([metric_table(rng, n_labels) for _ in edges])
    a = alpha_expansion(unary, edges, table, rng=seed)
    b = alpha_expansion(unary, edges, table_fn(table), rng=seed)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert a.energy == b.energy
    assert a.history == b.history


def test_callable_values_kept_across_moves_or_not(monkeypatch):
    # A callable's values on edges with an end that can take alpha are kept per label within a
    # budget and re-evaluated only where a label changed; past the budget every move evaluates
    # them afresh. Same labels, same history, either way; the kept values equal fresh ones, for
    # the edges with one active end as for those with two.
    rng = np.random.default_rng(310)
    n, n_labels = 14, 5
    edges = random_graph(rng, n, 36)
    unary = rng.random((n, n_labels)) * 3
    unary[rng.random((n, n_labels)) < 0.2] = np.inf
    unary[:, 0] = 2.0
    table = np.stack([metric_table(rng, n_labels) for _ in edges]) * 0.5 + 0.2  # V(a, a) = 0.2
    prepare = graphcut._Expansion._prepare
    checked = []

    def checking(self, kept, alpha, act):
        prepare(self, kept, alpha, act)
        ap, aq = act[kept.gp], act[kept.gq]
        la, lb = self.lab[kept.gp], self.lab[kept.gq]
        k = kept.idx
        b = ap & aq
        np.testing.assert_array_equal(kept.v01[b], table[k[b], la[b], alpha])
        np.testing.assert_array_equal(kept.v10[b], table[k[b], alpha, lb[b]])
        np.testing.assert_array_equal(kept.v11[b], table[k[b], alpha, alpha])
        np.testing.assert_array_equal(kept.v10[ap & ~aq], table[k[ap & ~aq], alpha, lb[ap & ~aq]])
        np.testing.assert_array_equal(kept.v01[aq & ~ap], table[k[aq & ~ap], la[aq & ~ap], alpha])
        checked.append(int(b.sum()))

    dtypes = set()

    def V(k, la, lb):
        dtypes.update((k.dtype, la.dtype, lb.dtype))
        return table[k, la, lb]

    monkeypatch.setattr(graphcut._Expansion, "_prepare", checking)
    a = alpha_expansion(unary, edges, V, init=np.zeros(n, dtype=int), rng=1)
    assert dtypes == {np.dtype(np.int64)}
    assert a.cycles == 3 and len(checked) > n_labels  # labels met again after changes
    monkeypatch.setattr(graphcut._Expansion, "_prepare", prepare)
    monkeypatch.setattr(graphcut, "_KEPT_EDGES", 2 * len(edges))
    b = alpha_expansion(unary, edges, table_fn(table), init=np.zeros(n, dtype=int), rng=1)
    monkeypatch.setattr(graphcut, "_KEPT_EDGES", 0)
    c = alpha_expansion(unary, edges, table_fn(table), init=np.zeros(n, dtype=int), rng=1)
    np.testing.assert_array_equal(a.labels, c.labels)
    assert a.history == c.history
    np.testing.assert_array_equal(a.labels, b.labels)
    assert a.history == b.history
    assert a.energy == energy(a.labels, unary, edges, table)


@pytest.mark.parametrize("seed", range(6))
def test_non_submodular_moves_never_raise_energy(seed):
    # Arbitrary (non-metric, partly negative) per-edge tables: moves are truncated, energy still falls.
    rng = np.random.default_rng(400 + seed)
    n, n_labels = 6, 3
    edges = random_graph(rng, n, 10)
    unary = rng.normal(size=(n, n_labels))
    table = rng.normal(size=(len(edges), n_labels, n_labels)) * 2
    V = table_fn(table)
    init = rng.integers(0, n_labels, n)
    res = alpha_expansion(unary, edges, table, init=init, rng=seed)
    check_result(res, unary, edges, table, V)
    assert res.history[0] == pytest.approx(ref_energy(init, unary, edges, V))
    assert res.energy >= brute_optimum(unary, edges, V) - 1e-9


def test_infinite_unary_respected():
    rng = np.random.default_rng(5)
    n, n_labels = 7, 3
    edges = random_graph(rng, n, 12)
    unary = rng.random((n, n_labels))
    unary[0, [0, 1]] = np.inf  # node 0 can only take label 2
    unary[3, 2] = INF  # node 3 cannot take label 2
    unary[5, [1, 2]] = np.inf  # node 5 can only take label 0
    table = 5.0 * (1 - np.eye(n_labels))  # strong smoothing pulls towards forbidden labels
    init = np.zeros(n, dtype=int)  # node 0 starts on a forbidden label
    V = table_fn(table)
    res = alpha_expansion(unary, edges, table, init=init)
    check_result(res, unary, edges, table, V)
    assert res.history[0] == np.inf
    assert np.isfinite(res.energy)
    assert res.labels[0] == 2 and res.labels[5] == 0 and res.labels[3] != 2
    check_local_optimum(res, unary, edges, V, n_labels)
    opt = brute_optimum(unary, edges, V)
    assert opt <= res.energy <= 2 * opt


def test_infinite_pairwise_empty_voxels():
    # Retargeting-style costs: label l at node p shows input cell src[p, l]; cells are empty or not;
    # empty next to non-empty costs inf, empty next to empty costs 0, else a distance.
    rng = np.random.default_rng(8)
    n, n_labels = 7, 3
    edges = np.array([[i, i + 1] for i in range(n - 1)] + [[0, 6]])
    cells = rng.normal(size=(10, 2))
    empty = np.zeros(10, dtype=bool)
    empty[[2, 5, 7]] = True
    src = rng.integers(0, 10, (n, n_labels))
    src[:, 0] = np.arange(n)  # label 0 is a feasible copy

    def V(k, a, b):
        k, a, b = np.atleast_1d(k), np.atleast_1d(a), np.atleast_1d(b)
        out = np.zeros(len(k))
        for side in (0, 1):
            node = edges[k, side]
            ca, cb = src[node, a], src[node, b]
            d = np.linalg.norm(cells[ca] - cells[cb], axis=-1)
            d = np.where(empty[ca] & empty[cb], 0.0, np.where(empty[ca] ^ empty[cb], np.inf, d))
            out += d
        return out

    unary = np.zeros((n, n_labels))
    ref = lambda k, a, b: float(V(k, a, b)[0])  # noqa: E731
    opt = brute_optimum(unary, edges, ref)
    # from an infeasible start (infinite terms present) and from a feasible one (all label 0),
    # where moves first fix the nodes whose switch would meet an infinite cost
    for init in (rng.integers(0, n_labels, n), np.zeros(n, dtype=int)):
        res = alpha_expansion(unary, edges, V, init=init, rng=0)
        check_result(res, unary, edges, V, ref)
        assert np.isfinite(res.energy)
        assert res.energy >= opt - 1e-9
        # every move is submodular here (V(a, a) = 0, finite current terms), so the result is a
        # local minimum of every expansion move
        check_local_optimum(res, unary, edges, ref, n_labels)
    assert np.isinf(energy(np.array([0, 1, 2, 0, 1, 2, 0]), unary, edges, V))


@pytest.mark.parametrize("seed", range(6))
def test_forced_nodes_with_infinite_pairwise_grid(seed):
    # 2 x 4 grid, 3 labels, random finite/inf pairwise per edge with V(a, a) = 0: brute-force moves.
    rng = np.random.default_rng(600 + seed)
    ids = np.arange(8).reshape(2, 4)
    edges = np.concatenate([np.stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()], 1),
                            np.stack([ids[:-1].ravel(), ids[1:].ravel()], 1)])
    n_labels = 3
    table = np.stack([metric_table(rng, n_labels) for _ in edges])
    forbid = rng.random(table.shape) < 0.25
    forbid = forbid | forbid.transpose(0, 2, 1)
    forbid[:, np.arange(n_labels), np.arange(n_labels)] = False
    table[forbid] = np.inf
    unary = rng.random((8, n_labels))
    unary[:, 1:][rng.random((8, n_labels - 1)) < 0.3] = np.inf  # label 0 stays feasible everywhere
    V = table_fn(table)
    res = alpha_expansion(unary, edges, table, init=np.zeros(8, dtype=int), rng=seed)
    check_result(res, unary, edges, table, V)
    check_local_optimum(res, unary, edges, V, n_labels)
    assert np.isfinite(res.energy)


def test_infeasible_problem_raises_or_returns_infinite():
    unary = np.array([[0.0, np.inf], [np.inf, 0.0]])
    table = np.array([[0.0, np.inf], [np.inf, 0.0]])
    with pytest.raises(ValueError, match="no finite-energy labeling"):
        alpha_expansion(unary, [[0, 1]], table)
    res = alpha_expansion(unary, [[0, 1]], table, allow_infinite=True)
    assert res.energy == np.inf
    assert res.labels.tolist() == [0, 1]


def test_two_label_grid_matches_grid_mincut():
    # Binary segmentation: alpha-expansion with 2 labels and Potts equals the direct min-cut.
    rng = np.random.default_rng(11)
    shape = (6, 7)
    d0 = rng.random(shape) * 2
    d1 = rng.random(shape) * 2
    side, flow = grid_mincut(d1, d0, 0.6)
    ids = np.arange(d0.size).reshape(shape)
    edges = np.concatenate([np.stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()], 1),
                            np.stack([ids[:-1].ravel(), ids[1:].ravel()], 1)])
    unary = np.stack([d0.ravel(), d1.ravel()], axis=1)
    res = alpha_expansion(unary, edges, 0.6 * (1 - np.eye(2)))
    assert res.energy == pytest.approx(flow)
    assert energy(side.ravel().astype(int), unary, edges, 0.6 * (1 - np.eye(2))) == pytest.approx(flow)


def test_determinism_and_order():
    rng = np.random.default_rng(12)
    n, n_labels = 30, 6
    edges = random_graph(rng, n, 80)
    unary = rng.random((n, n_labels)) * 3
    table = metric_table(rng, n_labels)
    a = alpha_expansion(unary, edges, table, rng=7)
    b = alpha_expansion(unary, edges, table, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a.labels, b.labels)
    assert a.history == b.history
    c = alpha_expansion(unary, edges, table)
    d = alpha_expansion(unary, edges, table)
    np.testing.assert_array_equal(c.labels, d.labels)
    assert c.history == d.history
    assert a.moves >= 1 and c.moves >= 1


def test_max_cycles_bounds_the_run():
    rng = np.random.default_rng(13)
    n, n_labels = 40, 5
    edges = random_graph(rng, n, 120)
    unary = rng.random((n, n_labels)) * 3
    table = metric_table(rng, n_labels)
    res = alpha_expansion(unary, edges, table, max_cycles=1)
    assert res.cycles == 1 and len(res.history) == 2
    assert res.energy == energy(res.labels, unary, edges, table)


def reference_move(labels, alpha, unary, edges, V, big=1e6):
    """One expansion move built edge by edge (plain Kolmogorov-Zabih form) and solved by mincut."""
    n = len(labels)
    fin = lambda v: big if np.isinf(v) else v  # noqa: E731
    src, snk = np.zeros(n), np.zeros(n)  # cost of x = 1 (sink side), of x = 0
    can = np.array([labels[p] != alpha and np.isfinite(unary[p][alpha]) for p in range(n)])
    for p in range(n):
        snk[p] += fin(unary[p][labels[p]])
        src[p] += fin(unary[p][alpha]) if can[p] else big
    pairs, caps = [], []
    for k, (p, q) in enumerate(edges):
        a, b = labels[p], labels[q]
        e00, e01, e10, e11 = (fin(V(k, a, b)), fin(V(k, a, alpha)), fin(V(k, alpha, b)),
                              fin(V(k, alpha, alpha)))
        snk[p] += e00
        src[p] += e10 - e00
        src[q] += e11 - e10
        pairs.append((p, q))
        caps.append(max(e01 + e10 - e00 - e11, 0.0))
    shift = np.minimum(src, snk)
    side, _ = mincut(n, np.array(pairs), np.array(caps), np.zeros(len(caps)), src - shift, snk - shift)
    return np.where(side & can, alpha, labels)


@pytest.mark.parametrize("seed", range(4))
def test_result_is_fixed_point_of_reference_moves(seed):
    rng = np.random.default_rng(700 + seed)
    n, n_labels = 40, 5
    edges = random_graph(rng, n, 110)
    table = np.stack([metric_table(rng, n_labels) for _ in edges])
    forbid = rng.random(table.shape) < 0.15
    forbid = forbid | forbid.transpose(0, 2, 1)
    forbid[:, np.arange(n_labels), np.arange(n_labels)] = False
    table[forbid] = np.inf
    unary = rng.random((n, n_labels)) * 2
    unary[:, 1:][rng.random((n, n_labels - 1)) < 0.2] = np.inf
    V = table_fn(table)
    res = alpha_expansion(unary, edges, table, init=np.zeros(n, dtype=int), rng=seed)
    check_result(res, unary, edges, table, V)
    for alpha in range(n_labels):
        moved = reference_move(res.labels, alpha, unary, edges, V)
        assert ref_energy(moved, unary, edges, V) >= res.energy - 1e-9


def test_expansion_without_edges_and_single_label():
    unary = np.array([[3.0, 1.0, np.inf], [0.5, 2.0, 0.0], [np.inf, np.inf, 4.0]])
    res = alpha_expansion(unary, np.zeros((0, 2), dtype=int), np.zeros((3, 3)))
    assert res.labels.tolist() == [1, 2, 2]
    assert res.energy == 5.0
    res = alpha_expansion(np.array([[1.0], [2.0]]), [[0, 1]], np.array([[0.5]]))
    assert res.labels.tolist() == [0, 0]
    assert res.energy == 3.5 and res.cycles == 1 and res.moves == 0


def test_compile_kernels_covers_the_types_of_real_runs():
    # make install compiles the kernels on a 3-node problem: real problems (callable or table
    # costs, infinite terms, several labels) must reuse those compilations, not add new ones
    from synthkit.core import flow

    graphcut.compile_kernels()
    kernels = (graphcut._move, graphcut._stale, graphcut._fix_blocked, flow._arcs)
    before = [len(k.signatures) for k in kernels]
    assert min(before) >= 1
    rng = np.random.default_rng(5)
    n, n_labels = 30, 4
    edges = random_graph(rng, n, 60)
    unary = rng.random((n, n_labels))
    unary[rng.random((n, n_labels)) < 0.2] = np.inf
    unary[:, 0] = 1.0
    table = rng.random((len(edges), n_labels, n_labels))
    table[:, 1, 2] = np.inf
    for pairwise in (table, table_fn(table), table[0]):
        alpha_expansion(unary, edges, pairwise, allow_infinite=True)
    assert [len(k.signatures) for k in kernels] == before
