"""Model analysis (paper section 2.1): lattice, pieces e_ijk, feature vectors, labels, constraints.

All functions are pure (arrays in, arrays out). Lattice axes are the example's world axes X, Y, Z;
a piece's vertices are kept in *local* coordinates of its lattice cell, ``(x - cell_lo) / unit``,
so a piece in [0, 1]^3 can be deformed into any hexahedron by trilinear FFD.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.core.mesh import clip_by_planes, face_areas, remove_unreferenced, split_by_planes
from synthkit.core.quality import degenerate_faces
from synthkit.errors import KeyedError
from synthkit.methods.petri.appearance import Look, carry
from synthkit.methods.petri.curves import VIEW_AXES
from synthkit.methods.petri.joints import close_t_junctions
from synthkit.methods.petri.options import LatticeOptions

MAX_PIECES = 200_000

SEAM_TOL = 1e-5
"""Local units within which a vertex lies on a cell face and two pieces' face vertices coincide (the
float32 rounding of exported assets, about 1e-7 of their coordinates, stays well inside)."""


@dataclass
class LatticeSpec:
    """A lattice of ``counts`` cells of size ``unit`` starting at ``origin`` (all (3,) arrays, X Y Z)."""

    unit: np.ndarray
    origin: np.ndarray
    counts: np.ndarray

    def cell_lo(self, ijk) -> np.ndarray:
        """Lower corner(s) ``(..., 3)`` of cell(s) ``ijk (..., 3)``."""
        return self.origin + np.asarray(ijk) * self.unit


@dataclass
class Pieces:
    """The example cut by the lattice.

    ``local[p] (n_p, 3)`` vertex positions in cell-local coordinates, ``faces[p] (m_p, 3)``,
    ``src_face[p] (m_p,)`` the example face each came from, ``look[p]`` their appearance (when the
    example's look was given); pieces are in C order of ``index (P, 3)``.
    """

    lattice: LatticeSpec
    index: np.ndarray
    local: list[np.ndarray] = field(default_factory=list)
    faces: list[np.ndarray] = field(default_factory=list)
    src_face: list[np.ndarray] = field(default_factory=list)
    look: list[Look] = field(default_factory=list)


@dataclass
class Constraints:
    """Adjacency constraints <L1, L2> per lattice axis (eq. 4).

    ``allowed[axis, a, b]`` is True when a piece labelled ``a`` has a neighbour labelled ``b`` at
    +1 along ``axis`` somewhere in the example. Index ``n_labels`` stands for "outside the lattice"
    when ``boundary`` is on (so ``allowed[axis, a, OUT]`` says ``a`` may end the model on that side).
    """

    allowed: np.ndarray
    n_labels: int
    boundary: bool

    @property
    def out(self) -> int:
        return self.n_labels


@dataclass
class Example:
    """The example analysed (section 2.1): its lattice ``spec``, ``pieces``, feature vectors
    ``features (P, 15)``, label ``grid (nx, ny, nz)``, each label's representative piece ``reps (L,)``
    and the adjacency constraints ``cons``."""

    spec: LatticeSpec
    pieces: Pieces
    features: np.ndarray
    grid: np.ndarray
    reps: np.ndarray
    cons: Constraints


def analyse(V, F, opts: LatticeOptions, look: Look | None = None) -> Example:
    """Lattice, pieces, labels and constraints of the example ``V (#V, 3)``, ``F (#F, 3)`` (section
    2.1); ``look`` the example faces' appearance, carried into the pieces. Raises :class:`KeyedError`
    when the lattice does not fit (:func:`resolve_lattice`)."""
    spec = resolve_lattice(V.min(axis=0), V.max(axis=0), unit=opts.unit, origin=opts.origin,
                           annotation=opts.annotation, fit_tolerance=opts.fit_tolerance)
    pieces = cut_pieces(V, F, spec, caps=opts.caps, look=look)
    features = feature_vectors(pieces)
    labels, reps = classify(
        features,
        tolerance=opts.tolerance,
        pieces=pieces if opts.match_geometry else None,
        seams=[face_seams(L, Fp) for L, Fp in zip(pieces.local, pieces.faces, strict=True)],
    )
    grid = labels.reshape(tuple(spec.counts))
    return Example(spec, pieces, features, grid, reps, adjacency_constraints(grid, len(reps), boundary=opts.boundary))


def resolve_lattice(
    lo,
    hi,
    *,
    unit=None,
    origin=None,
    annotation=None,
    fit_tolerance: float = 0.02,
) -> LatticeSpec:
    """The lattice covering the box ``[lo, hi]`` of the example.

    Either ``unit (3,)`` (and optional ``origin (3,)``, default ``lo``) or ``annotation = (view, rect,
    depth_unit)``: the rectangle gives the unit and a lattice corner in the view's two axes; along the
    depth axis the unit is ``depth_unit`` (None: the whole depth is one layer) from ``lo``. The lattice
    is replicated both ways from that corner; the example's box must start and end on lattice planes
    within ``fit_tolerance`` units, else :class:`KeyedError` ("... does not fit the model", its key
    ``unit``, ``annotation.rect`` or ``annotation.depth_unit`` and the value).
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    ext = hi - lo
    if annotation is not None:
        view, rect, depth_unit = annotation
        ax, ay, az = VIEW_AXES[view]
        x0, y0, x1, y1 = (float(v) for v in rect)
        u = np.zeros(3)
        o = lo.copy()
        u[ax], u[ay] = x1 - x0, y1 - y0
        o[ax], o[ay] = x0, y0
        u[az] = float(depth_unit) if depth_unit is not None else max(ext[az], 1e-12)
        for axis, a0, a1 in ((ax, x0, x1), (ay, y0, y1)):
            tol = fit_tolerance * u[axis]
            if a0 < lo[axis] - tol or a1 > hi[axis] + tol:
                raise KeyedError(
                    "annotation.rect", f"{list(rect)} lies outside the example's extent "
                    f"[{lo[axis]:.4g}, {hi[axis]:.4g}] along {'XYZ'[axis]} in the {view} view"
                )
    else:
        u = np.asarray(unit, dtype=np.float64).reshape(3)
        o = lo.copy() if origin is None else np.asarray(origin, dtype=np.float64).reshape(3)
    a = (lo - o) / u
    b = (hi - o) / u
    n0, n1 = np.round(a), np.round(b)
    for axis in range(3):
        if ext[axis] <= 0 and n1[axis] == n0[axis]:
            n1[axis] = n0[axis] + 1
            continue
        bad = abs(a[axis] - n0[axis]) > fit_tolerance or abs(b[axis] - n1[axis]) > fit_tolerance
        if bad or n1[axis] - n0[axis] < 1:
            if annotation is None:
                key, value = "unit", f"{u.tolist()}" + ("" if origin is None else f" with lattice.origin {o.tolist()}")
            elif axis == VIEW_AXES[annotation[0]][2]:
                key, value = "annotation.depth_unit", f"{annotation[2]}"
            else:
                key, value = "annotation.rect", f"{list(annotation[1])}"
            raise KeyedError(
                key, f"{value} does not fit the model: along {'XYZ'[axis]} the example spans "
                f"[{lo[axis]:.6g}, {hi[axis]:.6g}] = {b[axis] - a[axis]:.4g} units of {u[axis]:.6g} from the "
                f"lattice corner {o[axis]:.6g} (needs a whole number within {fit_tolerance})"
            )
    counts = (n1 - n0).astype(np.int64)
    if int(np.prod(counts)) > MAX_PIECES:
        raise KeyedError(
            "unit" if annotation is None else "annotation",
            f"the lattice does not fit the model: {counts.tolist()} cells is more than {MAX_PIECES}",
        )
    return LatticeSpec(unit=u, origin=o + n0 * u, counts=counts)


def snap_to_lattice(V, F, lattice: LatticeSpec, *, tol: float = SEAM_TOL):
    """``V (#V, 3)`` with every coordinate within ``tol`` units of a lattice plane moved onto it, and
    the faces of ``F (#F, 3)`` that are then degenerate (:func:`synthkit.core.quality.degenerate_faces`).

    Exported assets store positions in float32, so a wall meant to stand on a lattice plane often
    ends 1e-7 beside it; cut there, it would leave slivers that thin along every cut (a road tile:
    553 of 6,400 written faces with an edge under 1e-9). Returns ``(V, kept (#F,) bool)``."""
    V = np.array(V, np.float64)
    x = (V - lattice.origin) / lattice.unit
    r = np.round(x)
    near = np.abs(x - r) <= tol
    V[near] = (lattice.origin + r * lattice.unit)[near]
    return V, ~degenerate_faces(V, F)


def cut_pieces(V, F, lattice: LatticeSpec, *, caps: str = "open", look: Look | None = None) -> Pieces:
    """Cut the example ``V (#V, 3)``, ``F (#F, 3)`` along every interior lattice plane into pieces.

    Coordinates within :data:`SEAM_TOL` units of a lattice plane are first moved onto it and faces
    left degenerate dropped (:func:`snap_to_lattice`), so no cut leaves a sliver; faces with a vertex
    inside an open edge are split there (:func:`joints.close_t_junctions`; the example's T-junctions,
    often filled with zero-area faces that are dropped). Faces are split
    exactly (:func:`synthkit.core.mesh.split_by_planes`), so neighbouring pieces
    share their cut vertices bitwise; each face goes to the cell holding its centroid (clamped to the
    lattice for faces just outside within the fit tolerance). A face lying on a lattice plane goes to
    the cell behind it (its centroid is moved 1e-7 units against its normal first), so the roof of a
    box ending on a plane stays with the box. ``caps="open"`` leaves cut faces open.
    ``"capped"`` instead clips the example to each cell by the cell's interior lattice planes with
    :func:`synthkit.core.mesh.clip_by_planes` (``cap=True``), which closes every cut with planar caps
    (cap faces get ``src_face = -1``; meaningful for closed examples). With ``look`` (the example
    faces' appearance) each piece gets its faces' look (:func:`appearance.carry`: values at cut
    points interpolated in the example face).
    """
    V, kept = snap_to_lattice(V, F, lattice)
    F = np.asarray(F, np.int64)[kept]
    look = None if look is None else look.take(kept)
    # a zero-area face filling a T-junction leaves it open when dropped: split the face across instead
    F, _, _, look = close_t_junctions(V, F, np.arange(len(F)), [], look, SEAM_TOL * float(lattice.unit.min()))
    if caps == "capped":
        return _capped_pieces(V, F, lattice, look)
    normals, offsets = [], []
    for axis in range(3):
        for m in range(1, int(lattice.counts[axis])):
            n = np.zeros(3)
            n[axis] = 1.0
            normals.append(n)
            offsets.append(lattice.origin[axis] + m * lattice.unit[axis])
    if normals:
        V2, F2, src = split_by_planes(V, F, np.array(normals), np.array(offsets))
    else:
        V2, F2, src = np.asarray(V, np.float64), np.asarray(F, np.int64), np.arange(len(F))
    T = V2[F2]
    cent = T.mean(axis=1)
    # a face lying on a lattice plane belongs to the solid behind it: nudge centroids against the normal
    nrm = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    nlen = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.divide(nrm, nlen, out=np.zeros_like(nrm), where=nlen > 0)
    cent = cent - 1e-7 * lattice.unit * nrm
    cell = np.floor((cent - lattice.origin) / lattice.unit).astype(np.int64)
    cell = np.clip(cell, 0, lattice.counts - 1)
    flat = np.ravel_multi_index(cell.T, tuple(lattice.counts))
    n_cells = int(np.prod(lattice.counts))
    order = np.argsort(flat, kind="stable")
    bounds = np.searchsorted(flat[order], np.arange(n_cells + 1))
    index = np.stack(np.unravel_index(np.arange(n_cells), tuple(lattice.counts)), axis=1)
    pieces = Pieces(lattice=lattice, index=index)
    looks = None if look is None else carry(look, V, F, src, V2, F2)
    for p in range(n_cells):
        sel = order[bounds[p] : bounds[p + 1]]
        used, Fp = np.unique(F2[sel], return_inverse=True)
        pieces.local.append((V2[used] - lattice.cell_lo(index[p])) / lattice.unit)
        pieces.faces.append(Fp.reshape(-1, 3).astype(np.int64))
        pieces.src_face.append(src[sel])
        if looks is not None:
            pieces.look.append(looks.take(sel))
    return pieces


def _capped_pieces(V, F, lattice: LatticeSpec, look: Look | None) -> Pieces:
    """Pieces by clipping with caps: slabs along X, each cut into Y slabs, each into Z cells, so every
    face is clipped only against the planes around it. Only interior lattice planes cut."""
    counts = lattice.counts
    n_cells = int(np.prod(counts))
    index = np.stack(np.unravel_index(np.arange(n_cells), tuple(counts)), axis=1)
    out: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def split(Vm, Fm, Sm, axis, prefix):
        if axis == 3:
            out[prefix] = (Vm, Fm, Sm)
            return
        n = np.zeros(3)
        n[axis] = 1.0
        for i in range(int(counts[axis])):
            lo = lattice.origin[axis] + i * lattice.unit[axis]
            normals, offsets = [], []
            if i < counts[axis] - 1:
                normals.append(n)
                offsets.append(lo + lattice.unit[axis])
            if i > 0:
                normals.append(-n)
                offsets.append(-lo)
            if normals and len(Fm):
                Vi, Fi, keep = clip_by_planes(Vm, Fm, np.array(normals), np.array(offsets), cap=True)
                Si = np.where(keep >= 0, Sm[np.maximum(keep, 0)], -1)
            else:
                Vi, Fi, Si = Vm, Fm, Sm
            split(Vi, Fi, Si, axis + 1, prefix + (i,))

    F = np.asarray(F, np.int64)
    split(np.asarray(V, np.float64), F, np.arange(len(F)), 0, ())
    pieces = Pieces(lattice=lattice, index=index)
    for p in range(n_cells):
        Vp, Fp, Sp = out[tuple(int(v) for v in index[p])]
        Vp, Fp, _ = remove_unreferenced(Vp, Fp)
        pieces.local.append((Vp - lattice.cell_lo(index[p])) / lattice.unit)
        pieces.faces.append(Fp)
        pieces.src_face.append(Sp)
        if look is not None:
            pieces.look.append(carry(look, V, F, Sp, Vp, Fp))
    return pieces


def feature_vectors(pieces: Pieces, *, corner_tol: float = 1e-6) -> np.ndarray:
    """Feature vector of eq. (1) per piece, ``(P, 15)``: ``[S, X0, Y0, Z0, X1, Y1, Z1, f000 .. f111]``.

    ``S`` is the surface area in world units; the bounding box is in cell-local coordinates (so that
    translated copies agree); ``f_ijk`` (order ``i j k`` as in the paper: f000, f001, f010, ...) is 1 when
    the box corner ``[X^i, Y^j, Z^k]`` is a vertex of the piece (within ``corner_tol`` local units).
    An empty piece has all zeros.
    """
    unit = pieces.lattice.unit
    out = np.zeros((len(pieces.local), 15))
    for p, (L, Fp) in enumerate(zip(pieces.local, pieces.faces, strict=True)):
        if len(Fp) == 0:
            continue
        out[p, 0] = face_areas(L * unit, Fp).sum()
        bmin, bmax = L.min(axis=0), L.max(axis=0)
        out[p, 1:4], out[p, 4:7] = bmin, bmax
        f = 7
        for i in (0, 1):
            for j in (0, 1):
                for k in (0, 1):
                    corner = np.array([(bmin, bmax)[i][0], (bmin, bmax)[j][1], (bmin, bmax)[k][2]])
                    out[p, f] = float(np.any(np.all(np.abs(L - corner) <= corner_tol, axis=1)))
                    f += 1
    return out


def face_seams(L: np.ndarray, F: np.ndarray, *, tol: float = SEAM_TOL) -> list[tuple[np.ndarray, np.ndarray]]:
    """What a piece ``L (n, 3)`` (cell-local), ``F (m, 3)`` shows on each of its cell's six faces (order
    -X, +X, -Y, +Y, -Z, +Z): ``(points (k, 2), segments (e, 2, 2))``, its vertices on the face and its
    edges lying in the face, in the face's other two local coordinates."""
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]) if len(F) else np.zeros((0, 2), np.int64)
    out = []
    for t in range(3):
        others = [x for x in range(3) if x != t]
        for side in (0.0, 1.0):
            on = np.abs(L[:, t] - side) <= tol
            Es = E[on[E[:, 0]] & on[E[:, 1]]]
            out.append((L[on][:, others], L[Es][:, :, others]))
    return out


def curve_gap(P: np.ndarray, S: np.ndarray) -> float:
    """The largest distance from a point of ``P (n, 2)`` to its nearest segment of ``S (e, 2, 2)``: 0 for
    no points, infinite for points and no segments."""
    if len(P) == 0:
        return 0.0
    if len(S) == 0:
        return float("inf")
    A, D = S[:, 0], S[:, 1] - S[:, 0]
    dd = np.maximum((D * D).sum(axis=1), 1e-300)
    worst = 0.0
    step = max(1, (1 << 20) // len(S))
    for i in range(0, len(P), step):
        Q = P[i : i + step, None]
        t = np.clip(((Q - A[None]) * D[None]).sum(axis=2) / dd[None], 0.0, 1.0)
        worst = max(worst, float(np.linalg.norm(Q - (A[None] + t[..., None] * D[None]), axis=2).min(axis=1).max()))
    return worst


def same_seams(a, b, tol: float = SEAM_TOL) -> bool:
    """Whether two pieces' :func:`face_seams` show the same curves on every cell face: each one's face
    vertices lie on the other's face edges (so they differ at most by where their edges are split)."""
    return all(
        _same_vertices(pa, pb, tol) or (curve_gap(pa, sb) <= tol and curve_gap(pb, sa) <= tol)
        for (pa, sa), (pb, sb) in zip(a, b, strict=True)
    )


def _same_vertices(A: np.ndarray, B: np.ndarray, tol: float) -> bool:
    """Whether every point of ``A (n, 2)`` has one of ``B (m, 2)`` within ``tol`` and vice versa (the
    common case of :func:`same_seams`, decided without the segments)."""
    if len(A) == 0 or len(B) == 0:
        return len(A) == len(B)
    return bool(cKDTree(B).query(A)[0].max() <= tol and cKDTree(A).query(B)[0].max() <= tol)


def classify(features: np.ndarray, *, tolerance: float, pieces: Pieces | None = None,
             seams: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Labels from feature vectors: greedy, in piece order.

    A piece joins the first label whose representative (its first piece) has equal corner flags,
    an area within ``tolerance`` x the larger area, and bounding-box bounds within ``tolerance``
    local units; otherwise it starts a new label. With ``pieces`` given (the "geometry" match, an
    addition to the paper: eq. 1 cannot tell a piece from its mirror image), the two pieces' vertices
    and face centroids must also lie within ``tolerance`` local units of each other both ways.
    With ``seams`` (each piece's :func:`face_seams`) the two pieces must also show the same curves
    on each of the six cell faces (:func:`same_seams`; why: ``docs/findings/petri-synth.md``).
    Returns ``(labels (P,), representative (L,))``.
    """
    labels = np.full(len(features), -1, np.int64)
    reps: list[int] = []
    trees: dict[int, cKDTree] = {}

    def points(p: int) -> np.ndarray:
        L, Fp = pieces.local[p], pieces.faces[p]
        return np.concatenate([L, L[Fp].mean(axis=1)]) if len(Fp) else L

    def same_shape(p: int, r: int) -> bool:
        A, B = points(p), points(r)
        if len(A) == 0 or len(B) == 0:
            return len(A) == len(B)
        if r not in trees:
            trees[r] = cKDTree(B)
        if p not in trees:
            trees[p] = cKDTree(A)
        return bool(trees[r].query(A)[0].max() <= tolerance + 1e-12 and trees[p].query(B)[0].max() <= tolerance + 1e-12)

    for p, fv in enumerate(features):
        if reps:
            R = features[reps]
            area_ok = np.abs(R[:, 0] - fv[0]) <= tolerance * np.maximum(np.maximum(R[:, 0], fv[0]), 1e-300)
            area_ok |= (R[:, 0] == 0) & (fv[0] == 0)
            box_ok = np.all(np.abs(R[:, 1:7] - fv[1:7]) <= tolerance + 1e-12, axis=1)
            flag_ok = np.all(R[:, 7:] == fv[7:], axis=1)
            hit = np.flatnonzero(area_ok & box_ok & flag_ok)
            if pieces is not None:
                hit = [h for h in hit if same_shape(p, reps[h])]
            if seams is not None:
                hit = [h for h in hit if same_seams(seams[p], seams[reps[h]])]
            if len(hit):
                labels[p] = hit[0]
                continue
        labels[p] = len(reps)
        reps.append(p)
    return labels, np.asarray(reps, np.int64)


def adjacency_constraints(label_grid: np.ndarray, n_labels: int, *, boundary: bool = True) -> Constraints:
    """Allowed label pairs per axis from the example's ``label_grid (nx, ny, nz)`` (eq. 4).

    With ``boundary`` the grid is padded with the outside label ``n_labels`` so that which labels may
    end the model on each side is a constraint too.
    """
    n = n_labels + 1
    grid = np.pad(label_grid, 1, constant_values=n_labels) if boundary else label_grid
    allowed = np.zeros((3, n, n), bool)
    for axis in range(3):
        a = np.moveaxis(grid, axis, 0)
        first, second = a[:-1].ravel(), a[1:].ravel()
        allowed[axis, first, second] = True
    if boundary:
        allowed[:, n_labels, n_labels] = False
    return Constraints(allowed=allowed, n_labels=n_labels, boundary=boundary)


def join_ends(cons: Constraints, axis: int) -> Constraints:
    """``cons`` with the example's ends along ``axis`` joined: a label that may end the model at
    +axis may be followed there by any label that may begin it at -axis (``allowed[axis, a, OUT]``
    and ``allowed[axis, OUT, b]`` give ``allowed[axis, a, b]``), as if a copy of the example stood
    against it. Pairs of the other axes and the outside's own pairs are kept. Needs ``cons.boundary``."""
    if not cons.boundary:
        raise ValueError("joining the example's ends needs the outside as a label (labels.boundary: true)")
    A = cons.allowed.copy()
    L = cons.n_labels
    A[axis, :L, :L] |= np.outer(A[axis, :L, L], A[axis, L, :L])
    return Constraints(allowed=A, n_labels=L, boundary=True)


def _bool_power(M: np.ndarray, k: int) -> np.ndarray:
    """``M (n, n)`` (0/1 int64) to the power ``k >= 0`` as a 0/1 matrix: which walks of ``k`` steps exist."""
    out = np.eye(len(M), dtype=np.int64)
    while k:
        if k & 1:
            out = np.minimum(out @ M, 1)
        M = np.minimum(M @ M, 1)
        k >>= 1
    return out


def row_lengths(allowed_axis: np.ndarray, n_labels: int, row: np.ndarray, lo: int, hi: int, *, closed: bool):
    """``(hi - lo + 1,) bool``: which lengths ``k = lo .. hi`` (``lo >= 1``) a row of cells along one axis
    can take with the labels of the example row ``row (n,)`` alone under ``allowed_axis (L + 1, L + 1)``:
    a path of ``k`` labels from one that may follow the outside to one the outside may follow, or
    (``closed``) a cycle of ``k`` labels."""
    A = np.asarray(allowed_axis, bool)
    R = np.unique(row)
    step = A[np.ix_(R, R)].astype(np.int64)
    ok = np.zeros(hi - lo + 1, bool)
    if closed:
        walk = _bool_power(step, lo)
        for i in range(len(ok)):
            ok[i] = bool(np.trace(walk) > 0)
            walk = np.minimum(walk @ step, 1)
        return ok
    reach = np.minimum(A[n_labels, R].astype(np.int64) @ _bool_power(step, lo - 1), 1)
    for i in range(len(ok)):
        ok[i] = bool((reach.astype(bool) & A[R, n_labels]).any())
        reach = np.minimum(reach @ step, 1)
    return ok


def row_fits(label_grid: np.ndarray, cons: Constraints, axis: int, cells: int, *, closed: bool):
    """``(lo, fits)``: per row of ``label_grid (nx, ny, nz)`` along ``axis`` (C order of the other two
    axes), which lengths ``lo .. cells + n`` a row of cells can take with that row's labels
    (:func:`row_lengths`), ``fits (R, cells + n - lo + 1) bool``, ``n`` the example's count along
    ``axis`` and ``lo = max(1, cells - n)``. A joined example (:func:`join_ends`) takes every multiple
    of ``n`` in every row, so this window holds the nearest length that every row takes."""
    rows = np.moveaxis(label_grid, axis, -1)
    n = rows.shape[-1]
    lo, hi = max(1, cells - n), cells + n
    A, L = cons.allowed[axis], cons.n_labels
    fits = [row_lengths(A, L, rows[idx], lo, hi, closed=closed) for idx in np.ndindex(rows.shape[:-1])]
    return lo, np.array(fits)


def nearest_fit(lo: int, fits: np.ndarray, cells: int) -> int | None:
    """The length nearest to ``cells`` (ties: the shorter) that every row of ``fits (R, m)`` takes,
    lengths starting at ``lo`` (:func:`row_fits`), or None when there is none."""
    every = (lo + np.flatnonzero(fits.all(axis=0))).tolist()
    return min(every, key=lambda k: (abs(k - cells), k)) if every else None


def length_hint(label_grid: np.ndarray, cons: Constraints, axis: int, cells: int, *, closed: bool, unit: float):
    """Why ``cells`` cells along world ``axis`` (the curve's, ``unit`` long each) cannot be filled when
    every row of ``label_grid (nx, ny, nz)`` can repeat: the rows whose labels fit no row of that
    length (:func:`row_fits`), and the nearest length every row fits. None when each row fits."""
    lo, fits = row_fits(label_grid, cons, axis, cells, closed=closed)
    stuck = int((~fits[:, cells - lo]).sum())
    if not stuck:
        return None
    name = "XYZ"[axis]
    best = nearest_fit(lo, fits, cells)
    fix = (
        f"make the curve {best * unit:.4g} long, {best} cells of {unit:.4g} (it is cut into {cells})"
        if best is not None
        else f"choose the lattice along {name} so that pieces repeat within every row"
    )
    return (
        f"{stuck} of the example's {len(fits)} rows along {name} admit no row of {cells} cells with their "
        f"own pieces ({'closed' if closed else 'open'} curve): {fix}"
    )


FACADE_SLOPE = 0.1
"""A face is a facade face when its unit normal's component along the up axis is at most this
(within about 5.7 degrees of vertical): walls, window frames and door reveals, not floors or roofs."""


def _facade_faces(V, F, up_axis: int, slope: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(n (#F, 3) twice-area normals, double_area (#F,), facade (#F,) bool)`` of ``V (#V, 3)``,
    ``F (#F, 3)``: a facade face has non-zero area and ``|n[up_axis]| <= slope`` for its unit normal."""
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    double_area = np.linalg.norm(n, axis=1)
    return n, double_area, (np.abs(n[:, up_axis]) <= slope * double_area) & (double_area > 0)


ACROSS_COS = np.sqrt(0.5)
"""A facade face faces across the curve when its unit normal is within 45 degrees of the cell's
across direction (construction axis b), either way."""


def facade_areas(V, F, across, up_axis: int, *, slope: float = FACADE_SLOPE) -> tuple[float, float]:
    """``(facade, facing across)`` areas of ``V (#V, 3)``, ``F (#F, 3)`` from one pass: facade faces
    have a unit normal ``n`` with ``|n[up_axis]| <= slope`` (:data:`FACADE_SLOPE`); of those, the
    ones facing across the curve have ``|n . across| >= cos 45`` (:data:`ACROSS_COS`) for
    ``across (#F, 3)``, the unit across direction of each face's cell. Street fronts and backs face
    across; walls facing along the curve (end walls, walls between copies) do not."""
    n, double_area, facade = _facade_faces(V, F, up_axis, slope)
    across = np.asarray(across, np.float64).reshape(-1, 3)
    facing = np.abs(np.einsum("ij,ij->i", n, across)) >= ACROSS_COS * double_area
    return float(0.5 * double_area[facade].sum()), float(0.5 * double_area[facing & facade].sum())


def facade_cells(neighbours: np.ndarray, directions) -> int:
    """Facade cells of a space: cell sides in ``directions`` (of the six, 2 axis + 0 for +axis, + 1
    for -axis; the horizontal ones) without a neighbour, from ``neighbours (N, 6)`` (-1: none). A
    corner cell counts twice, so the facade area per facade cell is comparable between the example
    and a result of another shape."""
    nbr = np.asarray(neighbours)
    return int((nbr[:, list(directions)] < 0).sum())


def repeatable_labels(allowed_axis: np.ndarray, n_labels: int) -> np.ndarray:
    """``(L,) bool``: labels that may occur any number of times in a row along one axis, i.e. lie on
    a cycle of ``allowed_axis (L + 1, L + 1)`` (the outside, index L, excluded)."""
    A = np.asarray(allowed_axis, bool)[:n_labels, :n_labels]
    if n_labels == 0:
        return np.zeros(0, bool)
    count, comp = connected_components(csr_matrix(A), directed=True, connection="strong")
    sizes = np.bincount(comp, minlength=count)
    return (sizes[comp] > 1) | np.diag(A)


def growth_hint(label_grid: np.ndarray, cons: Constraints, axis: int, unit_key: str) -> str | None:
    """Why the example cannot grow along world ``axis`` (the curve's), or None when it can: the rows
    of ``label_grid (nx, ny, nz)`` along ``axis`` holding no label that may repeat along it, and the
    lattice change that would help.

    Why ``labels.join_ends: auto`` exists: ``docs/findings/petri-synth.md``."""
    repeat = repeatable_labels(cons.allowed[axis], cons.n_labels)
    rows = np.moveaxis(label_grid, axis, -1)
    stuck = [idx for idx in np.ndindex(rows.shape[:-1]) if not repeat[rows[idx]].any()]
    if not stuck:
        return None
    others = [a for a in range(3) if a != axis]
    names = ", ".join(
        "(" + ", ".join(f"{'XYZ'[a]}={i}" for a, i in zip(others, idx, strict=True)) + ")" for idx in stuck[:4]
    )
    more = f" and {len(stuck) - 4} more" if len(stuck) > 4 else ""
    unit = unit_key.replace(", along", " (along") + ")" if ", along" in unit_key else unit_key
    return (
        f"{len(stuck)} of the example's {int(np.prod(rows.shape[:-1]))} rows along {'XYZ'[axis]} ({names}{more}) hold "
        f"no piece that may repeat along {'XYZ'[axis]}, so the example cannot grow past its "
        f"{rows.shape[-1]} units there: choose {unit} so that pieces repeat within every row (a window "
        f"or bay width), or raise labels.tolerance"
        + (", or set labels.join_ends: auto (copies of the example side by side)" if cons.boundary else "")
    )


def normal_histogram(V, F, axes: tuple[int, int], *, bins: int = 12) -> np.ndarray:
    """Histogram ``(bins,)`` of face-normal directions in the plane of world ``axes`` (paper section 3.2).

    Each face counts once (the paper: "the normal of each face"); its normal's two components along
    ``axes`` give an angle in [0, 360) split into ``bins`` equal parts (bin 0 starts at angle 0).
    Faces whose normal has no in-plane component (below 1e-6 after normalising) have no direction and are left out.
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    a, b = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    n = [a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
         a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]]  # fmt: skip
    x, y = n[axes[0]], n[axes[1]]
    in_plane = x * x + y * y
    keep = in_plane > 1e-12 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    # bin positions rounded to 1e-6 so that normals on a bin edge (axis-aligned ones) land in one bin
    pos = np.round(np.arctan2(y[keep], x[keep]) / (2 * np.pi) * bins, 6)
    idx = np.floor(pos).astype(np.int64) % bins
    return np.bincount(idx, minlength=bins).astype(np.float64)


def histogram_discrimination(h1, h2) -> float:
    """D(H1, H2) of eq. (5): squared differences of the two normalised histograms, summed.

    NaN (reported as null) when a histogram is empty: a mesh whose faces all face along the sweep
    axis (floor slabs only) has no in-plane normal direction, and D is undefined for it."""
    h1 = np.asarray(h1, np.float64)
    h2 = np.asarray(h2, np.float64)
    if h1.sum() <= 0 or h2.sum() <= 0:
        return float("nan")
    return float(np.sum((h1 / h1.sum() - h2 / h2.sum()) ** 2))
