"""Piece deformation and assembly (the deforming transitions), and measurements of the result."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from scipy.spatial import cKDTree

from synthkit.core.ffd import trilinear_weights
from synthkit.core.mesh import weld
from synthkit.methods.petri.analysis import SEAM_TOL, curve_gap
from synthkit.methods.petri.appearance import Look, carry, concat
from synthkit.methods.petri.joints import edge_uses, repeated_faces
from synthkit.preview import golden_hues


class PieceLibrary:
    """The representative piece of every label, ready for trilinear FFD into any hexahedron.

    ``axes`` are the lattice axes of the construction axes (a, b, c): a piece's local coordinates
    are reordered to (a, b, c) and their eight trilinear weights cached, so deforming a piece into a
    cell is one ``(n, 8) @ (8, 3)`` product. ``looks[label]`` is the piece's
    :class:`~synthkit.methods.petri.appearance.Look` (None when the example's look was not given).
    """

    def __init__(self, pieces, representative: np.ndarray, axes: tuple[int, int, int]):
        looks = [pieces.look[int(p)] for p in representative] if pieces.look else None
        self._set(axes, [pieces.local[int(p)][:, list(axes)] for p in representative],
                  [pieces.faces[int(p)] for p in representative], looks)

    @classmethod
    def of(cls, axes, local: list, faces: list, looks: list | None) -> PieceLibrary:
        """A library of the pieces ``local[label] (n, 3)`` (in (a, b, c) order), ``faces[label]``."""
        out = cls.__new__(cls)
        out._set(axes, local, faces, looks)
        return out

    def _set(self, axes, local: list, faces: list, looks: list | None) -> None:
        self.axes = tuple(axes)
        self.local, self.faces, self.looks = list(local), list(faces), looks
        self.weights = [trilinear_weights(L) for L in self.local]
        self.face_sides = [face_sides(L, F) for L, F in zip(self.local, self.faces, strict=True)]

    def open_edges(self, label: int) -> np.ndarray:
        """``(k, 2)`` vertex pairs of ``label``'s piece: its open edges (:func:`piece_open_edges`), cached."""
        cache = self.__dict__.setdefault("_open", {})
        if label not in cache:
            cache[label] = piece_open_edges(self.local[label], self.faces[label])
        return cache[label]

    def deform(self, label: int, corners: np.ndarray) -> np.ndarray:
        """Vertices ``(n, 3)`` of ``label``'s piece deformed into the hexahedron ``corners (8, 3)``."""
        return self.weights[label] @ corners


def piece_open_edges(L: np.ndarray, F: np.ndarray, *, tol: float = SEAM_TOL) -> np.ndarray:
    """``(k, 2)`` vertex pairs: the edges of ``F (m, 3)`` used by one face only once the positions
    ``L (n, 3)`` are welded within ``tol`` (UV seams are not open) and faces stored twice counted once
    (as the result is written); each given by one of its copies."""
    if len(F) == 0:
        return np.zeros((0, 2), np.int64)
    _, _, cls = weld(L, np.zeros((0, 3), np.int64), tol, return_index=True)
    F = F[~repeated_faces(cls[F])]
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return E[edge_uses(cls[F]) == 1]


def face_sides(L: np.ndarray, F: np.ndarray, *, tol: float = SEAM_TOL) -> np.ndarray:
    """``(m,) int64``: the cell face (0 -a, 1 +a, 2 -b, 3 +b, 4 -c, 5 +c in local axes) each face of a
    piece ``L (n, 3)``, ``F (m, 3)`` lies on, -1 for none."""
    out = np.full(len(F), -1, np.int64)
    for side in range(6):
        on = np.abs(L[:, side >> 1] - (side & 1)) <= tol
        out[on[F].all(axis=1)] = side
    return out


def preview_library(library: PieceLibrary, max_faces: int) -> PieceLibrary:
    """A copy of ``library`` whose pieces have at most about ``max_faces`` triangles each, for previews.

    Larger pieces are decimated by quadric edge collapse with their boundaries kept (topology not
    enforced, which is faster; :func:`synthkit.core.mesh.simplify`); the weights are recomputed and the
    looks carried over (:func:`decimated_look`). Small pieces are shared as they are.
    """
    from synthkit.core.mesh import simplify

    local, faces, looks = [], [], None if library.looks is None else []
    for lab, (L, Fp) in enumerate(zip(library.local, library.faces, strict=True)):
        look = None if library.looks is None else library.looks[lab]
        if len(Fp) > max_faces:
            L2, F2, _ = simplify(L, Fp, max(max_faces, 4), preserve_boundary=True, preserve_topology=False)
            look = None if look is None else decimated_look(look, L, Fp, L2, F2)
            L, Fp = L2, F2
        local.append(L)
        faces.append(Fp)
        if looks is not None:
            looks.append(look)
    return PieceLibrary.of(library.axes, local, faces, looks)


def decimated_look(look: Look, L, F, L2, F2) -> Look:
    """The look of a decimated piece ``L2, F2`` from the full piece ``L, F``: each new face takes the
    material of the full face nearest its centroid and that face's values extended linearly to its
    corners (:func:`appearance.carry`, corners projected onto the face's plane)."""
    centroids = L[F].mean(axis=1)
    _, src = cKDTree(centroids).query(L2[F2].mean(axis=1))
    return carry(look, L, F, np.asarray(src, np.int64), L2, F2)


def reorder_library(library: PieceLibrary, axes: tuple[int, int, int]) -> PieceLibrary:
    """``library`` (in lattice axis order X, Y, Z) with local coordinates reordered to ``axes``."""
    return PieceLibrary.of(tuple(library.axes[a] for a in axes), [L[:, list(axes)] for L in library.local],
                           library.faces, library.looks)


def assemble(library: PieceLibrary, labels, corners: np.ndarray):
    """``(V, F, face_label)`` of ``library``'s pieces deformed into the cells ``corners (N, 8, 3)`` with
    ``labels (N,)`` (the same product as the deforming transitions, in one pass)."""
    Vs, Fs, labs, off = [], [], [], 0
    for c, lab in enumerate(np.asarray(labels).ravel().tolist()):
        X = library.deform(lab, corners[c])
        Vs.append(X)
        Fs.append(library.faces[lab] + off)
        labs.append(np.full(len(library.faces[lab]), lab, np.int64))
        off += len(X)
    return np.concatenate(Vs), np.concatenate(Fs), np.concatenate(labs)


class Assembler:
    """Collects deformed pieces (the deforming transitions' output) and assembles the result mesh."""

    def __init__(self, library: PieceLibrary, corners: np.ndarray):
        self.library = library
        self.corners = corners
        self.parts: list[tuple[int, int, np.ndarray]] = []

    def __call__(self, cell: int, label: int) -> None:
        self.parts.append((cell, label, self.library.deform(label, self.corners[cell])))

    def clear(self) -> None:
        self.parts.clear()

    def offsets(self, n_cells: int) -> np.ndarray:
        """Index of each cell's first vertex in :meth:`mesh`'s ``V`` ``(n_cells,)`` (-1: not deformed)."""
        out = np.full(n_cells, -1, np.int64)
        off = 0
        for cell, _, X in self.parts:
            out[cell] = off
            off += len(X)
        return out

    def mesh(self):
        """``(V, F, face_label, face_cell)`` of all deformed pieces, in firing order."""
        Vs, Fs, labs, cells = [], [], [], []
        off = 0
        for cell, label, X in self.parts:
            Fp = self.library.faces[label]
            Vs.append(X)
            Fs.append(Fp + off)
            labs.append(np.full(len(Fp), label, np.int64))
            cells.append(np.full(len(Fp), cell, np.int64))
            off += len(X)
        if not Vs:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(Vs), np.concatenate(Fs), np.concatenate(labs), np.concatenate(cells)

    def face_sides(self) -> np.ndarray:
        """:func:`face_sides` of :meth:`mesh`'s faces ``(#F,)``."""
        sides = [self.library.face_sides[label] for _, label, _ in self.parts]
        return np.concatenate(sides) if sides else np.zeros(0, np.int64)

    def look(self) -> Look | None:
        """The appearance of :meth:`mesh`'s faces (None without the example's look)."""
        looks = self.library.looks
        if looks is None:
            return None
        return concat([looks[label] for _, label, _ in self.parts], looks[0])


def crack_measure(
    library: PieceLibrary,
    label_grid: np.ndarray,
    corners: np.ndarray,
    *,
    periodic=(False,) * 3,
    tol: float = SEAM_TOL,
    offsets: np.ndarray | None = None,
):
    """Gaps between neighbouring deformed pieces where their example pieces met.

    For every pair of face-adjacent cells (p below q along construction axis t) with labels (A, B),
    the vertices of A's piece on its face ``t = 1`` are matched to those of B's piece on ``t = 0`` with
    the same other two local coordinates (within ``tol``): these are the boundary vertices the
    example pieces shared. Returns ``(max_gap, unmatched, seams, mismatch)``: the largest world distance
    between matched vertices after deformation, the number of vertices on shared cell faces (summed
    over distinct label pairs) without a partner (differing boundaries, or faces lying on the cell face
    such as a roof under an empty cell), when ``offsets (N,)`` (index of each cell's first vertex
    in the assembled mesh) is given the matched pairs as global vertex indices ``(k, 2)``, and the
    largest :func:`curve_mismatch` of the pairs (local units: where the pieces' cut curves do not meet,
    a hole the vertex gap cannot see).
    """
    lib = library
    shape = label_grid.shape
    flat = np.arange(label_grid.size).reshape(shape)
    max_gap, unmatched, mismatch = 0.0, 0, 0.0
    match_cache = {}
    seams = []
    for t in range(3):
        p_cells = np.moveaxis(flat, t, 0)
        first, second = p_cells[:-1].ravel(), p_cells[1:].ravel()
        if periodic[t] and shape[t] > 1:
            first = np.concatenate([first, p_cells[-1].ravel()])
            second = np.concatenate([second, p_cells[0].ravel()])
        la, lb = label_grid.ravel()[first], label_grid.ravel()[second]
        groups = defaultdict(list)
        for k, key in enumerate(zip(la.tolist(), lb.tolist(), strict=True)):
            groups[key].append(k)
        others = [x for x in range(3) if x != t]
        for (A, B), ks in groups.items():
            key = (t, A, B)
            if key not in match_cache:
                LA, LB = lib.local[A], lib.local[B]
                ia = np.flatnonzero(np.abs(LA[:, t] - 1) <= tol)
                ib = np.flatnonzero(np.abs(LB[:, t]) <= tol)
                CA = LA[ia][:, others] if len(ia) and len(ib) else None
                CB = LB[ib][:, others] if CA is not None else None
                match_cache[key], missing = _match_face(ia, ib, CA, CB, tol)
                unmatched += missing
                mismatch = max(mismatch, curve_mismatch(lib, A, 2 * t + 1, B, 2 * t, False, tol))
            ia, ib = match_cache[key]
            if len(ia) == 0:
                continue
            ks = np.asarray(ks)
            gap, seam = _gap_and_seam(lib, A, B, ia, ib, corners, first[ks], second[ks], offsets)
            max_gap = max(max_gap, gap)
            if seam is not None:
                seams.append(seam)
    seams = np.concatenate(seams) if seams else np.zeros((0, 2), np.int64)
    return max_gap, unmatched, seams, mismatch


def _face_coords(L: np.ndarray, t: int, flipped: bool) -> np.ndarray:
    """``(n, 2)`` coordinates of ``L (n, 3)`` on a cell face across local axis ``t``: (u, w) with w the
    sweep coordinate (for ``t = 2``: (a, b)), u mirrored to ``1 - u`` when ``flipped``."""
    if t == 2:
        return L[:, [0, 1]]
    u = L[:, 1 - t]
    return np.stack([1.0 - u if flipped else u, L[:, 2]], axis=1)


def curve_mismatch(lib: PieceLibrary, A: int, side_a: int, B: int, side_b: int, flipped: bool, tol: float) -> float:
    """How far apart the cut curves two pieces show on the cell face they share, in local units: the
    largest distance from an end of an open edge of either piece in its face (``side_a``/``side_b``:
    2 axis + 1 for the face at 1, + 0 for the one at 0) to the other's edges in that face, open or
    bounding a face lying in it (:func:`analysis.curve_gap`; B's face coordinates mirrored when
    ``flipped``), at most 1 (a cut curve with nothing across it: a hole). Open edges along the cell's
    rim (on two faces) are left to the pair across the other face."""
    curves = []
    for lab, side, fl in ((A, side_a, False), (B, side_b, flipped)):
        L, F = lib.local[lab], lib.faces[lab]
        on = np.abs(L[:, side >> 1] - (side & 1)) <= tol
        rim = ((np.abs(L) <= tol) | (np.abs(L - 1) <= tol)).sum(axis=1) >= 2
        E = lib.open_edges(lab)
        E = E[on[E[:, 0]] & on[E[:, 1]] & ~(rim[E[:, 0]] & rim[E[:, 1]])]
        every = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]) if len(F) else np.zeros((0, 2), np.int64)
        every = every[on[every[:, 0]] & on[every[:, 1]]]
        C = _face_coords(L, side >> 1, fl)
        curves.append((C[np.unique(E)], C[every]))
    (pa, sa), (pb, sb) = curves
    return float(min(max(curve_gap(pa, sb), curve_gap(pb, sa)), 1.0))


def _match_face(ia, ib, CA, CB, tol: float):
    """Match the face vertices ``ia`` of piece A to ``ib`` of piece B by their face coordinates
    ``CA (len(ia), 2)``, ``CB (len(ib), 2)`` (None when either side has none) within ``tol``.

    Returns ``((ia matched, ib partners), unmatched)``, ``unmatched`` counting the vertices of
    either side without a partner on the other."""
    if CA is None:
        return (np.zeros(0, np.int64), np.zeros(0, np.int64)), len(ia) + len(ib)
    dist, j = cKDTree(CB).query(CA)
    ok = dist <= tol
    d2, _ = cKDTree(CA).query(CB)  # B's face vertices without a partner in A
    return (ia[ok], ib[j[ok]]), int((~ok).sum()) + int((d2 > tol).sum())


def _gap_and_seam(lib, A, B, ia, ib, corners, cells_a, cells_b, offsets):
    """Largest distance between matched vertices ``ia`` of label A in ``cells_a (g,)`` and ``ib`` of
    label B in ``cells_b (g,)`` after deformation by their ``corners``, and the ``(g * m, 2)``
    output-vertex pairs to weld (None without ``offsets``, the first output vertex of each cell)."""
    XA = np.einsum("mk,gkd->gmd", lib.weights[A][ia], corners[cells_a])
    XB = np.einsum("mk,gkd->gmd", lib.weights[B][ib], corners[cells_b])
    gap = float(np.linalg.norm(XA - XB, axis=-1).max())
    if offsets is None:
        return gap, None
    oa, ob = offsets[cells_a], offsets[cells_b]
    return gap, np.stack([(oa[:, None] + ia[None]).ravel(), (ob[:, None] + ib[None]).ravel()], 1)


def label_colors(n: int) -> np.ndarray:
    """``(n, 3)`` distinct colours in [0, 1] (:func:`synthkit.preview.golden_hues`)."""
    return golden_hues(n)


def crack_measure_graph(library: PieceLibrary, labels, corners: np.ndarray, graph, *, tol: float = SEAM_TOL,
                        offsets=None):
    """:func:`crack_measure` on a curve network's neighbour graph ``graph = (neighbours, back, flip)``.

    For every pair of neighbours (cell p, its face d; cell q, its face e = ``back[p, d]``) the
    vertices of p's piece on its local face d are matched to those of q's piece on face e with the
    same face coordinates: the sweep coordinate w as it is, the in-plane face coordinate u as ``u``
    or, where the shared edge runs the other way in q's frame (``flip``), ``1 - u``. Within one frame
    this is exactly :func:`crack_measure`; across a junction it is the example's sharing of boundary
    vertices carried over by the rotation of the frames. Returns ``(max_gap, unmatched, seams, mismatch)``
    (unmatched counted once per distinct (d, e, flip, label pair)).
    """
    nbr, back, flip = (np.asarray(x) for x in graph)
    lab = np.asarray(labels, np.int64).ravel()
    lib = library
    max_gap, unmatched, mismatch = 0.0, 0, 0.0
    cache: dict = {}
    groups = defaultdict(list)
    N = len(lab)
    for d in range(6):
        n = nbr[:, d]
        cells = np.flatnonzero((n >= 0) & (np.arange(N) < np.where(n >= 0, n, -1)))
        for p in cells.tolist():
            q = int(n[p])
            groups[(d, int(back[p, d]), bool(flip[p, d]), int(lab[p]), int(lab[q]))].append((p, q))
    seams = []
    for key, pairs in groups.items():
        d, e, fl, A, B = key
        if key not in cache:
            ta, tb = d >> 1, e >> 1
            sa, sb = 1.0 - (d & 1), 1.0 - (e & 1)
            LA, LB = lib.local[A], lib.local[B]
            ia = np.flatnonzero(np.abs(LA[:, ta] - sa) <= tol)
            ib = np.flatnonzero(np.abs(LB[:, tb] - sb) <= tol)

            both = len(ia) and len(ib)
            CA = _face_coords(LA[ia], ta, fl) if both else None
            CB = _face_coords(LB[ib], tb, False) if both else None
            cache[key], missing = _match_face(ia, ib, CA, CB, tol)
            mismatch = max(mismatch, curve_mismatch(lib, B, 2 * tb + 1 - (e & 1), A, 2 * ta + 1 - (d & 1), fl, tol))
            unmatched += missing
        ia, ib = cache[key]
        if len(ia) == 0:
            continue
        P = np.asarray(pairs, np.int64)
        gap, seam = _gap_and_seam(lib, A, B, ia, ib, corners, P[:, 0], P[:, 1], offsets)
        max_gap = max(max_gap, gap)
        if seam is not None:
            seams.append(seam)
    seams = np.concatenate(seams) if seams else np.zeros((0, 2), np.int64)
    return max_gap, unmatched, seams, mismatch


def quality_limits(library: PieceLibrary, labels, neighbours, *, tol: float = SEAM_TOL) -> dict:
    """Limits of a result's mesh-quality figures when its pieces join exactly, summed over its cells
    (``labels (N,)``; the library's pieces welded within ``tol`` local units):

    - ``open_edges``: each piece's open edges that lie on no cell face (the example's own: a wall
      standing on a plate, a hole in a roof) plus those lying only on cell faces without a neighbour
      (``neighbours (N, 6)``, -1: none; directions 2 axis + 0 for +axis, + 1 for -axis): the border of
      the construction space, open where the pieces were cut inside the example (an edge on the rim
      between such a face and one with a neighbour is closed by that neighbour when pieces join);
    - ``nonmanifold_edges``: each piece's own (an example's overlapping boxes), its faces stored twice
      counted once; ``duplicate_faces``: 0 (they are never written).
    """
    open_by_faces = np.zeros((len(library.faces), 64), np.int64)  # open edges by the set of cell faces they lie on
    own = np.zeros((len(library.faces), 2), np.int64)
    for lab, (L, Fp) in enumerate(zip(library.local, library.faces, strict=True)):
        if len(Fp) == 0:
            continue
        P = L[library.open_edges(lab)]
        mask = np.zeros(len(P), np.int64)
        for f in range(6):
            mask |= np.all(np.abs(P[:, :, f >> 1] - (f & 1)) <= tol, axis=1).astype(np.int64) << f
        open_by_faces[lab] = np.bincount(mask, minlength=64)
        W = weld(L, np.zeros((0, 3), np.int64), tol, return_index=True)[2][Fp]
        twice = repeated_faces(W)
        own[lab] = (edge_uses(W[~twice]) > 2).sum(), 0
    lab = np.asarray(labels, np.int64).ravel()
    local_face = 2 * (np.arange(6) >> 1) + 1 - (np.arange(6) & 1)
    has = ((np.asarray(neighbours) >= 0).astype(np.int64) << local_face[None]).sum(axis=1)
    counted = (np.arange(64)[None] & has[:, None]) == 0  # on no cell face, or only on ones without a neighbour
    return {
        "open_edges": int((open_by_faces[lab] * counted).sum()),
        "nonmanifold_edges": int(own[lab, 0].sum()),
        "duplicate_faces": int(own[lab, 1].sum()),
    }


def open_edges_off_border(V: np.ndarray, F: np.ndarray, corners: np.ndarray, neighbours, tol: float, *,
                          cls: np.ndarray | None = None) -> int:
    """Open edges of ``V (n, 3)``, ``F (m, 3)`` (positions welded within ``tol``) whose midpoint lies
    farther than ``tol`` from every cell side without a neighbour (``corners (N, 8, 3)`` with corner
    ``i + 2 j + 4 k``, ``neighbours (N, 6)``, directions 2 axis + 0 for +axis, + 1 for -axis): holes
    inside the construction space, or the example's own open edges. ``cls (n,)`` may give the weld
    classes of ``V``."""
    import trimesh

    if len(F) == 0:
        return 0
    if cls is None:
        cls = weld(V, np.zeros((0, 3), np.int64), tol, return_index=True)[2]
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])[edge_uses(cls[F]) == 1]
    if len(E) == 0:
        return 0
    cell, d = np.nonzero(np.asarray(neighbours) < 0)
    if len(cell) == 0:
        return int(len(E))
    axis, side = d >> 1, 1 - (d & 1)
    quad = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])
    idx = np.zeros((len(cell), 4), np.int64)
    for q, (u, v) in enumerate(quad):
        bits = np.zeros((len(cell), 3), np.int64)
        bits[np.arange(len(cell)), axis] = side
        bits[np.arange(len(cell)), (axis + 1) % 3] = u
        bits[np.arange(len(cell)), (axis + 2) % 3] = v
        idx[:, q] = bits[:, 0] + 2 * bits[:, 1] + 4 * bits[:, 2]
    P = np.asarray(corners)[cell[:, None], idx].reshape(-1, 3)
    base = 4 * np.arange(len(cell))[:, None]
    T = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    border = trimesh.Trimesh(P, T, process=False)
    _, dist, _ = trimesh.proximity.closest_point(border, V[E].mean(axis=1))
    return int((dist > tol).sum())
