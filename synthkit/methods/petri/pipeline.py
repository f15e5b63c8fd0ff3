"""``petri-synth`` run: analysis, construction space, Petri nets, inference, assembly, evaluation.

One run for a single curve and a curve network (:mod:`.spaces`). The only module of the method that
knows config keys and exit codes: the stages raise :class:`~synthkit.errors.KeyedError` (a config error) or
:class:`~.net.Unfillable` (an input error), mapped here by :func:`synthkit.errors.refusals`.
"""

from __future__ import annotations

import numpy as np
import trimesh

from synthkit.asset import Asset
from synthkit.core.quality import mesh_quality
from synthkit.errors import InputError, refusals
from synthkit.io.inputs import Inputs
from synthkit.methods.petri import analysis
from synthkit.methods.petri.appearance import example_look
from synthkit.methods.petri.assembly import Assembler, PieceLibrary, quality_limits
from synthkit.methods.petri.config import PetriConfig
from synthkit.methods.petri.construction import build_construction_space
from synthkit.methods.petri.curves import PLANE_AXES
from synthkit.methods.petri.evaluation import (
    Synthesis,
    example_doc,
    example_net,
    origin_preference,
    result_metrics,
)
from synthkit.methods.petri.joints import joined_mesh, welded_mesh
from synthkit.methods.petri.network import build_network
from synthkit.methods.petri.options import curves_of, options_of, unit_key
from synthkit.methods.petri.outputs import PetriResult, PreviewScene, result_asset
from synthkit.methods.petri.spaces import CurveSpace, NetworkSpace, Space
from synthkit.result import result_fields

__all__ = ["compute"]


def curve_constraints(cfg: PetriConfig, ex: analysis.Example, axis: int):
    """The constraints the target net uses along the curve's world ``axis``, the growth hint for its
    contradiction message (:func:`analysis.growth_hint`) and whether the example's ends were joined
    (``labels.join_ends``; 'auto' joins when the hint says some row cannot grow)."""
    key = unit_key(cfg, axis)
    cons, grid = ex.cons, ex.grid
    hint = analysis.growth_hint(grid, cons, axis, key)
    mode = cfg.labels.join_ends
    if cons.boundary and (mode == "always" or (mode == "auto" and hint is not None)):
        joined = analysis.join_ends(cons, axis)
        return joined, analysis.growth_hint(grid, joined, axis, key), True
    return cons, hint, False


def build_space(cfg: PetriConfig, ex: analysis.Example, cons, hint: str | None, ctx) -> tuple[Space, str | None]:
    """The construction space of the config's curve or network (Algorithm 1) and the hint for an
    unfillable one. A single curve's S_X is fitted to the example's rows (``construction.fit_cells``,
    reported as ``metrics.fitted_cells``) unless some row cannot repeat at all (``hint``)."""
    opts = options_of(cfg).space(ex.spec)
    if cfg.construction.curves is not None:
        return NetworkSpace(build_network(curves_of(cfg), opts)), hint
    points, closed = curves_of(cfg)[0]
    space = build_construction_space(points, closed, opts)
    fitted = None
    if hint is None and cfg.construction.fit_cells:
        n0 = space.shape[0]
        lo, fits = analysis.row_fits(ex.grid, cons, space.axes[0], n0, closed=space.closed)
        k = None if fits[:, n0 - lo].all() else analysis.nearest_fit(lo, fits, n0)
        if k is not None:
            space = build_construction_space(points, closed, opts, cells=k)
            fitted = {"from_length": int(n0), "to": int(k)}
    ctx.metrics["fitted_cells"] = fitted
    if hint is None:
        hint = analysis.length_hint(ex.grid, cons, space.axes[0], space.shape[0], closed=space.closed,
                                    unit=float(space.units[0]))
    return CurveSpace(space), hint


def synthesize(space: Space, cons, library: PieceLibrary, grid, rng, max_restarts: int, hint: str | None):
    """Target net + Algorithm 2, its deforming transitions placing pieces into the cells (the origin
    cell prefers the example's piece at (0, 0, 0)). ``hint`` is what to change when the space cannot
    be filled at all (:func:`analysis.growth_hint`). Returns a :class:`Synthesis` without meshes."""
    net = space.make_net(cons, hint)
    assembler = Assembler(library, net.corners)
    restarts = net.infer(rng, origin_labels=origin_preference(grid), deform=assembler, max_restarts=max_restarts,
                         on_restart=assembler.clear)
    return Synthesis(net, assembler, restarts, space.labels_of(net))


def require_faces(F: np.ndarray, source: str) -> None:
    """Refuse (exit 3) a result without faces: every cell took an empty piece of the example
    (``source``: what the line starts with, the example's file)."""
    if len(F) == 0:
        raise InputError(
            f"{source}petri-synth: every cell took an empty piece of the example, so the result has "
            "no faces (choose a lattice whose pieces hold the model's surface)"
        )


def check_result_quality(ctx, asset: Asset, V, F, library: PieceLibrary, labels, neighbours) -> None:
    """``ctx.check_quality`` of the written result against the example, with petri-synth's limits
    (:func:`assembly.quality_limits`: what the placed pieces bring themselves, plus the open cuts on
    the construction space's border; no degenerate face)."""
    before = mesh_quality(asset.V, asset.F)
    limits = {**quality_limits(library, labels, neighbours), "degenerate_faces": 0}
    ctx.check_quality("mesh", before, mesh_quality(V, F), limits)


def run_baseline(cfg: PetriConfig, ctx, ex: analysis.Example, cons, library, space: Space, h_ex):
    """Model synthesis on the orthogonal lattice (no curve, Merrell-style) along a straight curve from
    the first curve's first point (:meth:`Space.straight_length`), in the same code path. Returns its
    figures (``metrics["baseline"]`` and ``metrics["baseline_normal_histogram_D"]``) and its net."""
    P0 = np.asarray(curves_of(cfg)[0][0][0], np.float64)
    length, what = space.straight_length()
    bspace = CurveSpace(build_construction_space([P0, P0 + [length, 0.0]], False, options_of(cfg).space(ex.spec)))
    base = synthesize(bspace, cons, library, ex.grid, ctx.rng, cfg.inference.max_restarts, None)
    seams = bspace.cracks(library, base.net, base.assembler)["seams"]
    BV, BF, *_ = welded_mesh(base.assembler, seams, weld=cfg.output.weld)
    h_base = analysis.normal_histogram(BV, BF, space.point_axes)
    figures = {
        "method": f"model synthesis on the orthogonal lattice ({what})",
        "normal_histogram_D": analysis.histogram_discrimination(h_ex, h_base),
        "normal_histogram": h_base,
        "adjacency_violations": bspace.violations(base.labels, base.net, cons),
        "restarts": int(base.restarts),
    }
    return {"baseline": figures, "baseline_normal_histogram_D": figures["normal_histogram_D"]}, base.net


CELL_BYTES = 4096
"""Bytes per construction cell besides its piece geometry: places, tokens, candidate sets (estimate)."""
GEOMETRY_COPIES = 3
"""Copies of a piece's geometry a cell holds while it is deformed, assembled and welded."""


def check_construction_budget(budget, cfg: PetriConfig, spec, V: np.ndarray, F: np.ndarray, n_pieces: int) -> None:
    """Refuse a curve whose cells (S_X S_Y S_Z over every curve), each with its deformed piece,
    exceed the memory budget, before the construction space is built."""
    opts = options_of(cfg).space(spec)
    length = 0.0
    for points, closed in curves_of(cfg):
        P = np.asarray(points, np.float64)
        if closed:
            P = np.vstack([P, P[:1]])
        length += float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
    cells = (length / float(opts.units[0]) + 0.5) * opts.size_y * opts.size_z
    piece_bytes = (V.nbytes + F.nbytes) / max(n_pieces, 1) * GEOMETRY_COPIES
    key = "construction.curves" if cfg.construction.curves is not None else "construction.points"
    budget.require(key, f"{length:.6g} units long", cells, "cells", bytes_each=CELL_BYTES + piece_bytes)


def compute(cfg: PetriConfig, inputs: Inputs, ctx) -> PetriResult:
    """All stages of a run on the example read through ``inputs``; writes nothing (:class:`PetriResult`)."""
    with ctx.stage("load"):
        asset = inputs.asset(cfg.example)
        V, F = asset.V, asset.F
        look = example_look(asset.corner_uv, asset.corner_color, asset.face_material, len(F))
    source = "" if inputs.is_memory(cfg.example) else f"{cfg.example}: "
    with ctx.stage("analysis"), refusals(source, "lattice"):
        ex = analysis.analyse(V, F, options_of(cfg).lattice, look)
    check_construction_budget(ctx.budget, cfg, ex.spec, V, F, len(ex.pieces.index))
    cons, hint, joined = curve_constraints(cfg, ex, PLANE_AXES[cfg.construction.plane][0])
    ctx.metrics["joined_ends"] = joined
    with ctx.stage("construction"), refusals(section="construction"):
        space, hint = build_space(cfg, ex, cons, hint, ctx)
    library = PieceLibrary(ex.pieces, ex.reps, space.axes)
    with ctx.stage("inference"), refusals(section="inference"):
        syn = synthesize(space, cons, library, ex.grid, ctx.rng, cfg.inference.max_restarts, hint)
    with ctx.stage("assembly"):
        cracks = space.cracks(library, syn.net, syn.assembler)
        syn.welded = welded_mesh(syn.assembler, cracks["seams"], weld=cfg.output.weld)
        syn.result = joined_mesh(syn.assembler, syn.welded, space.graph(syn.net))
        RV, RF, face_label, look, _ = syn.result
        require_faces(RF, source)
        check_result_quality(ctx, asset, RV, RF, library, syn.labels.ravel(), syn.net.neighbours)
    with ctx.stage("evaluation"):
        h_ex, shared = result_metrics(V, F, ex, space, syn, library, cracks, cons)
        metrics = {**space.shape_metrics(syn.net, cracks, float(ex.spec.unit.min())), **shared}
    bnet = None
    if cfg.output.baseline:
        with ctx.stage("baseline"), refusals(section="construction"):
            figures, bnet = run_baseline(cfg, ctx, ex, cons, library, space, h_ex)
            metrics.update(figures)
    ctx.metrics.update(metrics)
    scene = PreviewScene(PieceLibrary(ex.pieces, ex.reps, (0, 1, 2)), ex.grid, space.axes, space.lines(),
                         cfg.construction.plane)
    return PetriResult(**result_fields(cfg, ctx, inputs), mesh=trimesh.Trimesh(RV, RF, process=False),
                       asset=result_asset(asset, RV, RF, look), face_labels=face_label, label_grid=syn.labels,
                       labels={**space.labels_doc(syn.labels), **example_doc(ex, cons)}, target_net=syn.net,
                       example_net=example_net(ex.grid, cons, ex.spec), baseline_net=bnet, example=asset, look=look,
                       scene=scene)
