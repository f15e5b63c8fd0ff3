"""Joining the deformed pieces into the result: seams welded, walls between cells dropped, faces
stored twice found, T-junctions (a vertex of one face inside an open edge of another) closed."""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.core.mesh import merge_vertices, remove_unreferenced, weld
from synthkit.core.quality import WELD_REL_TOL, degenerate_faces
from synthkit.methods.petri.appearance import Look


def edge_uses(W: np.ndarray) -> np.ndarray:
    """``(3 m,)``: how many faces of ``W (m, 3)`` (corners as welded position classes) use each of their
    edges, edges ordered (0, 1) of every face, then (1, 2), then (2, 0); 0 for a collapsed edge."""
    E = np.concatenate([W[:, [0, 1]], W[:, [1, 2]], W[:, [2, 0]]])
    lo, hi = E.min(axis=1), E.max(axis=1)
    key = lo * (int(W.max(initial=0)) + 1) + hi
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    out = counts[inv.ravel()]
    out[lo == hi] = 0
    return out


def repeated_faces(W: np.ndarray) -> np.ndarray:
    """``(#F,) bool``: faces of ``W (#F, 3)`` (corners as welded positions) over the same positions in
    the same orientation as an earlier face: a surface stored twice (two boxes of an example that share
    a side, cut into the same triangles by the lattice)."""
    R = np.take_along_axis(W, (np.argmin(W, axis=1)[:, None] + np.arange(3)) % 3, axis=1)
    _, first = np.unique(np.ascontiguousarray(R).view(np.dtype((np.void, 24))).ravel(), return_index=True)
    out = np.ones(len(W), bool)
    out[first] = False
    return out


def close_t_junctions(V: np.ndarray, F: np.ndarray, face_cell: np.ndarray, keep_with: list, look: Look | None,
                      tol: float, *, passes: int = 4, cls: np.ndarray | None = None):
    """Split faces of ``V (n, 3)``, ``F (m, 3)`` at the vertices of other cells (``face_cell (m,)``) that
    lie inside one of their open edges (within ``tol``), so that a cut curve split more finely on one
    side of a cell face than on the other (a T-junction: closed in space, open in the mesh) is joined
    edge to edge. T-junctions inside one piece are the example's own and stay.

    Edges are counted over positions welded within ``tol`` (an example's UV seams are not open). A face
    whose edge (a, b) holds points p_1 .. p_k becomes the fan (a, p_1, c), ..., (p_k, b, c); its
    per-corner ``look`` values are interpolated along the edge, and each array of ``keep_with``
    (per-face, e.g. labels) is repeated for the new faces. A split that would give an edge more than
    two faces is not made (:func:`_crowding_splits`); ``cls`` may give the weld classes of ``V``. At
    most ``passes`` rounds (a face with points on two edges is split once per round). Returns
    ``(F, face_cell, keep_with, look)``.
    """
    if cls is None:
        _, _, cls = weld(V, np.zeros((0, 3), np.int64), tol, return_index=True)
    for _ in range(passes):
        vertex_cell = np.full(len(V), -1, np.int64)
        vertex_cell[F.ravel()] = np.repeat(face_cell, 3)
        splits = _edge_splits(V, F, cls, vertex_cell, face_cell, tol)
        for f in _crowding_splits(F, splits, cls):
            del splits[f]
        if not splits:
            break
        F, (face_cell, *keep_with), look = _split_faces(F, splits, [face_cell, *keep_with], look)
    return F, face_cell, keep_with, look


def _crowding_splits(F, splits: dict, cls) -> list[int]:
    """The faces of ``splits`` whose split would give one of the new edge pieces along the split edge
    more than two faces (an example's overlapping boxes, whose vertices lie on each other's edges):
    such a T-junction is left open rather than made non-manifold."""
    if not splits:
        return []
    F2, (origin,), _ = _split_faces(F, splits, [np.arange(len(F))], None)
    crowded = (edge_uses(cls[F2]) > 2).reshape(3, -1)[0]  # edge (0, 1) of each fan face: along the split
    new = np.arange(len(F2)) >= len(F2) - sum(len(p) + 1 for _, p in splits.values())
    return sorted(set(origin[crowded & new].tolist()))


def _edge_splits(V, F, cls, vertex_cell, face_cell, tol: float) -> dict:
    """``{face: (k, [(t, vertex), ...])}``: for each face, its first open edge (corner k to k + 1)
    holding vertices of other cells' open edges strictly inside it."""
    open_e = np.flatnonzero(edge_uses(cls[F]) == 1)
    if len(open_e) == 0:
        return {}
    m = len(F)
    face, corner = open_e % m, open_e // m
    a, b = F[face, corner], F[face, (corner + 1) % 3]
    ends = np.unique(np.concatenate([a, b]))
    tree = cKDTree(V[ends])
    A, B = V[a], V[b]
    D = B - A
    length = np.linalg.norm(D, axis=1)
    near = tree.query_ball_point((A + B) / 2, length / 2 + tol)
    sizes = np.fromiter((len(x) for x in near), np.int64, len(near))
    e = np.repeat(np.arange(len(near)), sizes)
    cand = ends[np.concatenate([np.asarray(x, np.int64) for x in near])] if len(e) else np.zeros(0, np.int64)
    keep = (cls[cand] != cls[a[e]]) & (cls[cand] != cls[b[e]]) & (vertex_cell[cand] != face_cell[face[e]])
    keep &= length[e] > 2 * tol
    e, cand = e[keep], cand[keep]
    t = ((V[cand] - A[e]) * D[e]).sum(axis=1) / length[e] ** 2
    dist = np.linalg.norm(V[cand] - (A[e] + t[:, None] * D[e]), axis=1)
    ok = (dist <= tol) & (t * length[e] > tol) & ((1 - t) * length[e] > tol)
    e, cand, t = e[ok], cand[ok], t[ok]
    # one edge per face (its first), one vertex per welded position, in order along the edge
    first_edge = np.full(m, len(open_e), np.int64)
    np.minimum.at(first_edge, face[e], e)
    sel = first_edge[face[e]] == e
    e, cand, t = e[sel], cand[sel], t[sel]
    order = np.lexsort((t, cls[cand], e))
    e, cand, t = e[order], cand[order], t[order]
    fresh = np.ones(len(e), bool)
    fresh[1:] = (e[1:] != e[:-1]) | (cls[cand[1:]] != cls[cand[:-1]])
    e, cand, t = e[fresh], cand[fresh], t[fresh]
    order = np.lexsort((t, e))
    e, cand, t = e[order], cand[order], t[order]
    splits: dict = {}
    bounds = np.flatnonzero(np.diff(np.concatenate([[-1], e, [-1]])))
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        k = int(e[lo])
        splits[int(face[k])] = (int(corner[k]), list(zip(t[lo:hi].tolist(), cand[lo:hi].tolist(), strict=True)))
    return splits


def _split_faces(F, splits: dict, keep_with: list, look: Look | None):
    """Replace each face of ``splits`` (see :func:`_edge_splits`) by its fan."""
    new_F, src, weights = [], [], []
    for f, (k, pts) in splits.items():
        a, b, c = F[f, k], F[f, (k + 1) % 3], F[f, (k + 2) % 3]
        chain = [(0.0, a)] + pts + [(1.0, b)]
        for (t0, v0), (t1, v1) in zip(chain[:-1], chain[1:], strict=True):
            new_F.append((v0, v1, c))
            src.append(f)
            # corner weights over the old face's corners (a, b, c) at k, k + 1, k + 2
            weights.append([[1 - t0, t0, 0.0], [1 - t1, t1, 0.0], [0.0, 0.0, 1.0]])
    faces = np.fromiter(splits, np.int64)
    keep = np.ones(len(F), bool)
    keep[faces] = False
    src = np.asarray(src, np.int64)
    F2 = np.concatenate([F[keep], np.asarray(new_F, np.int64)])
    kept = [np.concatenate([x[keep], x[src]]) for x in keep_with]
    if look is None:
        return F2, kept, None
    Wt = np.asarray(weights)
    rot = np.asarray([splits[int(f)][0] for f in src])
    order = (rot[:, None] + np.arange(3)[None]) % 3
    arrays = []
    for arr in look.corners():
        if arr is None:
            arrays.append(None)
            continue
        vals = np.take_along_axis(arr[src], order[:, :, None], axis=1)
        arrays.append(np.concatenate([arr[keep], np.einsum("mcb,mbk->mck", Wt, vals)]))
    mat = np.concatenate([look.face_material[keep], look.face_material[src]])
    return F2, kept, Look(arrays[0], arrays[1], mat)


def welded_mesh(assembler, seams: np.ndarray, *, weld: bool):
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


def joined_mesh(assembler, welded, graph):
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
    of the one covering the same region as a part of the other (:func:`same_region`; they may be
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
        parts2 = face_components(cls[F[idx2]], np.asarray(idx2))
        for part in face_components(cls[F[idx]], np.asarray(idx)):
            for k, part2 in enumerate(parts2):
                if same_region(T[part], area[part], T[part2], area[part2], tol):
                    out[part] = out[part2] = True
                    parts2.pop(k)
                    break
    return out


def face_components(W: np.ndarray, idx: np.ndarray) -> list[np.ndarray]:
    """The faces ``idx (k,)`` grouped into connected pieces by their welded corners ``W (k, 3)``."""
    _, inv = np.unique(W, return_inverse=True)
    inv = inv.reshape(W.shape)
    k, n = len(W), int(inv.max()) + 1
    rows = np.repeat(np.arange(k), 3)
    graph = csr_matrix((np.ones(3 * k), (rows, k + inv.ravel())), shape=(k + n, k + n))
    _, comp = connected_components(graph, directed=False)
    return [idx[comp[:k] == c] for c in np.unique(comp[:k])]


def same_region(Ta, area_a, Tb, area_b, tol: float) -> bool:
    """Whether two sets of coplanar triangles ``(k, 3, 3)`` (their doubled areas ``(k,)``) cover the same
    region: the same area (to 1e-6) and the same bounding box (within ``tol``)."""
    a, b = float(area_a.sum()), float(area_b.sum())
    if abs(a - b) > 1e-6 * max(a, b):
        return False
    Pa, Pb = Ta.reshape(-1, 3), Tb.reshape(-1, 3)
    return bool(np.abs(Pa.min(0) - Pb.min(0)).max() <= tol and np.abs(Pa.max(0) - Pb.max(0)).max() <= tol)


def weld_seams(V, F, seams):
    """Merge the matched seam vertices ``seams`` of ``V (n, 3)``, ``F (m, 3)``; faces that collapse
    are dropped. Returns ``(V, F, keep (m,) bool)``, ``keep`` the faces kept."""
    V, F2, old_to_new = merge_vertices(V, F, seams, return_index=True)
    G = old_to_new[F]
    keep = (G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 2] != G[:, 0])
    return V, F2, keep
