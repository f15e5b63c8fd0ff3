"""Graph-cut benchmarks: alpha-expansion on 26-connected voxel grids and binary min-cut on a mesh.

Figures (issue 2, goals on a 2-core machine):
- alpha-expansion with position-dependent (retargeting-style, section III-B) costs, 1000 nodes x 30
  labels: <= 0.2 s; gco-wrapper also runs the same problem through its per-pair Python callback
  (slow: once); a period-2 stress variant is timed too (no goal);
- the same with 4992 nodes x 64 labels: <= 1 s;
- each also with nothing kept between moves (pairwise values, graphs and flows made afresh), the
  figure that shows what keeping them saves;
- each also on a problem gco-wrapper expresses natively (pairwise = w_pq * V(la, lb), same graph,
  same validity pattern), timed against gco in the same process, with both energies printed;
- binary min-cut over the vertex graph of a 100k-vertex mesh: <= 0.5 s on the energy its consumer
  (surfacing by numbers, section 3) minimises: a bumpy torus, eq. 1 boundary costs from dihedral
  angles and edge lengths, stroke seeds and k-means colour region costs at every vertex; the same
  with a 10x weaker region term, and the seeds-only worst case for Boykov-Kolmogorov (a height
  field, seeds at two ends, edge-length capacities, no region term), both without a goal; each
  against SciPy's ``maximum_flow`` (integer capacities) on the same graph.
All times are medians over repeats (``--quick``: one, and neither 4992 x 64 nor the seeds-only case:
it checks that the benchmark runs); every solver starts from the same labeling
(the cheapest unary label per node).

Run: ``.venv/bin/python benchmarks/graphcut.py [--quick] [--only expansion|mincut]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import print_table, record, write_results  # noqa: E402

from synthkit.core import graphcut  # noqa: E402
from synthkit.core.graphcut import alpha_expansion, energy, mincut  # noqa: E402

AREA = "graphcut"
BIG_INT = 4 * 10**6  # gco's stand-in for an infinite cost (its terms must stay below 10**7)
GCO_SCALE = 1000  # float costs are passed to gco as integers in units of 1 / GCO_SCALE


def grid_edges(shape: tuple[int, int, int]) -> np.ndarray:
    """(E, 2) int64 edges of the 26-connected grid of ``shape``, each undirected edge once."""
    ids = np.arange(np.prod(shape)).reshape(shape)
    out = []
    for off in np.ndindex(3, 3, 3):
        o = np.array(off) - 1
        if tuple(o) <= (0, 0, 0):  # keep one of each +-o pair
            continue
        a = tuple(slice(max(0, -d), s - max(0, d)) for d, s in zip(o, shape, strict=True))
        b = tuple(slice(max(0, d), s - max(0, -d)) for d, s in zip(o, shape, strict=True))
        out.append(np.stack([ids[a].ravel(), ids[b].ravel()], axis=1))
    return np.concatenate(out).astype(np.int64)


def retarget_problem(out_shape, label_shape, seed: int = 0, *, pattern: str = "lattice"):
    """A retargeting problem of the offset-statistics paper (section III-B).

    The input model is a voxel grid of ``out_shape - label_shape + 1`` cells, one lattice cell per
    voxel as in the paper (voxels are spanned by the principle offsets, so copies shifted by any
    label line up with the lattice). ``pattern="lattice"``: a cell's descriptor depends on where
    it sits in the model (first, inner or last layer along each axis: 27 classes, like the ends,
    edges and corners of a facade), with 4 slightly different variants per class drawn at random
    and 12 % of the cells replaced by random other classes (doors, balconies); the top layer is
    empty except at both ends of the first axis. ``pattern="period2"``: a stress case whose
    descriptors repeat every 2 cells along the first axis, so odd offsets never line up.

    Label ``l = (u, v, w)`` copies voxel ``x - l``; its unary cost is 0 inside the input, inf
    outside. The pairwise cost of edge ``(x, x')`` is ``d(G(x - la), G(x - lb)) + d(G(x' - la),
    G(x' - lb))`` with ``d`` the Euclidean distance between cell descriptors, 0 between two empty
    cells and inf between an empty and a non-empty one. Cells outside the input count as empty, so
    a seam between two labels is finite only where both copies cover both voxels.

    Returns unary (N, L), edges (E, 2), pairwise callable, labels as offsets (L, 3).
    """
    rng = np.random.default_rng(seed)
    out_shape = np.array(out_shape)
    lab = np.array(list(np.ndindex(*label_shape)))
    in_shape = out_shape - np.array(label_shape) + 1
    cells = np.array(list(np.ndindex(*in_shape)))
    if pattern == "lattice":
        cls = np.where(cells == 0, 0, np.where(cells == in_shape - 1, 2, 1)) @ np.array([9, 3, 1])
        n_cls, variants = 27, 4
        ctype = 1 + cls * variants + rng.integers(0, variants, len(cells))
        defect = rng.random(len(cells)) < 0.12
        ctype[defect] = 1 + rng.integers(0, n_cls, defect.sum()) * variants
        proto = rng.normal(size=(n_cls, 6))
        desc = np.repeat(proto, variants, axis=0) + 0.1 * rng.normal(size=(n_cls * variants, 6))
        roof = (cells[:, 2] == in_shape[2] - 1) & (cells[:, 0] > 0) & (cells[:, 0] < in_shape[0] - 1)
        ctype[roof] = 0
    else:
        n_types = 16
        ctype = 1 + (cells[:, 0] % 2)
        defect = rng.random(len(cells)) < 0.12
        ctype[defect] = rng.integers(1, n_types, defect.sum())
        desc = rng.normal(size=(n_types - 1, 6))
    desc = np.concatenate([np.zeros((1, 6)), desc])  # type 0 is empty
    dt = np.linalg.norm(desc[:, None] - desc[None], axis=-1)
    dt[0, :] = np.inf
    dt[:, 0] = np.inf
    dt[0, 0] = 0.0

    nodes = np.array(list(np.ndindex(*out_shape)))
    src = nodes[:, None, :] - lab[None, :, :]  # (N, L, 3)
    inside = np.all((src >= 0) & (src < in_shape), axis=-1)
    flat = np.ravel_multi_index(tuple(np.clip(src, 0, in_shape - 1).transpose(2, 0, 1)), tuple(in_shape))
    typ = np.where(inside, ctype[flat], 0)  # (N, L) descriptor type shown at node p under label l
    unary = np.where(inside, 0.0, np.inf)
    edges = grid_edges(tuple(out_shape))
    e0, e1 = edges[:, 0], edges[:, 1]

    def pairwise(e, la, lb):
        p, q = e0[e], e1[e]
        return dt[typ[p, la], typ[p, lb]] + dt[typ[q, la], typ[q, lb]]

    # gco's per-pair callback: the same cost in integer units of 1 / GCO_SCALE, with each infinite
    # descriptor distance replaced by BIG_INT. Capping each distance keeps every V_pq a metric,
    # so gco's expansion moves stay submodular as it requires.
    dt_int = np.where(np.isinf(dt), BIG_INT, np.round(dt * GCO_SCALE)).astype(np.int64).tolist()
    typ_list = typ.tolist()

    def site_pairwise(s1: int, s2: int, l1: int, l2: int) -> int:
        t1, t2 = typ_list[s1], typ_list[s2]
        return dt_int[t1[l1]][t1[l2]] + dt_int[t2[l1]][t2[l2]]

    pairwise.site = site_pairwise
    return unary, edges, pairwise, lab


def weighted_problem(out_shape, label_shape, seed: int = 0):
    """The same graph and validity pattern with gco-expressible integer costs.

    unary = data cost in 0..20 for valid labels, inf outside the input; pairwise = w_pq * V(la, lb)
    with w_pq in 1..5 and V = 10 * min(|la - lb|_1, 3) (a truncated L1 metric on offset labels).
    """
    rng = np.random.default_rng(seed)
    unary, edges, _, lab = retarget_problem(out_shape, label_shape, seed)
    unary = np.where(np.isfinite(unary), rng.integers(0, 21, unary.shape).astype(float), np.inf)
    w = rng.integers(1, 6, len(edges)).astype(float)
    V = 10.0 * np.minimum(np.abs(lab[:, None] - lab[None]).sum(-1), 3)
    return unary, edges, w, V


def run_gco(unary, edges, w, V, init):
    import gco

    n, n_labels = unary.shape
    g = gco.GCO()
    g.create_general_graph(n, n_labels, False)
    g.set_data_cost(np.where(np.isfinite(unary), unary, BIG_INT).astype(np.intc))
    g.set_all_neighbors(edges[:, 0], edges[:, 1], w.astype(np.intc))
    g.set_smooth_cost(V.astype(np.intc))
    for i, l0 in enumerate(init):
        g.init_label_at_site(i, int(l0))
    g.expansion(-1)
    labels = g.get_labels().astype(np.int64)
    g.destroy_graph()
    return labels


def run_gco_callback(unary, edges, site_pairwise, init):
    """gco on the position-dependent problem itself, through its per-pair smooth-cost callback
    ``site_pairwise(s1, s2, l1, l2) -> int`` (costs in units of 1 / GCO_SCALE, inf as BIG_INT)."""
    import gco

    n, n_labels = unary.shape
    g = gco.GCO()
    g.create_general_graph(n, n_labels, False)
    g.set_data_cost(np.where(np.isfinite(unary), unary * GCO_SCALE, BIG_INT).astype(np.intc))
    g.set_all_neighbors(edges[:, 0], edges[:, 1], np.ones(len(edges), dtype=np.intc))
    g.set_smooth_cost_function(lambda s1, s2, l1, l2: site_pairwise(int(s1), int(s2), int(l1), int(l2)))
    for i, l0 in enumerate(init):
        g.init_label_at_site(i, int(l0))
    g.expansion(-1)
    labels = g.get_labels().astype(np.int64)
    g.destroy_graph()
    return labels


def timed(fn, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def bench_expansion(
    name: str, out_shape, label_shape, goal: float, repeats: int, peer_repeats: int, *, gco_callback: bool
) -> None:
    unary, edges, pairwise, _ = retarget_problem(out_shape, label_shape)
    n, n_labels = unary.shape
    alpha_expansion(unary, edges, pairwise)  # warm-up
    t_pos, res = timed(lambda: alpha_expansion(unary, edges, pairwise), repeats)
    print(
        f"{name}: {n} nodes x {n_labels} labels, {len(edges)} edges, position-dependent: "
        f"{t_pos * 1e3:.1f} ms, energy {res.history[0]:.4g} -> {res.energy:.6g} "
        f"in {res.cycles} cycles, {res.moves} moves",
        file=sys.stderr,
    )
    if gco_callback:
        init = np.argmin(unary, axis=1)
        t_cb, lab_cb = timed(lambda: run_gco_callback(unary, edges, pairwise.site, init), 1)
        e_cb = energy(lab_cb, unary, edges, pairwise)
        n_inf = int(np.isinf(unary[np.arange(n), lab_cb]).sum())
        n_inf += int(np.isinf(pairwise(np.arange(len(edges)), lab_cb[edges[:, 0]], lab_cb[edges[:, 1]])).sum())
        print(
            f"{name}: gco on the same position-dependent problem (per-pair Python callback, inf as "
            f"{BIG_INT / GCO_SCALE:g}): {t_cb * 1e3:.1f} ms, energy {e_cb:.6g} ({n_inf} infinite terms); "
            f"time ratio ours/gco {t_pos / t_cb:.3f}",
            file=sys.stderr,
        )
        record(AREA, f"{name}_posdep_s", t_pos, "s", goal=goal, baseline=t_cb)
        # an infinite gco energy has no JSON ratio: it is printed above instead
        record(AREA, f"{name}_posdep_energy", res.energy, "energy", baseline=e_cb if np.isfinite(e_cb) else None)
    else:
        record(AREA, f"{name}_posdep_s", t_pos, "s", goal=goal)
    # the same run with nothing kept between moves: every move evaluates its pairwise values and
    # builds its graph afresh, and its max-flow starts from zero
    kept_edges, graphcut._KEPT_EDGES = graphcut._KEPT_EDGES, 0
    try:
        t_fresh, res_f = timed(lambda: alpha_expansion(unary, edges, pairwise), 1)
    finally:
        graphcut._KEPT_EDGES = kept_edges
    assert res_f.energy == res.energy
    print(f"{name}: nothing kept between moves (fresh values, graphs and flows): {t_fresh * 1e3:.1f} ms; "
          f"time ratio kept/fresh {t_pos / t_fresh:.2f}", file=sys.stderr)
    record(AREA, f"{name}_posdep_fresh_s", t_fresh, "s")
    unary_s, edges_s, pairwise_s, _ = retarget_problem(out_shape, label_shape, pattern="period2")
    t_str, res_s = timed(lambda: alpha_expansion(unary_s, edges_s, pairwise_s), repeats)
    print(
        f"{name}: stress case (period-2 lattice, odd offsets never fit): {t_str * 1e3:.1f} ms, "
        f"energy {res_s.history[0]:.4g} -> {res_s.energy:.6g} in {res_s.cycles} cycles, {res_s.moves} moves",
        file=sys.stderr,
    )
    record(AREA, f"{name}_posdep_period2_s", t_str, "s")

    unary_w, edges_w, w, V = weighted_problem(out_shape, label_shape)
    init = np.argmin(unary_w, axis=1)
    table = w[:, None, None] * V[None]

    def ours():
        return alpha_expansion(unary_w, edges_w, lambda e, a, b: w[e] * V[a, b])

    t_ours, res_w = timed(ours, repeats)
    t_gco, lab_gco = timed(lambda: run_gco(unary_w, edges_w, w, V, init), peer_repeats)
    e_gco = energy(lab_gco, unary_w, edges_w, table)
    print(
        f"{name} weighted (w_pq * V): ours {t_ours * 1e3:.1f} ms energy {res_w.energy:.6g}; "
        f"gco {t_gco * 1e3:.1f} ms energy {e_gco:.6g}; time ratio ours/gco {t_ours / t_gco:.2f}",
        file=sys.stderr,
    )
    record(AREA, f"{name}_weighted_s", t_ours, "s", goal=goal, baseline=t_gco)
    record(AREA, f"{name}_weighted_energy", res_w.energy, "energy", baseline=e_gco if np.isfinite(e_gco) else None)


def grid_mesh(nx: int, ny: int, seed: int = 0):
    """A bumpy height-field mesh of nx * ny vertices: V (n, 3), unique edges (E, 2)."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny), indexing="ij")
    z = 0.05 * np.sin(9 * x) * np.cos(7 * y) + 0.002 * rng.standard_normal(x.shape)
    V = np.stack([x, y, z], -1).reshape(-1, 3)
    ids = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = ids[:-1, :-1].ravel(), ids[1:, :-1].ravel(), ids[1:, 1:].ravel(), ids[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.unique(np.sort(E, axis=1), axis=0)
    return V, E


def bumpy_torus(nu: int, nv: int, seed: int = 0):
    """A closed bumpy torus of ``nu * nv`` vertices with two regions split by concave grooves.

    The ring angle ``u`` is cut into region B (``b1(v) < u < b2(v)``, two wavy curves) and region
    A (the rest); along both curves the tube radius dips (a groove: concave edges, where the
    minima rule puts part boundaries). Returns V (n, 3), F (2n, 3) int, region (n,) bool (True
    in B) and the parameters u, v (n,) of every vertex.
    """
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    b1 = np.pi / 2 + 0.3 * np.sin(3 * v)
    b2 = 3 * np.pi / 2 + 0.25 * np.cos(2 * v)
    dist = np.minimum(np.abs(u - b1), np.abs(u - b2))
    r = (0.35 + 0.02 * np.sin(11 * u) * np.cos(7 * v) - 0.06 * np.exp(-((dist / 0.05) ** 2))
         + 0.002 * rng.standard_normal(u.shape))
    ring = 1.0 + r * np.cos(v)
    V = np.stack([ring * np.cos(u), ring * np.sin(u), r * np.sin(v)], -1).reshape(-1, 3)
    ids = np.arange(nu * nv).reshape(nu, nv)
    b = np.roll(ids, -1, 0)
    c, d = np.roll(b, -1, 1), np.roll(ids, -1, 1)
    F = np.concatenate([np.stack([ids.ravel(), b.ravel(), c.ravel()], 1),
                        np.stack([ids.ravel(), c.ravel(), d.ravel()], 1)])
    return V, F, ((u > b1) & (u < b2)).ravel(), u.ravel(), v.ravel()


def boundary_costs(V, F):
    """Unique edges (E, 2) of a closed manifold mesh and the paper's boundary cost (eq. 1) per edge.

    ``e_ij = eta (2 pi - theta_ij) / (2 pi) + gamma d_ij / mean(d)`` with ``eta = gamma = 1`` (the
    paper's values) and ``theta_ij`` the dihedral angle of the two faces at the edge: ``pi`` when
    flat, larger when concave, smaller when convex.
    """
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    opp = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    face = np.tile(np.arange(len(F)), 3)
    key = np.sort(he, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    E = key[order][0::2]
    if not np.array_equal(E, key[order][1::2]):
        raise ValueError("mesh is not a closed manifold: an edge without exactly two faces")
    f1, f2, o2 = face[order][0::2], face[order][1::2], opp[order][1::2]
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area = 0.5 * np.linalg.norm(fn, axis=1)
    fn /= 2 * area[:, None]
    bend = np.arccos(np.clip(np.einsum("ij,ij->i", fn[f1], fn[f2]), -1.0, 1.0))
    concave = np.einsum("ij,ij->i", fn[f1], V[o2] - V[E[:, 0]]) > 0
    theta = np.pi + np.where(concave, bend, -bend)
    d = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    vertex_area = np.bincount(F.ravel(), np.repeat(area / 3, 3), minlength=len(V))
    return E, (2 * np.pi - theta) / (2 * np.pi) + d / d.mean(), vertex_area / vertex_area.mean()


def segmentation_problem(nu: int = 400, nv: int = 250, *, region_weight: float = 1.0, seed: int = 0):
    """A surfacing-by-numbers segmentation (section 3) of a 100k-vertex bumpy torus.

    One node per vertex, one edge per mesh edge with the boundary cost of eq. 1 (both ways). A
    noisy colour signal covers the surface (two colours per region, Gaussian noise of 0.12); two
    strokes (a band of vertices in each region) are fixed to their terminal by infinite links.
    Region costs as in the paper's refs [20, 26] (Lazy Snapping): the stroke colours of each region
    are clustered by k-means (4 clusters), ``d_A, d_B`` are the distances of a vertex's colour to
    the nearest cluster of each, and the cost of labeling a vertex A is ``d_A / (d_A + d_B)``,
    times its vertex area (normalised to mean 1, as the paper asks), times ``region_weight``.
    Source side = region A (stroke A), sink side = region B.

    Returns n, edges (E, 2), capacities (E,), source (n,), sink (n,), truth (n,) bool (True in B).
    """
    from scipy.cluster.vq import kmeans2

    rng = np.random.default_rng(seed)
    V, F, truth, u, v = bumpy_torus(nu, nv, seed)
    E, w, vertex_area = boundary_costs(V, F)
    n = len(V)
    palette_a = np.array([[0.8, 0.3, 0.2], [0.6, 0.4, 0.3]])
    palette_b = np.array([[0.3, 0.5, 0.7], [0.45, 0.45, 0.5]])
    pick = rng.integers(0, 2, n)
    colour = np.where(truth[:, None], palette_b[pick], palette_a[pick]) + 0.12 * rng.standard_normal((n, 3))
    stroke_a = (np.abs(np.angle(np.exp(1j * u))) < 0.05) & (np.abs(v - 1.0) < 1.2)
    stroke_b = (np.abs(u - np.pi) < 0.05) & (np.abs(v - 4.0) < 1.2)
    dist = []
    for stroke in (stroke_a, stroke_b):
        centres, _ = kmeans2(colour[stroke], 4, seed=rng, minit="++")
        dist.append(np.linalg.norm(colour[:, None] - centres[None], axis=-1).min(axis=1))
    d_a, d_b = dist
    sink = region_weight * vertex_area * d_a / (d_a + d_b)  # paid on the source side (A)
    source = region_weight * vertex_area * d_b / (d_a + d_b)  # paid on the sink side (B)
    source[stroke_a] = np.inf
    sink[stroke_b] = np.inf
    return n, E, w, source, sink, truth


def scipy_mincut(n, E, cap, source, sink, scale: float):
    """SciPy ``maximum_flow`` (integer capacities: ``round(cap * scale)``, infinite as 2**30) on
    the same undirected graph with terminal links; returns a callable and the scale."""
    from scipy.sparse import csr_array
    from scipy.sparse.csgraph import maximum_flow

    def as_int(x):
        return np.where(np.isinf(x), 2**30, np.round(x * scale)).astype(np.int32)

    s_node, t_node = n, n + 1
    src, snk = np.flatnonzero(source > 0), np.flatnonzero(sink > 0)
    rows = np.concatenate([E[:, 0], E[:, 1], np.full(len(src), s_node), snk])
    cols = np.concatenate([E[:, 1], E[:, 0], src, np.full(len(snk), t_node)])
    data = np.concatenate([as_int(cap), as_int(cap), as_int(source[src]), as_int(sink[snk])])
    graph = csr_array((data, (rows, cols)), shape=(n + 2, n + 2))
    return lambda: maximum_flow(graph, s_node, t_node).flow_value / scale


def bench_mincut_case(name, n, E, cap, source, sink, *, goal, repeats, peer_repeats, scale, truth=None):
    mincut(n, E, cap, cap, source, sink)
    t_ours, (side, flow) = timed(lambda: mincut(n, E, cap, cap, source, sink), repeats)
    t_scipy, flow_scipy = timed(scipy_mincut(n, E, cap, source, sink, scale), peer_repeats)
    acc = "" if truth is None else f", {100 * np.mean(side == truth):.2f} % of vertices as in the truth"
    print(
        f"{name}: {n} vertices, {len(E)} edges: ours {t_ours * 1e3:.1f} ms flow {flow:.6g} "
        f"({int(side.sum())} on sink side{acc}); scipy maximum_flow {t_scipy * 1e3:.1f} ms flow "
        f"{flow_scipy:.6g}; ratio {t_ours / t_scipy:.3f}",
        file=sys.stderr,
    )
    record(AREA, f"{name}_s", t_ours, "s", goal=goal, baseline=t_scipy)


def bench_mesh_mincut(repeats: int, peer_repeats: int, *, quick: bool = False) -> None:
    # the figure with a goal: the paper's energy (eq. 1 boundary costs, stroke-based region costs)
    n, E, w, source, sink, truth = segmentation_problem()
    bench_mincut_case("mesh_mincut_100k", n, E, w, source, sink, goal=0.5, repeats=repeats,
                      peer_repeats=peer_repeats, scale=1e4, truth=truth)
    # the same with a 10x weaker region term (boundary costs dominate): no goal
    n, E, w, source, sink, truth = segmentation_problem(region_weight=0.1)
    bench_mincut_case("mesh_mincut_100k_weak_region", n, E, w, source, sink, goal=None, repeats=repeats,
                      peer_repeats=peer_repeats, scale=1e4, truth=truth)
    if quick:
        return
    # worst case for Boykov-Kolmogorov, no goal: seeds at two ends of a height field, edge-length
    # capacities, no region term anywhere else
    V, E = grid_mesh(317, 316)
    length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    cap = length / length.mean()
    source = np.where(V[:, 0] < 0.01, np.inf, 0.0)
    sink = np.where(V[:, 0] > 0.99, np.inf, 0.0)
    bench_mincut_case("mesh_mincut_100k_seeds_only", len(V), E, cap, source, sink, goal=None,
                      repeats=max(1, repeats // 2), peer_repeats=1, scale=1e4)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one repeat, the small cases only")
    ap.add_argument("--only", choices=["expansion", "mincut"], help="run one group of figures")
    args = ap.parse_args(argv)
    repeats = 1 if args.quick else 7
    peer_repeats = 1 if args.quick else 3  # the peers are slow: fewer repeats
    if args.only != "mincut":
        # gco through its Python callback takes about 4 s on 1000 x 30 and 90 s on 4992 x 64: it
        # runs once on each
        bench_expansion("expansion_1000x30", (10, 10, 10), (2, 3, 5), 0.2, repeats, peer_repeats,
                        gco_callback=True)
        if not args.quick:
            bench_expansion("expansion_4992x64", (13, 16, 24), (4, 4, 4), 1.0, max(1, repeats // 2), 1,
                            gco_callback=True)
    if args.only != "expansion":
        bench_mesh_mincut(repeats, peer_repeats, quick=args.quick)
    print_table(AREA)
    write_results(AREA)


if __name__ == "__main__":
    main()
