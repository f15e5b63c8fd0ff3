"""A scene of pieces: portals found, each later piece placed at its join, all concatenated.

A piece is a :class:`~synthkit.methods.reshape.textured.TexturedMesh` at its file's coordinates;
:func:`place_pieces` gives each a world offset so that the portals its ``chain`` joins meet
(section 5), :func:`assemble` concatenates them (``V (#V, 3)``, ``F (#F, 3)``, materials, piece
ranges) and :func:`snap_joined` makes the joined portal vertices coincide; :func:`frozen_nodes`
are those a limited propagation keeps in place.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from synthkit.errors import KeyedError
from synthkit.methods.reshape.handles import PieceRange
from synthkit.methods.reshape.portals import align_portals, boundary_portals, detect_portals, portal_positions
from synthkit.methods.reshape.textured import TexturedMesh

__all__ = ["piece_portals", "place_pieces", "portal_gaps", "snap_joined", "assemble", "frozen_nodes"]


def piece_portals(mesh: TexturedMesh, extra: dict, *, tol: float, key: str) -> dict[str, np.ndarray]:
    """Portal name -> render vertices of one piece (detected end planes and boundary loops, given
    indices: ``key.portals.<name>`` names them in a KeyedError)."""
    found = {**detect_portals(mesh.V, tol=tol), **boundary_portals(mesh.V, mesh.F, tol=tol)}
    for name, idx in extra.items():
        idx = np.asarray(idx, np.int64)
        bad = idx[(idx < 0) | (idx >= len(mesh.positions))]
        if len(bad):
            raise KeyedError(f"{key}.portals.{name}",
                             f"vertex {int(bad[0])} is out of range ({len(mesh.positions)} vertices)")
        found[name] = np.flatnonzero(np.isin(mesh.position_index, idx))
    return found


def place_pieces(names: list[str], meshes: list[TexturedMesh], extra: list[dict], chain: list, *,
                 tol: float) -> tuple[list[np.ndarray], list[dict], list[tuple]]:
    """World offset ``(3,)`` of each piece, the joins made (for the report) and, per join, the
    joined render vertices ``(piece a, indices, piece b, indices)``. ``extra`` are the pieces'
    portals given by file vertex index, ``chain`` the joins (``a``, ``a_portal``, ``b``,
    ``b_portal``) placing each later piece; ``tol`` the portal plane tolerance (model units).
    KeyedError names the ``pieces[i]``, ``chain[i]`` or ``chain`` key at fault."""
    if not chain and len(names) == 1:
        return [np.zeros(3)], [], []
    offsets: dict[str, np.ndarray] = {names[0]: np.zeros(3)}
    portals = {n: piece_portals(m, more, tol=tol, key=f"pieces[{i}]")
               for i, (n, m, more) in enumerate(zip(names, meshes, extra, strict=True))}
    joins, joined = [], []
    for i, j in enumerate(chain):
        key = f"chain[{i}]"
        for side, piece, portal in (("a", j.a, j.a_portal), ("b", j.b, j.b_portal)):
            if piece not in portals:
                raise KeyedError(f"{key}.{side}", f"no piece named {piece!r} (pieces: {', '.join(names)})")
            if portal not in portals[piece]:
                raise KeyedError(f"{key}.{side}_portal",
                                 f"piece {piece} has no portal {portal!r} (portals: {', '.join(portals[piece])})")
        if j.a not in offsets:
            raise KeyedError(f"{key}.a", f"piece {j.a!r} is not placed yet (join pieces in chain order)")
        if j.b in offsets:
            raise KeyedError(f"{key}.b", f"piece {j.b!r} is placed already")
        ma, mb = meshes[names.index(j.a)], meshes[names.index(j.b)]
        Pa = portal_positions(ma.V, portals[j.a][j.a_portal], tol=tol) + offsets[j.a]
        Pb = portal_positions(mb.V, portals[j.b][j.b_portal], tol=tol)
        try:
            t, gap = align_portals(Pa, Pb, tol=100 * tol)
        except ValueError as exc:
            raise KeyedError(key, f"{j.a}.{j.a_portal} and {j.b}.{j.b_portal}: {exc}") from None
        offsets[j.b] = t
        joins.append({"a": f"{j.a}.{j.a_portal}", "b": f"{j.b}.{j.b_portal}", "vertices": len(Pa), "placed_gap": gap})
        joined.append((names.index(j.a), portals[j.a][j.a_portal], names.index(j.b), portals[j.b][j.b_portal]))
    missing = [n for n in names if n not in offsets]
    if missing:
        raise KeyedError("chain", f"pieces {', '.join(missing)} are not joined to the first piece {names[0]}")
    return [offsets[n] for n in names], joins, joined


def portal_gaps(joined, ranges, Vout) -> list[float]:
    """Largest distance from a joined portal vertex of piece a to the nearest of piece b, per join,
    in the reshaped world positions ``Vout (#V, 3)``."""
    gaps = []
    for ia, va, ib, vb in joined:
        Pa, Pb = Vout[ranges[ia].start + va], Vout[ranges[ib].start + vb]
        gaps.append(float(np.linalg.norm(Pa[:, None] - Pb[None], axis=2).min(axis=1).max()))
    return gaps


def snap_joined(V, ranges, joined) -> None:
    """Move each joined portal vertex of piece b onto its nearest partner of piece a (in place), so
    that the graph welds every joined pair into one node even when the placed portals differ by
    more than the weld tolerance (they may differ up to the portal match tolerance)."""
    for ia, va, ib, vb in joined:
        Pa = V[ranges[ia].start + va]
        _, j = cKDTree(Pa).query(V[ranges[ib].start + vb])
        V[ranges[ib].start + vb] = Pa[j]


def assemble(names, meshes, offsets):
    """Concatenated ``V (#V, 3)`` (world), ``F (#F, 3)``, ``face_material (#F,)`` and piece ranges."""
    Vs, Fs, fms, ranges, base, mbase = [], [], [], [], 0, 0
    for name, m, off in zip(names, meshes, offsets, strict=True):
        Vs.append(m.V + off)
        Fs.append(m.F + base)
        fms.append(m.face_material + mbase)
        ranges.append(PieceRange(name, base, base + len(m.V), m.position_index, len(m.positions)))
        base += len(m.V)
        mbase += len(m.materials)
    return np.vstack(Vs), np.vstack(Fs), np.concatenate(fms), ranges


def frozen_nodes(ranges: list[PieceRange], node_of_vertex: np.ndarray, chain: list, handles: np.ndarray,
                 limit: int | None) -> np.ndarray:
    """Nodes of the pieces farther than ``limit`` joins of ``chain`` from every piece holding one of
    the ``handles`` (empty without a limit or with one piece): they keep their place while dragging
    (section 5). ``node_of_vertex (#V,)`` maps the scene's render vertices to graph nodes."""
    if limit is None or len(ranges) == 1:
        return np.zeros(0, np.int64)
    piece_nodes = {r.name: node_of_vertex[r.start:r.stop] for r in ranges}
    dist = {n: 0 for n, nodes in piece_nodes.items() if np.isin(nodes, handles).any()}
    frontier = list(dist)
    while frontier:
        nxt = []
        for j in chain:
            for a, b in ((j.a, j.b), (j.b, j.a)):
                if a in frontier and b not in dist:
                    dist[b] = dist[a] + 1
                    nxt.append(b)
        frontier = nxt
    far = [nodes for n, nodes in piece_nodes.items() if dist.get(n, limit + 1) > limit]
    return np.setdiff1d(np.concatenate(far) if far else np.zeros(0, np.int64), handles)
