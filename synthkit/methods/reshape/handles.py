"""Batch handles, fixed vertices and links (paper sections 3.3, 3.4 and 5) over assembled pieces.

Selections resolve to graph nodes of the assembled mesh: ``V (#V, 3)`` render-vertex positions in
world coordinates, ``node_of_vertex (#V,)``, and per piece a :class:`PieceRange` (its render
vertices and the file vertex index of each). Errors are ValueError naming the config key and value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PieceRange", "select_nodes", "resolve_handles", "resolve_fixed", "resolve_links"]

_AXIS = {"x": 0, "y": 1, "z": 2}


@dataclass
class PieceRange:
    """Render vertices ``start:stop`` of the assembled mesh belong to piece ``name``;
    ``position_index (stop - start,)`` is the file vertex of each; the file has ``n_positions``."""

    name: str
    start: int
    stop: int
    position_index: np.ndarray
    n_positions: int


def _candidates(sel, pieces: list[PieceRange], key: str) -> list[PieceRange]:
    if sel.piece is None:
        return pieces[:1] if sel.index is not None else pieces
    chosen = [p for p in pieces if p.name == sel.piece]
    if not chosen:
        raise ValueError(f"{key}.piece: no piece named {sel.piece!r} (pieces: {', '.join(p.name for p in pieces)})")
    return chosen


def select_nodes(sel, pieces: list[PieceRange], V, node_of_vertex, *, key: str) -> np.ndarray:
    """Sorted unique nodes ``(k,)`` chosen by selection ``sel`` (a config Selection); raises
    ValueError for an index out of range or a selection that selects nothing."""
    found = []
    for p in _candidates(sel, pieces, key):
        verts = np.arange(p.start, p.stop)
        if sel.index is not None:
            idx = np.asarray(sel.index, np.int64)
            bad = idx[(idx < 0) | (idx >= p.n_positions)]
            if len(bad):
                raise ValueError(
                    f"{key}.index: vertex {int(bad[0])} is out of range (piece {p.name} has {p.n_positions} vertices)"
                )
            found.append(verts[np.isin(p.position_index, idx)])
        elif sel.nearest is not None:
            P = np.asarray(sel.nearest, np.float64)
            d = np.linalg.norm(V[verts][None] - P[:, None], axis=2)
            found.append(verts[np.argmin(d, axis=1)])
        elif sel.box is not None:
            lo, hi = np.asarray(sel.box.min), np.asarray(sel.box.max)
            found.append(verts[np.all((V[verts] >= lo) & (V[verts] <= hi), axis=1)])
        else:
            h = sel.half_space
            c = V[verts, _AXIS[h.axis]]
            found.append(verts[c >= h.above] if h.above is not None else verts[c <= h.below])
    verts = np.concatenate(found) if found else np.zeros(0, np.int64)
    if sel.nearest is not None and len(pieces) > 1 and sel.piece is None:
        verts = _nearest_overall(sel, V, verts)
    nodes = np.unique(node_of_vertex[verts])
    if not len(nodes):
        raise ValueError(f"{key}: selects no vertex ({_describe(sel)})")
    return nodes


def _nearest_overall(sel, V, verts) -> np.ndarray:
    """Of the per-piece nearest vertices, the nearest one for each point."""
    P = np.asarray(sel.nearest, np.float64)
    per = verts.reshape(-1, len(P)).T
    d = np.linalg.norm(V[per] - P[:, None], axis=2)
    return per[np.arange(len(P)), np.argmin(d, axis=1)]


def _describe(sel) -> str:
    for k in ("index", "nearest", "box", "half_space"):
        value = getattr(sel, k)
        if value is not None:
            shown = value.model_dump() if hasattr(value, "model_dump") else value
            return f"{k}: {shown}"
    return "nothing"


def resolve_handles(handles, pieces, V, node_of_vertex, X0) -> tuple[np.ndarray, np.ndarray]:
    """``(nodes (k,), targets (k, 3))`` of every handle; raises ValueError when two handles share a node."""
    nodes, targets, owner = [], [], {}
    for i, h in enumerate(handles):
        key = f"handles[{i}]"
        sel = select_nodes(h, pieces, V, node_of_vertex, key=key)
        for n in sel:
            if int(n) in owner:
                raise ValueError(f"{key}: shares vertex node {int(n)} with handles[{owner[int(n)]}]")
            owner[int(n)] = i
        start = X0[sel]
        if h.displacement is not None:
            goal = start + np.asarray(h.displacement)
        else:
            goal = start + (np.asarray(h.target) - start.mean(axis=0))
        nodes.append(sel)
        targets.append(goal)
    return np.concatenate(nodes), np.vstack(targets)


def resolve_fixed(fixed, handle_nodes, pieces, V, node_of_vertex) -> np.ndarray:
    """Fixed nodes ``(k,)``; raises ValueError when a fixed vertex is also a handle."""
    out = []
    for i, f in enumerate(fixed):
        key = f"fixed[{i}]"
        sel = select_nodes(f, pieces, V, node_of_vertex, key=key)
        both = np.intersect1d(sel, handle_nodes)
        if len(both):
            raise ValueError(
                f"{key}: {len(both)} vertices are also handles (node {int(both[0])}); a vertex is one or the other"
            )
        out.append(sel)
    return np.unique(np.concatenate(out)) if out else np.zeros(0, np.int64)


def resolve_links(links, pieces, V, node_of_vertex) -> np.ndarray:
    """Link node pairs ``(k, 2)``; raises ValueError when a link's two vertices are one node."""
    pairs = []
    for i, link in enumerate(links):
        key = f"links[{i}]"
        ends = []
        for j in range(2):
            sub = link.model_copy(update={"index": [link.index[j]] if link.index is not None else None,
                                          "nearest": [link.nearest[j]] if link.nearest is not None else None})
            ends.append(select_nodes(sub, pieces, V, node_of_vertex, key=key)[0])
        if ends[0] == ends[1]:
            raise ValueError(f"{key}: both ends are the same vertex")
        pairs.append(ends)
    return np.asarray(pairs, np.int64).reshape(-1, 2)
