"""Figures of a petri-synth result against its example (paper section 3.2: normal histograms; facade
areas, cracks, open edges), and the example as a Petri net and as ``labels.json`` describes it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synthkit.core.quality import WELD_REL_TOL
from synthkit.methods.petri import analysis
from synthkit.methods.petri.assembly import Assembler, open_edges_off_border
from synthkit.methods.petri.net import ColouredPetriNet

__all__ = ["Synthesis", "facade_metrics", "origin_preference", "example_net", "example_doc", "result_metrics"]


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


def example_doc(ex: analysis.Example, cons: analysis.Constraints) -> dict:
    """The part of ``labels.json`` that describes the example: its label grid and lattice, each
    label's representative piece and feature vector, and the adjacency constraints."""
    grid, spec, features, reps = ex.grid, ex.spec, ex.features, ex.reps
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


@dataclass
class Synthesis:
    """What inference and assembly made: the target ``net`` (filled), its ``assembler`` of deformed pieces,
    the ``restarts`` it took, the net's ``labels`` (any shape), the :func:`joints.welded_mesh`
    ``welded`` and the result as written ``(V, F, face_label, look, cls)`` (``cls`` the weld classes)."""

    net: ColouredPetriNet
    assembler: Assembler
    restarts: int
    labels: np.ndarray
    welded: tuple = ()
    result: tuple = ()


def result_metrics(V, F, ex: analysis.Example, space, syn: Synthesis, library, cracks: dict, cons) -> tuple:
    """The metrics a single-curve and a network run share, and the example's normal histogram
    (the baseline compares against it): the result of ``syn`` against the example ``V, F`` (its
    analysis ``ex``), with the crack figures ``cracks`` of ``space`` (:mod:`.spaces`) and the
    constraints ``cons`` the net was filled under. The normal histogram is taken on the welded
    pieces (as the baseline's). Returns ``(h_ex, metrics)``."""
    RV, RF, _, _, cls = syn.result
    net, labels_out, welded, spec = syn.net, syn.labels, syn.welded, ex.spec
    plane_axes = space.point_axes
    h_ex = analysis.normal_histogram(V, F, plane_axes)
    h_res = analysis.normal_histogram(welded[0], welded[1], plane_axes)
    return h_ex, {
        "labels": int(cons.n_labels),
        "example_pieces": int(ex.grid.size),
        "example_lattice": {"unit": spec.unit, "origin": spec.origin, "counts": spec.counts},
        "transitions": dict(net.fired),
        "restarts": int(syn.restarts),
        "adjacency_violations": int(space.violations(labels_out, net, cons)),
        "unfilled_cells": int((labels_out < 0).sum()),
        "empty_cells": int(sum(len(library.faces[lab]) == 0 for lab in labels_out.ravel().tolist())),
        "crack_max": max(cracks["gap"] / float(spec.unit.min()), cracks["mismatch"]),
        "boundary_unmatched_vertices": int(cracks["unmatched"]),
        "curve_max_deviation": float(space.space.center_deviation().max()),
        "normal_histogram_D": analysis.histogram_discrimination(h_ex, h_res),
        "normal_histogram_example": h_ex,
        "normal_histogram_result": h_res,
        "open_edges_off_border": open_edges_off_border(
            RV, RF, net.corners, net.neighbours, WELD_REL_TOL * float(np.linalg.norm(np.ptp(RV, axis=0))), cls=cls
        ),
        "result_vertices": int(len(RV)),
        "result_faces": int(len(RF)),
        **facade_metrics(V, F, syn.assembler, ex.grid, net, space.axes),
    }
