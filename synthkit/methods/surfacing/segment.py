"""Region-centric segmentation of ``V (#V, 3)``, ``F (#F, 3)`` from stroke owners: the whole of
section 3 as one function over arrays, shared by the pipeline and the benchmark.

Faces: on the face graph every face is a node and gets its node's label; on the vertex graph a
face takes the label of at least two of its corners (three different labels: the smallest), so
the boundary between regions always runs along mesh edges and no face is split. Vertex labels on
the face graph are the label with the largest incident face area. A connected component without
any stroke takes, whole, the region of the stroke nearest to it (Euclidean).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from synthkit.core.mesh import face_adjacency
from synthkit.methods.surfacing import lod, regions
from synthkit.methods.surfacing.graph import (
    SegGraph,
    build_graph,
    face_labels_from_vertices,
    vertex_labels_from_faces,
)
from synthkit.methods.surfacing.solve import Problem, build_hierarchy, cut_cost, solve_labels, solve_multires
from synthkit.methods.surfacing.strokes import assign_unstroked_components, graph_seeds

__all__ = ["Options", "Segmentation", "segment", "region_costs", "cut_edges", "chain_edges"]


WALL_COST = 1e9
"""Node cost of a region walled off from the node (finite, so costs stay summable in the hierarchy,
and beyond any cut: area-normalised edge costs are of order 1 per edge)."""


@dataclass
class Options:
    """Solver settings (see :mod:`synthkit.methods.surfacing.config` for their meaning)."""

    graph: str
    eta: float
    gamma: float
    region_model: str
    region_weight: float
    concavity: float
    trust: float
    wall_deg: float
    clusters: int
    multires: bool
    coarsest_nodes: int
    ratio: float
    max_levels: int
    band_rings: int
    crease_deg: float
    compare_single_level: bool


@dataclass
class Segmentation:
    """Result: ``face_labels (#F,)``, ``vertex_labels (#V,)``, the graph, its ``seeds (n,)`` and
    ``labels (n,)``, per-level ``levels`` stats (finest first, each with a ``free_faces (#F,) bool``
    mask), ``cut_cost`` (the cost of the graph cut: boundary plus region terms, the energy
    minimised), ``boundary_cost`` (its boundary part), the solver name, timings."""

    face_labels: np.ndarray
    vertex_labels: np.ndarray
    graph: SegGraph
    seeds: np.ndarray
    labels: np.ndarray
    levels: list[dict]
    cut_cost: float
    boundary_cost: float
    solver: str
    unstroked_components: int
    timings: dict = field(default_factory=dict)
    single_level: dict | None = None


def region_costs(graph: SegGraph, seeds, n_labels: int, opt: Options, *, colors=None, rng=None) -> np.ndarray:
    """Node costs ``(n, L)`` of the region model (zeros for ``none``, the paper's energy); the
    geodesic model's are scaled per node by :func:`regions.trust_weights`; a label a node may not
    take by :func:`regions.walled_off` (concave creases sharper than ``wall_deg``) costs
    ``WALL_COST``."""
    if opt.region_model == "none" or opt.region_weight == 0:
        return np.zeros((graph.n, n_labels))
    if opt.region_model == "geodesic":
        extra = opt.concavity * graph.lengths.mean() * np.where(graph.bend < 0, 1 - np.cos(graph.bend), 0.0)
        d = regions.geodesic_distances(graph.points, graph.edges, seeds, n_labels, extra=extra)
        weight = graph.areas * regions.trust_weights(d, opt.trust)
    elif opt.region_model == "color":
        if colors is None:
            raise ValueError("region model 'color' needs vertex colours or a texture, and the mesh has neither")
        d = regions.color_distances(colors, seeds, n_labels, clusters=opt.clusters, rng=rng)
        weight = graph.areas
    else:
        raise ValueError(f"unknown region model {opt.region_model!r}")
    cost = opt.region_weight * weight[:, None] * regions.normalised_cost(d)
    if opt.wall_deg < 180:
        walls = graph.bend < -np.radians(opt.wall_deg)
        cost[regions.walled_off(graph.n, graph.edges, walls, seeds, n_labels)] = WALL_COST
    return cost


def _node_colors(F, colors, kind: str):
    if colors is None:
        return None
    colors = np.asarray(colors, np.float64)
    return colors[np.asarray(F)].mean(axis=1) if kind == "face" else colors


def _to_faces(F, graph: SegGraph, node_mask_or_labels):
    return node_mask_or_labels if graph.kind == "face" else face_labels_from_vertices(F, node_mask_or_labels)


def segment(V, F, vertex_owner, face_owner, n_labels: int, opt: Options, *, colors=None, rng=None) -> Segmentation:
    """Segment the mesh into ``n_labels`` regions from the stroke owners ``vertex_owner (#V,)`` and
    ``face_owner (#F,)`` (-1 unstroked); ``colors (#V, C)`` feed the colour model."""
    timings = {}
    t = time.perf_counter()
    graph = build_graph(V, F, opt.graph, eta=opt.eta, gamma=opt.gamma)
    seeds = graph_seeds(F, opt.graph, vertex_owner, face_owner)
    missing = [r for r in range(n_labels) if not np.any(seeds == r)]
    if missing:
        raise ValueError(f"region {missing[0]} has no stroke left on the {opt.graph} graph")
    seeds, n_unstroked = assign_unstroked_components(graph.points, graph.edges, seeds)
    unary = region_costs(graph, seeds, n_labels, opt, colors=_node_colors(F, colors, opt.graph), rng=rng)
    timings["graph"] = time.perf_counter() - t
    t = time.perf_counter()
    maps = []
    if opt.multires and graph.n > opt.coarsest_nodes:
        per_vertex = 2 if opt.graph == "face" else 1  # a closed mesh has about twice as many faces as vertices
        maps = lod.lod_maps(V, F, opt.graph, coarsest=max(opt.coarsest_nodes // per_vertex, 4), ratio=opt.ratio,
                            max_levels=opt.max_levels)
    problem = Problem(unary, graph.edges, graph.weights, seeds, graph.bend < -np.radians(opt.crease_deg))
    hierarchy = build_hierarchy(problem, maps)
    timings["hierarchy"] = time.perf_counter() - t
    t = time.perf_counter()
    labels, levels = solve_multires(problem, hierarchy, band_rings=opt.band_rings, rng=rng)
    timings["cut"] = time.perf_counter() - t
    for st in levels:
        st["free_faces"] = _to_faces(F, graph, st.pop("free"))
    result = _result(V, F, graph, seeds, labels, unary, n_labels, levels, n_unstroked, timings)
    if opt.compare_single_level and maps:
        t = time.perf_counter()
        single = solve_labels(unary, graph.edges, graph.weights, seeds, rng=rng)
        seconds = time.perf_counter() - t
        fl = _to_faces(F, graph, single)
        result.single_level = {
            "cut_cost": _energy(unary, graph, single),
            "seconds": seconds,
            "face_agreement": float(np.mean(fl == result.face_labels)),
        }
    return result


def _result(V, F, graph, seeds, labels, unary, n_labels, levels, n_unstroked, timings) -> Segmentation:
    fl = _to_faces(F, graph, labels)
    vl = vertex_labels_from_faces(V, F, fl, n_labels) if graph.kind == "face" else labels
    solver = "s-t min cut (exact)" if n_labels == 2 else "alpha-expansion (Potts, within 2x of optimum)"
    return Segmentation(fl, vl, graph, seeds, labels, levels, _energy(unary, graph, labels),
                        cut_cost(labels, graph.edges, graph.weights), solver, n_unstroked, timings)


def _energy(unary, graph: SegGraph, labels) -> float:
    """Boundary plus region cost of ``labels`` (the cost of the corresponding graph cut)."""
    return cut_cost(labels, graph.edges, graph.weights) + float(unary[np.arange(graph.n), labels].sum())


def cut_edges(V, F, face_labels) -> np.ndarray:
    """Mesh edges ``(k, 2)`` between faces of different labels (each once)."""
    pairs, edges = face_adjacency(F)
    cut = face_labels[pairs[:, 0]] != face_labels[pairs[:, 1]]
    return np.unique(edges[cut], axis=0) if cut.any() else np.zeros((0, 2), np.int64)


def chain_edges(edges) -> list[np.ndarray]:
    """Edges ``(k, 2)`` chained into polylines (vertex index arrays); a chain stops where the
    degree is not 2; closed loops repeat their first vertex at the end."""
    edges = np.asarray(edges, np.int64)
    adj: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    used: set[tuple[int, int]] = set()
    chains = []
    starts = [v for v, nb in adj.items() if len(nb) != 2] + list(adj)
    for s in starts:
        for nxt in adj[s]:
            if (min(s, nxt), max(s, nxt)) in used:
                continue
            chain, prev, cur = [s], s, nxt
            used.add((min(s, nxt), max(s, nxt)))
            chain.append(cur)
            while len(adj[cur]) == 2 and cur != s:
                step = adj[cur][0] if adj[cur][0] != prev else adj[cur][1]
                if (min(cur, step), max(cur, step)) in used:
                    break
                used.add((min(cur, step), max(cur, step)))
                prev, cur = cur, step
                chain.append(cur)
            chains.append(np.asarray(chain, np.int64))
    return chains
