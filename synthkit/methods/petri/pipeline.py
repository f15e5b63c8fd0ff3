"""``petri-synth`` run: analysis, construction space, Petri nets, inference, assembly, evaluation."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from synthkit.api import result_fields
from synthkit.core.mesh import merge_vertices, remove_unreferenced, weld
from synthkit.core.quality import WELD_REL_TOL, degenerate_faces, mesh_quality
from synthkit.errors import InputError
from synthkit.io.assets import Asset
from synthkit.io.inputs import Inputs
from synthkit.methods.petri import analysis, construction, network
from synthkit.methods.petri.appearance import Look, example_look
from synthkit.methods.petri.assembly import (
    Assembler,
    PieceLibrary,
    crack_measure,
    crack_measure_graph,
    open_edges_off_border,
    quality_limits,
)
from synthkit.methods.petri.config import PetriConfig
from synthkit.methods.petri.joints import close_t_junctions, repeated_faces
from synthkit.methods.petri.net import (
    ColouredPetriNet,
    adjacency_violations,
    graph_violations,
)
from synthkit.methods.petri.outputs import PetriResult, PreviewScene, result_asset


def analyse_example(V, F, cfg: PetriConfig, look: Look | None = None):
    """Lattice, pieces, labels and constraints of the example (section 2.1); ``look`` the example
    faces' appearance, carried into the pieces."""
    lat = cfg.lattice
    ann = lat.annotation
    spec = analysis.resolve_lattice(
        V.min(axis=0),
        V.max(axis=0),
        unit=lat.unit,
        origin=lat.origin,
        annotation=None if ann is None else (ann.view, ann.rect, ann.depth_unit),
        fit_tolerance=lat.fit_tolerance,
        source=str(cfg.example),
    )
    pieces = analysis.cut_pieces(V, F, spec, caps=lat.caps, look=look)
    features = analysis.feature_vectors(pieces)
    labels, reps = analysis.classify(
        features,
        tolerance=cfg.labels.tolerance,
        pieces=pieces if cfg.labels.match == "geometry" else None,
        seams=[analysis.face_seams(L, Fp) for L, Fp in zip(pieces.local, pieces.faces, strict=True)],
    )
    grid = labels.reshape(tuple(spec.counts))
    cons = analysis.adjacency_constraints(grid, len(reps), boundary=cfg.labels.boundary)
    return spec, pieces, features, grid, reps, cons


def curve_constraints(cfg: PetriConfig, grid: np.ndarray, cons, axis: int):
    """The constraints the target net uses along the curve's world ``axis``, the growth hint for its
    contradiction message (:func:`analysis.growth_hint`) and whether the example's ends were joined
    (``labels.join_ends``; 'auto' joins when the hint says some row cannot grow)."""
    key = unit_key(cfg, axis)
    hint = analysis.growth_hint(grid, cons, axis, key)
    mode = cfg.labels.join_ends
    if cons.boundary and (mode == "always" or (mode == "auto" and hint is not None)):
        joined = analysis.join_ends(cons, axis)
        return joined, analysis.growth_hint(grid, joined, axis, key), True
    return cons, hint, False


def facade_metrics(V, F, assembler: Assembler, grid: np.ndarray, net: ColouredPetriNet, axes) -> dict:
    """Facade figures of the assembled result against the example ``V, F`` (world axes; ``axes`` the
    construction's world axes a, b, c with c up). Facade faces have a normal orthogonal to the up
    axis (:func:`analysis.facade_areas`); facade cells are cell sides facing the outside across a or b
    (:func:`analysis.facade_cells`; the example's ``grid (nx, ny, nz)`` counted the same way); the
    expected area is the example's facade area per facade cell times the result's facade cells. The
    ``_across`` figures take only faces facing across the curve and the sides across b
    (:func:`analysis.facade_areas`): fronts along the curve, not walls between copies."""
    up, b = int(axes[2]), int(axes[1])
    RV, RF, _, face_cell = assembler.mesh()
    ex_cells = sum(2 * grid.size // grid.shape[h] for h in axes[:2])
    ex_across_cells = 2 * grid.size // grid.shape[b]
    e_b = np.zeros((len(F), 3))
    e_b[:, b] = 1.0
    ex_area, ex_across = analysis.facade_areas(V, F, e_b, up)
    C = net.corners
    across = C[:, [2, 3, 6, 7]].mean(axis=1) - C[:, [0, 1, 4, 5]].mean(axis=1)
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-300)
    res_cells = analysis.facade_cells(net.neighbours, range(4))
    res_across_cells = analysis.facade_cells(net.neighbours, (2, 3))
    res_area, res_across = analysis.facade_areas(RV, RF, across[face_cell], up)
    return {
        "facade_area": res_area,
        "facade_area_expected": ex_area / max(ex_cells, 1) * res_cells,
        "facade_cells": res_cells,
        "facade_area_across": res_across,
        "facade_area_across_expected": ex_across / max(ex_across_cells, 1) * res_across_cells,
        "facade_cells_across": res_across_cells,
        "example_facade_area": ex_area,
        "example_facade_cells": int(ex_cells),
        "example_facade_area_across": ex_across,
    }


def origin_preference(grid: np.ndarray) -> list[int]:
    """Labels of the example's pieces ordered by lattice distance from e_000 (e_000's first), unique."""
    idx = np.stack(np.unravel_index(np.arange(grid.size), grid.shape), axis=1)
    order = np.lexsort((idx[:, 2], idx[:, 1], idx[:, 0], np.abs(idx).sum(axis=1)))
    seen, out = set(), []
    for lab in grid.ravel()[order].tolist():
        if lab not in seen:
            seen.add(lab)
            out.append(lab)
    return out


def build_space(cfg: PetriConfig, spec: analysis.LatticeSpec, points=None, cells: int | None = None):
    """Algorithm 1 on the config's curve (or on ``points``) with the lattice's units (and S_X =
    ``cells`` when given)."""
    con = cfg.construction
    axes = construction.PLANE_AXES[con.plane]
    units = spec.unit[list(axes)]
    return construction.build_construction_space(
        con.points if points is None else points,
        plane=con.plane,
        closed=con.closed if points is None else False,
        side=con.side,
        units=units,
        size_y=con.size_y if con.size_y is not None else int(spec.counts[axes[1]]),
        size_z=con.size_z if con.size_z is not None else int(spec.counts[axes[2]]),
        sweep_origin=float(spec.origin[axes[2]]),
        unit_key=unit_key(cfg, axes[0]),
        cells=cells,
    )


def fit_space(cfg: PetriConfig, spec, grid: np.ndarray, cons, space):
    """``space`` with S_X changed to the nearest count every row of the example's ``grid`` along the
    curve takes (``construction.fit_cells``; only when each row can repeat, so the count stays within
    a period of the curve's). Returns ``(space, fitted)``, ``fitted = {"from_length", "to"}`` or None."""
    n0 = space.shape[0]
    if not cfg.construction.fit_cells:
        return space, None
    lo, fits = analysis.row_fits(grid, cons, space.axes[0], n0, closed=space.closed)
    k = None if fits[:, n0 - lo].all() else analysis.nearest_fit(lo, fits, n0)
    if k is None:
        return space, None
    return build_space(cfg, spec, cells=k), {"from_length": int(n0), "to": int(k)}


def unit_key(cfg: PetriConfig, axis: int) -> str:
    """Where the config sets the lattice unit along world ``axis`` (for error messages)."""
    name = "XYZ"[axis]
    ann = cfg.lattice.annotation
    if ann is None:
        return f"lattice.unit[{axis}], along {name}"
    ax, ay, _ = analysis.VIEW_AXES[ann.view]
    if axis == ax:
        return f"the width of lattice.annotation.rect, along {name}"
    if axis == ay:
        return f"the height of lattice.annotation.rect, along {name}"
    if ann.depth_unit is None:
        return f"the example's whole depth along {name}, lattice.annotation.depth_unit: null"
    return f"lattice.annotation.depth_unit, along {name}"


def synthesize(space, cons, library: PieceLibrary, grid, rng, *, max_restarts: int, hint: str | None = None):
    """Target net + Algorithm 2 + deformation. Returns (net, assembler, restarts). ``hint`` is what to
    change when the space cannot be filled at all (see :func:`analysis.growth_hint`)."""
    axes = space.axes
    allowed_t = cons.allowed[list(axes)]
    corners = space.hex_corners()
    net = ColouredPetriNet(
        space.shape,
        allowed_t,
        cons.n_labels,
        boundary=cons.boundary,
        periodic=(space.closed, False, False),
        corners=corners,
    )
    net.unfillable_hint = hint
    return infer_and_deform(net, library, corners, grid, rng, max_restarts=max_restarts)


def infer_and_deform(net: ColouredPetriNet, library: PieceLibrary, corners, grid, rng, *, max_restarts: int):
    """Algorithm 2 on ``net``, its deforming transitions placing pieces into the hexahedra ``corners``
    (the origin cell prefers the example's piece at (0, 0, 0)). Returns (net, assembler, restarts)."""
    assembler = Assembler(library, corners)
    restarts = net.infer(
        rng,
        origin_labels=origin_preference(grid),
        deform=assembler,
        max_restarts=max_restarts,
        on_restart=assembler.clear,
    )
    return net, assembler, restarts


def welded_mesh(assembler: Assembler, seams: np.ndarray, *, weld: bool):
    """The deformed pieces with their seam vertices ``seams (k, 2)`` merged when ``weld`` (faces that
    collapse dropped): the form of mesh the normal histograms of the curved result and of the
    baseline are both taken on. Returns ``(V, F, face_label, face_cell, kept)``, ``kept`` the indices
    of :meth:`Assembler.mesh`'s faces kept."""
    V, F, face_label, face_cell = assembler.mesh()
    kept = np.arange(len(F))
    if weld:
        V, F, keep = weld_seams(V, F, seams)
        kept = kept[keep]
    return V, F, face_label[kept], face_cell[kept], kept


def joined_mesh(assembler: Assembler, welded, graph):
    """The result as written, from its :func:`welded_mesh` ``welded``: walls between cells
    (:func:`drop_inner_walls`, ``graph = (neighbours, back)``), degenerate faces, faces that collapse
    when positions are welded for the quality figures and faces stored twice (:func:`repeated_faces`)
    dropped, then T-junctions closed (:func:`close_t_junctions`) and unused vertices dropped.
    Returns ``(V, F, face_label, look, cls)`` (``look`` None without the example's look; ``cls (#V,)``
    the positions' weld classes)."""
    V, F, face_label, face_cell, kept = welded
    look = assembler.look()
    tol = WELD_REL_TOL * float(np.linalg.norm(np.ptp(V, axis=0))) if len(V) else 0.0
    cls = weld_classes(V, tol)
    walls = drop_inner_walls(V, F, cls, face_cell, assembler.face_sides()[kept], graph, tol)
    W = cls[F]
    collapsed = (W[:, 0] == W[:, 1]) | (W[:, 1] == W[:, 2]) | (W[:, 2] == W[:, 0])
    keep = ~walls & ~degenerate_faces(V, F) & ~collapsed & ~repeated_faces(W)
    F, face_label, face_cell, kept = F[keep], face_label[keep], face_cell[keep], kept[keep]
    look = None if look is None else look.take(kept)
    # after the drops: a zero-area face that filled a T-junction leaves it to be closed here; the fans
    # keep their face's height and split edges at vertices more than ``tol`` apart, so none is degenerate
    F, _, (face_label,), look = close_t_junctions(V, F, face_cell, [face_label], look, tol, cls=cls)
    V, F, used = remove_unreferenced(V, F)
    return V, F, face_label, look, cls[used]


def grid_graph(net: ColouredPetriNet):
    """``(neighbours (N, 6), back (N, 6))`` of a grid net (directions 2 axis + 0 for +axis, + 1 for -axis)."""
    nbr = np.asarray(net.neighbours)
    return nbr, np.broadcast_to(np.arange(6) ^ 1, nbr.shape)


def weld_classes(V: np.ndarray, tol: float) -> np.ndarray:
    """``(#V,)``: the class of each position of ``V`` once positions within ``tol`` are welded."""
    return weld(V, np.zeros((0, 3), np.int64), tol, return_index=True)[2]


def drop_inner_walls(V, F, cls, face_cell, face_side, graph, tol: float) -> np.ndarray:
    """``(#F,) bool``: walls inside the result where two pieces stand back to back (copies of the
    example side by side: the end of one house's plate against the start of the next one's).

    ``cls (#V,)`` are the weld classes of ``V`` (within ``tol``). A wall is the faces of one cell
    (``face_cell (#F,)``) lying on one of its cell's faces
    (``face_side (#F,)``, :func:`assembly.face_sides`); where the neighbour across that face
    (``graph = (neighbours (N, 6), back (N, 6))``) has a wall on the face it shares, each connected part
    of the one covering the same region as a part of the other (:func:`_same_region`; they may be
    triangulated differently) is dropped with it."""
    nbr, back = graph
    out = np.zeros(len(F), bool)
    on = np.flatnonzero(face_side >= 0)
    if len(on) == 0:
        return out
    side = face_side[on]
    d = 2 * (side >> 1) + 1 - (side & 1)
    cell = face_cell[on]
    other = nbr[cell, d]
    walls: dict = {}
    for i in np.flatnonzero(other >= 0).tolist():
        walls.setdefault((int(cell[i]), int(d[i])), []).append(int(on[i]))
    T = V[F]
    area = np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    for (c, dc), idx in walls.items():
        n = int(nbr[c, dc])
        idx2 = walls.get((n, int(back[c, dc])))
        if n < c or not idx2:
            continue
        parts2 = _face_components(cls[F[idx2]], np.asarray(idx2))
        for part in _face_components(cls[F[idx]], np.asarray(idx)):
            for k, part2 in enumerate(parts2):
                if _same_region(T[part], area[part], T[part2], area[part2], tol):
                    out[part] = out[part2] = True
                    parts2.pop(k)
                    break
    return out


def _face_components(W: np.ndarray, idx: np.ndarray) -> list[np.ndarray]:
    """The faces ``idx (k,)`` grouped into connected pieces by their welded corners ``W (k, 3)``."""
    _, inv = np.unique(W, return_inverse=True)
    inv = inv.reshape(W.shape)
    k, n = len(W), int(inv.max()) + 1
    rows = np.repeat(np.arange(k), 3)
    graph = csr_matrix((np.ones(3 * k), (rows, k + inv.ravel())), shape=(k + n, k + n))
    _, comp = connected_components(graph, directed=False)
    return [idx[comp[:k] == c] for c in np.unique(comp[:k])]


def _same_region(Ta, area_a, Tb, area_b, tol: float) -> bool:
    """Whether two sets of coplanar triangles ``(k, 3, 3)`` (their doubled areas ``(k,)``) cover the same
    region: the same area (to 1e-6) and the same bounding box (within ``tol``)."""
    a, b = float(area_a.sum()), float(area_b.sum())
    if abs(a - b) > 1e-6 * max(a, b):
        return False
    Pa, Pb = Ta.reshape(-1, 3), Tb.reshape(-1, 3)
    return bool(np.abs(Pa.min(0) - Pb.min(0)).max() <= tol and np.abs(Pa.max(0) - Pb.max(0)).max() <= tol)


def require_faces(F: np.ndarray, cfg: PetriConfig) -> None:
    """Refuse (exit 3) a result without faces: every cell took an empty piece of the example."""
    if len(F) == 0:
        raise InputError(
            f"{cfg.example}: petri-synth: every cell took an empty piece of the example, so the result has "
            "no faces (choose a lattice whose pieces hold the model's surface)"
        )


def weld_seams(V, F, seams):
    """Merge the matched seam vertices ``seams`` of ``V (n, 3)``, ``F (m, 3)``; faces that collapse
    are dropped. Returns ``(V, F, keep (m,) bool)``, ``keep`` the faces kept."""
    V, F2, old_to_new = merge_vertices(V, F, seams, return_index=True)
    G = old_to_new[F]
    keep = (G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 2] != G[:, 0])
    return V, F2, keep


def check_result_quality(ctx, asset: Asset, V, F, library: PieceLibrary, labels, neighbours) -> None:
    """``ctx.check_quality`` of the written result against the example, with petri-synth's limits
    (:func:`assembly.quality_limits`: what the placed pieces bring themselves, plus the open cuts on
    the construction space's border; no degenerate face)."""
    before = mesh_quality(asset.V, asset.F)
    limits = {**quality_limits(library, labels, neighbours), "degenerate_faces": 0}
    ctx.check_quality("mesh", before, mesh_quality(V, F), limits)


def example_net(grid: np.ndarray, cons, spec) -> ColouredPetriNet:
    """The example Petri net: one local net per piece, tokens holding its coordinate and label."""
    lo = spec.origin
    n = grid.size
    idx = np.stack(np.unravel_index(np.arange(n), grid.shape), axis=1)
    corners = np.empty((n, 8, 3))
    for c in range(8):
        off = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
        corners[:, c] = lo + (idx + off) * spec.unit
    net = ColouredPetriNet(grid.shape, cons.allowed, cons.n_labels, boundary=cons.boundary, corners=corners)
    for c, lab in enumerate(grid.ravel().tolist()):
        net.cand[c] = 1 << lab
        net.label[c] = lab
        net.state[c] = 3
    return net


def _lines_of_space(space, *, z_index: int = 0) -> np.ndarray:
    """Segments ``(k, 2, 3)`` of the construction plane's cell edges at one sweep level, plus the curve."""
    G = space.grid
    w = space.sweep[z_index]
    W = space.world(G, np.full(G.shape[:2], w))
    segs = []
    nI, nJ = G.shape[:2]
    rows = np.arange(nI) if space.closed else np.arange(nI - 1)
    for j in range(nJ):
        segs.append(np.stack([W[rows, j], W[(rows + 1) % nI, j]], axis=1))
    for i in range(nI):
        segs.append(np.stack([W[i, :-1], W[i, 1:]], axis=1))
    curve = space.curve if not space.closed else np.vstack([space.curve, space.curve[:1]])
    C = space.world(curve, np.full(len(curve), w))
    segs.append(np.stack([C[:-1], C[1:]], axis=1))
    return np.concatenate(segs)


def run_baseline(cfg, ctx, spec, cons, library, grid, straight, h_ex, plane_axes, metrics, *, what: str):
    """Model synthesis on the orthogonal lattice (no curve, Merrell-style) along the polyline
    ``straight``, in the same code path; its figures go to ``metrics["baseline"]`` and
    ``metrics["baseline_normal_histogram_D"]``. Returns the baseline's net."""
    bspace = build_space(cfg, spec, points=straight)
    bnet, bassembler, brestarts = synthesize(
        bspace, cons, library, grid, ctx.rng, max_restarts=cfg.inference.max_restarts
    )
    _, _, seams, _ = crack_measure(library, bnet.label_grid(), bnet.corners, periodic=bnet.periodic,
                                   offsets=bassembler.offsets(bnet.n_cells))
    BV, BF, *_ = welded_mesh(bassembler, seams, weld=cfg.output.weld)
    h_base = analysis.normal_histogram(BV, BF, plane_axes)
    metrics["baseline"] = {
        "method": f"model synthesis on the orthogonal lattice ({what})",
        "normal_histogram_D": analysis.histogram_discrimination(h_ex, h_base),
        "normal_histogram": h_base,
        "adjacency_violations": adjacency_violations(
            bnet.label_grid(), bnet.allowed, cons.n_labels, boundary=cons.boundary
        ),
        "restarts": int(brestarts),
    }
    metrics["baseline_normal_histogram_D"] = metrics["baseline"]["normal_histogram_D"]
    return bnet


def _result_metrics(V, F, RV, RF, space, net, spec, cons, grid, library, labels_out, *, assembler, restarts,
                    violations, gap, unmatched, deviation, cls, welded) -> tuple[np.ndarray, dict]:
    """The metrics a single-curve and a network run share, and the example's normal histogram
    (the baseline compares against it): the result ``RV, RF`` against the example ``V, F``, the
    net's labels ``labels_out`` (any shape) and the assembly's crack ``gap`` (lattice units) and ``unmatched``
    boundary vertices; ``cls`` the weld classes of ``RV``; ``welded`` the :func:`welded_mesh` the
    normal histogram is taken on (as the baseline's)."""
    plane_axes = space.point_axes
    h_ex = analysis.normal_histogram(V, F, plane_axes)
    h_res = analysis.normal_histogram(welded[0], welded[1], plane_axes)
    return h_ex, {
        "labels": int(cons.n_labels),
        "example_pieces": int(grid.size),
        "example_lattice": {"unit": spec.unit, "origin": spec.origin, "counts": spec.counts},
        "transitions": dict(net.fired),
        "restarts": int(restarts),
        "adjacency_violations": int(violations),
        "unfilled_cells": int((labels_out < 0).sum()),
        "empty_cells": int(sum(len(library.faces[lab]) == 0 for lab in labels_out.ravel().tolist())),
        "crack_max": gap,
        "boundary_unmatched_vertices": int(unmatched),
        "curve_max_deviation": float(deviation.max()),
        "normal_histogram_D": analysis.histogram_discrimination(h_ex, h_res),
        "normal_histogram_example": h_ex,
        "normal_histogram_result": h_res,
        "open_edges_off_border": open_edges_off_border(
            RV, RF, net.corners, net.neighbours, WELD_REL_TOL * float(np.linalg.norm(np.ptp(RV, axis=0))), cls=cls
        ),
        "result_vertices": int(len(RV)),
        "result_faces": int(len(RF)),
        **facade_metrics(V, F, assembler, grid, net, space.axes),
    }


CELL_BYTES = 4096
"""Bytes per construction cell besides its piece geometry: places, tokens, candidate sets (estimate)."""
GEOMETRY_COPIES = 3
"""Copies of a piece's geometry a cell holds while it is deformed, assembled and welded."""


def check_construction_budget(budget, cfg: PetriConfig, spec, V: np.ndarray, F: np.ndarray, n_pieces: int) -> None:
    """Refuse a curve whose cells (S_X S_Y S_Z over every curve), each with its deformed piece,
    exceed the memory budget, before the construction space is built."""
    con = cfg.construction
    axes = construction.PLANE_AXES[con.plane]
    unit = float(spec.unit[axes[0]])
    curves = [(c.points, c.closed) for c in con.curves] if con.curves is not None else [(con.points, con.closed)]
    length = 0.0
    for points, closed in curves:
        P = np.asarray(points, np.float64)
        if closed:
            P = np.vstack([P, P[:1]])
        length += float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
    size_y = con.size_y if con.size_y is not None else int(spec.counts[axes[1]])
    size_z = con.size_z if con.size_z is not None else int(spec.counts[axes[2]])
    cells = (length / unit + 0.5) * size_y * size_z
    piece_bytes = (V.nbytes + F.nbytes) / max(n_pieces, 1) * GEOMETRY_COPIES
    key = "construction.curves" if con.curves is not None else "construction.points"
    budget.require(key, f"{length:.6g} units long", cells, "cells", bytes_each=CELL_BYTES + piece_bytes)


def compute(cfg: PetriConfig, inputs: Inputs, ctx) -> PetriResult:
    """All stages of a run on the example read through ``inputs``; writes nothing (:class:`PetriResult`)."""
    with ctx.stage("load"):
        asset = inputs.asset(cfg.example)
        V, F = asset.V, asset.F
        look = example_look(asset.corner_uv, asset.corner_color, asset.face_material, len(F))

    with ctx.stage("analysis"):
        spec, pieces, features, grid, reps, cons = analyse_example(V, F, cfg, look)

    check_construction_budget(ctx.budget, cfg, spec, V, F, len(pieces.index))
    cons, hint, joined = curve_constraints(cfg, grid, cons, construction.PLANE_AXES[cfg.construction.plane][0])
    ctx.metrics["joined_ends"] = joined
    if cfg.construction.curves is not None:
        return compute_network(cfg, ctx, inputs, asset, spec, pieces, features, grid, reps, cons)

    with ctx.stage("construction"):
        space = build_space(cfg, spec)
        fitted = None
        if hint is None:
            space, fitted = fit_space(cfg, spec, grid, cons, space)
        ctx.metrics["fitted_cells"] = fitted
        deviation = space.center_deviation()

    axes = space.axes
    library = PieceLibrary(pieces, reps, axes)
    with ctx.stage("inference"):
        if hint is None:
            hint = analysis.length_hint(grid, cons, axes[0], space.shape[0], closed=space.closed,
                                        unit=float(space.units[0]))
        net, assembler, restarts = synthesize(
            space, cons, library, grid, ctx.rng, max_restarts=cfg.inference.max_restarts, hint=hint
        )
    labels_out = net.label_grid()

    with ctx.stage("assembly"):
        gap, unmatched, seams, mismatch = crack_measure(
            library, labels_out, net.corners, periodic=net.periodic, offsets=assembler.offsets(net.n_cells)
        )
        welded = welded_mesh(assembler, seams, weld=cfg.output.weld)
        RV, RF, face_label, look, cls = joined_mesh(assembler, welded, grid_graph(net))
        require_faces(RF, cfg)
        check_result_quality(ctx, asset, RV, RF, library, labels_out.ravel(), net.neighbours)
        labels_doc = _labels_doc(labels_out, grid, cons, space, spec, features, reps)

    with ctx.stage("evaluation"):
        violations = adjacency_violations(
            labels_out, net.allowed, cons.n_labels, boundary=cons.boundary, periodic=net.periodic
        )
        plane_axes = space.point_axes
        h_ex, shared = _result_metrics(V, F, RV, RF, space, net, spec, cons, grid, library, labels_out,
                                       assembler=assembler,
                                       restarts=restarts, violations=violations,
                                       gap=max(gap / float(spec.unit.min()), mismatch), unmatched=unmatched,
                                       deviation=deviation, cls=cls, welded=welded)
        metrics = {"cells": int(net.n_cells), "construction_shape": list(space.shape), **shared}

    bnet = None
    if cfg.output.baseline:
        with ctx.stage("baseline"):
            P0 = np.asarray(cfg.construction.points[0], np.float64)
            straight = [P0, P0 + [space.shape[0] * space.units[0], 0.0]]
            bnet = run_baseline(cfg, ctx, spec, cons, library, grid, straight, h_ex, plane_axes, metrics,
                                what="straight curve of the same length")

    ctx.metrics.update(metrics)
    scene = PreviewScene(PieceLibrary(pieces, reps, (0, 1, 2)), grid, axes, _lines_of_space(space),
                         cfg.construction.plane)
    return _result(cfg, ctx, inputs, asset, (RV, RF, face_label, look), labels_out, labels_doc,
                   (net, example_net(grid, cons, spec), bnet), scene)


def _result(cfg, ctx, inputs, asset: Asset, mesh, labels_out, labels_doc, nets, scene) -> PetriResult:
    """The :class:`PetriResult` of a run: ``mesh = (V, F, face_label, look)``, ``nets = (target,
    example, baseline)``."""
    V, F, face_label, look = mesh
    net, ex_net, bnet = nets
    return PetriResult(**result_fields(cfg, ctx, inputs), mesh=trimesh.Trimesh(V, F, process=False),
                       asset=result_asset(asset, V, F, look), face_labels=face_label, label_grid=labels_out,
                       labels=labels_doc, target_net=net, example_net=ex_net, baseline_net=bnet, example=asset,
                       look=look, scene=scene)


def run(cfg: PetriConfig, ctx) -> None:
    """The command line's run: :func:`compute` on the config's files, then the result's files."""
    compute(cfg, Inputs(), ctx).write(ctx)


def _example_doc(grid, cons, spec, features, reps) -> dict:
    """The part of ``labels.json`` that describes the example: its label grid and lattice, each
    label's representative piece and feature vector, and the adjacency constraints."""
    return {
        "example": {
            "shape": list(grid.shape),
            "grid": grid.tolist(),
            "unit": spec.unit.tolist(),
            "origin": spec.origin.tolist(),
        },
        "labels": [
            {
                "label": k,
                "piece": [int(v) for v in np.unravel_index(int(r), grid.shape)],
                "feature": features[r].tolist(),
            }
            for k, r in enumerate(reps)
        ],
        "constraints": {
            "outside_label": cons.out if cons.boundary else None,
            "pairs": {"XYZ"[axis]: np.argwhere(cons.allowed[axis]).tolist() for axis in range(3)},
        },
    }


def _labels_doc(labels_out, grid, cons, space, spec, features, reps) -> dict:
    """``labels.json`` of a single-curve run."""
    return {
        "format": "petri-synth label grid: grid[i][j][k], i along the curve, j across, k along the sweep",
        "shape": list(labels_out.shape),
        "axes": {"a": "XYZ"[space.axes[0]], "b": "XYZ"[space.axes[1]], "c": "XYZ"[space.axes[2]]},
        "closed": bool(space.closed),
        "grid": labels_out.tolist(),
        **_example_doc(grid, cons, spec, features, reps),
    }


# ---------------------------------------------------------------------------------------- networks
def build_network_space(cfg: PetriConfig, spec: analysis.LatticeSpec) -> network.NetworkSpace:
    """:func:`network.build_network` on the config's ``construction.curves`` with the lattice's units."""
    con = cfg.construction
    axes = construction.PLANE_AXES[con.plane]
    return network.build_network(
        [(c.points, c.closed) for c in con.curves],
        plane=con.plane,
        side=con.side,
        units=spec.unit[list(axes)],
        size_y=con.size_y if con.size_y is not None else int(spec.counts[axes[1]]),
        size_z=con.size_z if con.size_z is not None else int(spec.counts[axes[2]]),
        sweep_origin=float(spec.origin[axes[2]]),
        unit_key=unit_key(cfg, axes[0]),
    )


def synthesize_network(space: network.NetworkSpace, cons, library: PieceLibrary, grid, rng, *, max_restarts: int):
    """Target net over the network's neighbour graph + Algorithm 2 + deformation: (net, assembler, restarts)."""
    allowed_t = cons.allowed[list(space.axes)]
    corners = space.hex_corners()
    nbr, back, _, coords = space.graph()
    net = ColouredPetriNet(
        (space.n_cells, 1, 1),
        allowed_t,
        cons.n_labels,
        boundary=cons.boundary,
        corners=corners,
        graph=(nbr, back, coords, space.describe),
    )
    return infer_and_deform(net, library, corners, grid, rng, max_restarts=max_restarts)


def network_metrics(space: network.NetworkSpace, net: ColouredPetriNet, library: PieceLibrary, assembler) -> dict:
    """Quality figures of a network run, overall and at the junctions (cells of junction parts and their
    neighbours across a frame change)."""
    nbr, back, flip, _ = space.graph()
    labels = np.asarray(net.label, np.int64)
    gap, unmatched, seams, mismatch = crack_measure_graph(
        library, labels, net.corners, (nbr, back, flip), offsets=assembler.offsets(net.n_cells)
    )
    SZ = space.size_z
    junction_plane = np.array([space.parts[p]["kind"] == "junction" for p in space.cell_part.tolist()])
    in_junction = np.repeat(junction_plane, SZ)
    across = (nbr >= 0) & (back != (np.arange(6) ^ 1)[None])
    touched = in_junction | across.any(axis=1)
    sub = np.where(touched[:, None], nbr, -1)
    sub = np.where((sub >= 0) & (touched[np.maximum(sub, 0)] | touched[:, None]), sub, -1)
    jviol = graph_violations(labels, sub, back, net.allowed, net.n_labels, boundary=False)
    jgap, junmatched, _, jmismatch = crack_measure_graph(library, labels, net.corners, (sub, back, flip))
    return {
        "gap": gap,
        "mismatch": mismatch,
        "unmatched": unmatched,
        "seams": seams,
        "junction_cells": int(in_junction.sum()),
        "junction_adjacency_violations": int(jviol),
        "junction_gap": jgap,
        "junction_mismatch": jmismatch,
        "junction_unmatched": int(junmatched),
    }


def compute_network(cfg: PetriConfig, ctx, inputs: Inputs, asset: Asset, spec, pieces, features, grid, reps,
                    cons) -> PetriResult:
    """The run of :func:`compute` for a curve network (``construction.curves``)."""
    V, F = asset.V, asset.F
    with ctx.stage("construction"):
        space = build_network_space(cfg, spec)
        deviation = space.center_deviation()

    axes = space.axes
    library = PieceLibrary(pieces, reps, axes)
    with ctx.stage("inference"):
        net, assembler, restarts = synthesize_network(
            space, cons, library, grid, ctx.rng, max_restarts=cfg.inference.max_restarts
        )
    labels_out = np.asarray(net.label, np.int64)

    with ctx.stage("assembly"):
        jm = network_metrics(space, net, library, assembler)
        welded = welded_mesh(assembler, jm["seams"], weld=cfg.output.weld)
        RV, RF, face_label, look, cls = joined_mesh(assembler, welded, space.graph()[:2])
        require_faces(RF, cfg)
        check_result_quality(ctx, asset, RV, RF, library, labels_out, net.neighbours)
        labels_doc = _network_labels_doc(labels_out, grid, cons, space, spec, features, reps)

    with ctx.stage("evaluation"):
        nbr, back, _, _ = space.graph()
        violations = graph_violations(labels_out, nbr, back, net.allowed, cons.n_labels, boundary=cons.boundary)
        plane_axes = space.point_axes
        h_ex, shared = _result_metrics(V, F, RV, RF, space, net, spec, cons, grid, library, labels_out,
                                       assembler=assembler,
                                       restarts=restarts, violations=violations,
                                       gap=max(jm["gap"] / float(spec.unit.min()), jm["mismatch"]),
                                       unmatched=jm["unmatched"], deviation=deviation, cls=cls, welded=welded)
        metrics = {
            "cells": int(net.n_cells),
            "construction_shape": {
                "parts": [{k: v for k, v in p.items() if k != "name"} | {"name": p["name"]} for p in space.parts],
                "size_y": space.size_y,
                "size_z": space.size_z,
            },
            "curves": len(space.curves),
            "junctions": len(space.junctions),
            "junction_cells": jm["junction_cells"],
            "junction_adjacency_violations": jm["junction_adjacency_violations"],
            "junction_crack_max": max(jm["junction_gap"] / float(spec.unit.min()), jm["junction_mismatch"]),
            "junction_unmatched_vertices": jm["junction_unmatched"],
            **shared,
        }

    bnet = None
    if cfg.output.baseline:
        with ctx.stage("baseline"):
            P0 = np.asarray(cfg.construction.curves[0].points[0], np.float64)
            along = max(1, space.n_plane // space.size_y)
            straight = [P0, P0 + [along * space.units[0], 0.0]]
            bnet = run_baseline(cfg, ctx, spec, cons, library, grid, straight, h_ex, plane_axes, metrics,
                                what="a straight curve with as many cells")

    ctx.metrics.update(metrics)
    w = space.sweep[0]
    segs = space.plane_segments()
    lines = [space.world(segs, np.full(segs.shape[:2], w))]
    for P, closed in zip(space.curves, space.closed, strict=True):
        C = np.vstack([P, P[:1]]) if closed else P
        C = space.world(C, np.full(len(C), w))
        lines.append(np.stack([C[:-1], C[1:]], axis=1))
    scene = PreviewScene(PieceLibrary(pieces, reps, (0, 1, 2)), grid, axes, np.concatenate(lines),
                         cfg.construction.plane)
    return _result(cfg, ctx, inputs, asset, (RV, RF, face_label, look), labels_out, labels_doc,
                   (net, example_net(grid, cons, spec), bnet), scene)


def _network_labels_doc(labels_out, grid, cons, space: network.NetworkSpace, spec, features, reps) -> dict:
    """``labels.json`` of a curve-network run."""
    SZ = space.size_z
    L = labels_out.reshape(space.n_plane, SZ)
    parts = []
    first = 0
    for idx, p in enumerate(space.parts):
        n = int(np.prod(p["shape"]))
        q = np.flatnonzero(space.cell_part == idx)
        assert len(q) == n and q[0] == first
        parts.append(dict(p, grid=L[q].reshape(p["shape"][0], p["shape"][1], SZ).tolist()))
        first += n
    return {
        "format": "petri-synth curve network: per part (arm of a curve or junction of two) grid[i][j][k], i along "
        "the part's curve (a junction: along its first curve), j across, k along the sweep",
        "axes": {"a": "XYZ"[space.axes[0]], "b": "XYZ"[space.axes[1]], "c": "XYZ"[space.axes[2]]},
        "parts": parts,
        "junctions": [{"curves": [a, b], "point": pt} for a, b, pt in space.junctions],
        **_example_doc(grid, cons, spec, features, reps),
    }
