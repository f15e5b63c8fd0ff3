"""The construction space as one run sees it: a single curve (:class:`CurveSpace`) or a curve network
(:class:`NetworkSpace`) behind the same methods, so that :func:`synthkit.methods.petri.pipeline.compute`
is one run over both: the target net, the neighbour graph the result is joined over, the crack
figures, the adjacency violations, the shape figures of ``report.json``, ``labels.json``'s grid and
the lines of the construction-space preview."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from synthkit.methods.petri import network
from synthkit.methods.petri.assembly import Assembler, PieceLibrary, crack_measure, crack_measure_graph
from synthkit.methods.petri.construction import ConstructionSpace
from synthkit.methods.petri.net import ColouredPetriNet, adjacency_violations, graph_violations

__all__ = ["Space", "CurveSpace", "NetworkSpace", "axes_doc"]


class Space(Protocol):
    """What a run needs of its construction space, besides the attributes of the space it wraps
    (``space``, ``axes``, ``point_axes``, ``units``): the target net over its cells (hexahedra
    ``net.corners``); the net's labels as ``labels.json`` holds them; the cells' ``(neighbours (N, 6),
    back (N, 6))``; the crack figures (``gap``, ``unmatched``, ``seams``, ``mismatch``, and a network's
    junction figures); the adjacency violations counted apart from the inference; the figures
    ``report.json`` lists first (cells, the space's shape); the baseline's straight curve (its length
    and how it was chosen); ``labels.json``'s grid; the plane's cell edges and curves ``(k, 2, 3)``
    at the first sweep level, for the previews."""

    space: ConstructionSpace | network.NetworkSpace

    def make_net(self, cons, hint: str | None) -> ColouredPetriNet: ...
    def labels_of(self, net: ColouredPetriNet) -> np.ndarray: ...
    def graph(self, net: ColouredPetriNet) -> tuple[np.ndarray, np.ndarray]: ...
    def cracks(self, library: PieceLibrary, net: ColouredPetriNet, assembler: Assembler) -> dict: ...
    def violations(self, labels: np.ndarray, net: ColouredPetriNet, cons) -> int: ...
    def shape_metrics(self, net: ColouredPetriNet, cracks: dict, unit: float) -> dict: ...
    def straight_length(self) -> tuple[float, str]: ...
    def labels_doc(self, labels: np.ndarray) -> dict: ...
    def lines(self) -> np.ndarray: ...


def axes_doc(axes) -> dict:
    """The construction axes a, b, c as world axis names."""
    return {"a": "XYZ"[axes[0]], "b": "XYZ"[axes[1]], "c": "XYZ"[axes[2]]}


class _Wrapped:
    """The attributes every run reads of the space it wraps."""

    def __init__(self, space):
        self.space = space
        self.axes = space.axes
        self.point_axes = space.point_axes
        self.units = space.units


class CurveSpace(_Wrapped):
    """One curve's grid of cells ``(S_X, S_Y, S_Z)`` (:class:`~.construction.ConstructionSpace`)."""

    def make_net(self, cons, hint: str | None) -> ColouredPetriNet:
        space = self.space
        net = ColouredPetriNet(space.shape, cons.allowed[list(space.axes)], cons.n_labels, boundary=cons.boundary,
                               periodic=(space.closed, False, False), corners=space.hex_corners())
        net.unfillable_hint = hint
        return net

    def labels_of(self, net: ColouredPetriNet) -> np.ndarray:
        return net.label_grid()

    def graph(self, net: ColouredPetriNet) -> tuple[np.ndarray, np.ndarray]:
        nbr = np.asarray(net.neighbours)
        return nbr, np.broadcast_to(np.arange(6) ^ 1, nbr.shape)

    def cracks(self, library: PieceLibrary, net: ColouredPetriNet, assembler: Assembler) -> dict:
        gap, unmatched, seams, mismatch = crack_measure(
            library, net.label_grid(), net.corners, periodic=net.periodic, offsets=assembler.offsets(net.n_cells)
        )
        return {"gap": gap, "mismatch": mismatch, "unmatched": unmatched, "seams": seams}

    def violations(self, labels: np.ndarray, net: ColouredPetriNet, cons) -> int:
        return adjacency_violations(labels, net.allowed, cons.n_labels, boundary=cons.boundary,
                                    periodic=net.periodic)

    def shape_metrics(self, net: ColouredPetriNet, cracks: dict, unit: float) -> dict:
        return {"cells": int(net.n_cells), "construction_shape": list(self.space.shape)}

    def straight_length(self) -> tuple[float, str]:
        return self.space.shape[0] * self.units[0], "straight curve of the same length"

    def labels_doc(self, labels: np.ndarray) -> dict:
        return {
            "format": "petri-synth label grid: grid[i][j][k], i along the curve, j across, k along the sweep",
            "shape": list(labels.shape),
            "axes": axes_doc(self.axes),
            "closed": bool(self.space.closed),
            "grid": labels.tolist(),
        }

    def lines(self) -> np.ndarray:
        space = self.space
        G = space.grid
        w = space.sweep[0]
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


class NetworkSpace(_Wrapped):
    """A curve network's arms and junctions (:class:`~.network.NetworkSpace`), cells in a graph."""

    def make_net(self, cons, hint: str | None) -> ColouredPetriNet:
        space = self.space
        nbr, back, _, coords = space.graph()
        return ColouredPetriNet((space.n_cells, 1, 1), cons.allowed[list(space.axes)], cons.n_labels,
                                boundary=cons.boundary, corners=space.hex_corners(),
                                graph=(nbr, back, coords, space.describe))

    def labels_of(self, net: ColouredPetriNet) -> np.ndarray:
        return np.asarray(net.label, np.int64)

    def graph(self, net: ColouredPetriNet) -> tuple[np.ndarray, np.ndarray]:
        return self.space.graph()[:2]

    def cracks(self, library: PieceLibrary, net: ColouredPetriNet, assembler: Assembler) -> dict:
        """The crack figures overall and at the junctions (cells of junction parts and their
        neighbours across a frame change)."""
        space = self.space
        nbr, back, flip, _ = space.graph()
        labels = np.asarray(net.label, np.int64)
        gap, unmatched, seams, mismatch = crack_measure_graph(
            library, labels, net.corners, (nbr, back, flip), offsets=assembler.offsets(net.n_cells)
        )
        junction_plane = np.array([space.parts[p]["kind"] == "junction" for p in space.cell_part.tolist()])
        in_junction = np.repeat(junction_plane, space.size_z)
        across = (nbr >= 0) & (back != (np.arange(6) ^ 1)[None])
        touched = in_junction | across.any(axis=1)
        sub = np.where(touched[:, None], nbr, -1)
        sub = np.where((sub >= 0) & (touched[np.maximum(sub, 0)] | touched[:, None]), sub, -1)
        jviol = graph_violations(labels, sub, back, net.allowed, net.n_labels, boundary=False)
        jgap, junmatched, _, jmismatch = crack_measure_graph(library, labels, net.corners, (sub, back, flip))
        return {"gap": gap, "mismatch": mismatch, "unmatched": unmatched, "seams": seams,
                "junction_cells": int(in_junction.sum()), "junction_adjacency_violations": int(jviol),
                "junction_gap": jgap, "junction_mismatch": jmismatch, "junction_unmatched": int(junmatched)}

    def violations(self, labels: np.ndarray, net: ColouredPetriNet, cons) -> int:
        nbr, back, _, _ = self.space.graph()
        return graph_violations(labels, nbr, back, net.allowed, cons.n_labels, boundary=cons.boundary)

    def shape_metrics(self, net: ColouredPetriNet, cracks: dict, unit: float) -> dict:
        space = self.space
        return {
            "cells": int(net.n_cells),
            "construction_shape": {
                "parts": [{k: v for k, v in p.items() if k != "name"} | {"name": p["name"]} for p in space.parts],
                "size_y": space.size_y,
                "size_z": space.size_z,
            },
            "curves": len(space.curves),
            "junctions": len(space.junctions),
            "junction_cells": cracks["junction_cells"],
            "junction_adjacency_violations": cracks["junction_adjacency_violations"],
            "junction_crack_max": max(cracks["junction_gap"] / unit, cracks["junction_mismatch"]),
            "junction_unmatched_vertices": cracks["junction_unmatched"],
        }

    def straight_length(self) -> tuple[float, str]:
        space = self.space
        return max(1, space.n_plane // space.size_y) * space.units[0], "a straight curve with as many cells"

    def labels_doc(self, labels: np.ndarray) -> dict:
        space = self.space
        SZ = space.size_z
        L = labels.reshape(space.n_plane, SZ)
        parts = []
        for idx, p in enumerate(space.parts):
            q = np.flatnonzero(space.cell_part == idx)  # a part's cells are consecutive (network._Cells)
            parts.append(dict(p, grid=L[q].reshape(p["shape"][0], p["shape"][1], SZ).tolist()))
        return {
            "format": "petri-synth curve network: per part (arm of a curve or junction of two) grid[i][j][k], i "
            "along the part's curve (a junction: along its first curve), j across, k along the sweep",
            "axes": axes_doc(self.axes),
            "parts": parts,
            "junctions": [{"curves": [a, b], "point": pt} for a, b, pt in space.junctions],
        }

    def lines(self) -> np.ndarray:
        space = self.space
        w = space.sweep[0]
        segs = space.plane_segments()
        lines = [space.world(segs, np.full(segs.shape[:2], w))]
        for P, closed in zip(space.curves, space.closed, strict=True):
            C = np.vstack([P, P[:1]]) if closed else P
            C = space.world(C, np.full(len(C), w))
            lines.append(np.stack([C[:-1], C[1:]], axis=1))
        return np.concatenate(lines)
