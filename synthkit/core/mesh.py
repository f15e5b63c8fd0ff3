"""Functions over indexed triangle meshes in ``V (#V, 3) float64``, ``F (#F, 3) int64`` form.

Pure numpy/scipy (plus pymeshlab for decimation): no files. Conventions:

- ``V`` vertex positions, ``F`` triangle corner indices; other integer index arrays are int64.
- A face's normal follows the right-hand rule on ``(F[:, 0], F[:, 1], F[:, 2])``.
- ``TOL`` is the one relative tolerance used to decide "on the plane" when clipping.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.core.tol import tol

__all__ = [
    "TOL",
    "checked_plane_args",
    "split_by_plane",
    "as_mesh_arrays",
    "normalize_unit",
    "face_normals",
    "vertex_normals",
    "barycentric",
    "child_uvs",
    "consistent_winding",
    "face_areas",
    "vertex_areas",
    "edge_lengths",
    "vertex_graph_edges",
    "face_adjacency",
    "dihedral_angles",
    "poisson_disk_sample",
    "simplify",
    "clip_by_planes",
    "clip_by_box",
    "split_by_planes",
    "weld",
    "merge_vertices",
    "remove_unreferenced",
    "boundary_loops",
    "triangulate_polygons",
    "cap_plane",
]

TOL = tol.plane
"""Relative tolerance (times the bounding-box diagonal) for a vertex to count as on a clipping plane
(:attr:`~synthkit.core.tol.Tolerances.plane`)."""


def as_mesh_arrays(V, F) -> tuple[np.ndarray, np.ndarray]:
    """Validate and convert ``V (#V, 3)`` to float64 and ``F (#F, 3)`` to int64.

    Raises ValueError for wrong shapes, non-finite positions or out-of-range indices.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"V must have shape (n, 3), got {V.shape}")
    if F.size == 0:
        F = F.reshape(0, 3)
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"F must have shape (m, 3), got {F.shape}")
    if not np.issubdtype(F.dtype, np.integer):
        raise ValueError(f"F must hold integer indices, got dtype {F.dtype}")
    F = F.astype(np.int64, copy=False)
    if not np.all(np.isfinite(V)):
        raise ValueError("V holds NaN or infinite coordinates")
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise ValueError(f"F indices must lie in [0, {len(V) - 1}], got [{F.min()}, {F.max()}]")
    return V, F


def normalize_unit(V) -> tuple[np.ndarray, np.ndarray, float]:
    """Translate and scale ``V (n, 3)`` so that its longest bounding-box side spans [-1, 1].

    Returns ``(Vn (n, 3), center (3,), scale)`` with ``Vn = (V - center) / scale``; ``center`` is the
    bounding-box centre and ``scale`` half the longest side. Raises ValueError for an empty or
    zero-extent point set.
    """
    V = np.asarray(V, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
        raise ValueError(f"V must have shape (n, 3) with n > 0, got {V.shape}")
    if not np.all(np.isfinite(V)):
        raise ValueError("V holds NaN or infinite coordinates")
    lo, hi = V.min(axis=0), V.max(axis=0)
    scale = float((hi - lo).max()) / 2.0
    if scale <= 0.0:
        raise ValueError("V has zero extent: cannot normalize a single point")
    center = (lo + hi) / 2.0
    return (V - center) / scale, center, scale


def face_normals(V, F) -> np.ndarray:
    """Unit normals ``(#F, 3)``; a degenerate (zero-area) face gets the zero vector."""
    V, F = as_mesh_arrays(V, F)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


def vertex_normals(V, F, *, weights: str = "area") -> np.ndarray:
    """Vertex normals ``(#V, 3)`` (unit; zero for isolated vertices), the sum of the incident
    face normals weighted by face area (``weights="area"``) or by the face's angle at the vertex
    (``"angle"``, Thuermer and Wuethrich 1998: independent of how a flat region is triangulated)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    if weights not in ("area", "angle"):
        raise ValueError(f"weights must be 'area' or 'angle', got {weights!r}")
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    fn = np.cross(b - a, c - a)  # length = twice the area: area weighting
    if weights == "angle":
        ln = np.linalg.norm(fn, axis=1, keepdims=True)
        fn = np.divide(fn, ln, out=np.zeros_like(fn), where=ln > 0)
    acc = np.zeros_like(V)
    tri = np.stack([a, b, c], axis=1)
    for k in range(3):
        w = 1.0
        if weights == "angle":
            e1, e2 = tri[:, (k + 1) % 3] - tri[:, k], tri[:, (k + 2) % 3] - tri[:, k]
            den = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
            cos = np.divide(np.einsum("ij,ij->i", e1, e2), den, out=np.ones(len(F)), where=den > 0)
            w = np.arccos(np.clip(cos, -1.0, 1.0))[:, None]
        np.add.at(acc, F[:, k], w * fn)
    n = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.divide(acc, n, out=np.zeros_like(acc), where=n > 0)


def barycentric(T, P) -> np.ndarray:
    """Barycentric weights ``(m, k, 3)`` of the points ``P (m, k, d)`` in the triangles
    ``T (m, 3, d)``, d = 2 or 3: least squares in the triangle's plane (a point off the plane is
    projected, one outside extrapolated). A degenerate triangle (``tol.degenerate_gram``) gives each
    point the weights of its nearest corner, so a value read through them is a corner's."""
    T, P = np.asarray(T, np.float64), np.asarray(P, np.float64)
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    d11, d12, d22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
    den = d11 * d22 - d12 * d12
    ok = den > tol.degenerate_gram * np.maximum(d11 * d22, 1e-300)
    Q = P - T[:, None, 0]
    q1, q2 = (Q * e1[:, None]).sum(-1), (Q * e2[:, None]).sum(-1)
    safe = np.where(ok, den, 1.0)[:, None]
    b1 = (d22[:, None] * q1 - d12[:, None] * q2) / safe
    b2 = (d11[:, None] * q2 - d12[:, None] * q1) / safe
    B = np.stack([1.0 - b1 - b2, b1, b2], axis=-1)
    if ok.all():
        return B
    nearest = np.argmin(np.linalg.norm(P[:, :, None] - T[:, None], axis=-1), axis=-1)
    return np.where(ok[:, None, None], B, np.eye(3)[nearest])


def consistent_winding(V, F) -> tuple[np.ndarray, np.ndarray]:
    """``F (#F, 3)`` with faces flipped so each connected piece winds one way (trimesh's
    ``fix_winding``) and the ``(#F,) bool`` mask of flipped faces."""
    import trimesh

    m = trimesh.Trimesh(V, F, process=False)
    trimesh.repair.fix_winding(m)
    G = np.asarray(m.faces, np.int64)
    return G, (G != F).any(axis=1)


def child_uvs(P: np.ndarray, uv: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Corner UVs ``(n, 3, 2)`` of child triangles ``C (n, 3, 3)`` lying in their parents ``P (n, 3, 3)``
    whose corner UVs are ``uv (n, 3, 2)``: each corner's :func:`barycentric` coordinates in its parent
    (exact for midpoint subdivision), so a subdivided mesh keeps its texture (UVs are per corner)."""
    return np.einsum("nkj,njd->nkd", barycentric(P, C), uv)


def face_areas(V, F) -> np.ndarray:
    """Triangle areas ``(#F,)``."""
    V, F = as_mesh_arrays(V, F)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return 0.5 * np.linalg.norm(n, axis=1)


def vertex_areas(V, F) -> np.ndarray:
    """Barycentric vertex areas ``(#V,)``: one third of the area of every incident face.

    They sum to the total surface area; unreferenced vertices get 0.
    """
    V, F = as_mesh_arrays(V, F)
    a = face_areas(V, F) / 3.0
    return np.bincount(F.ravel(), weights=np.repeat(a, 3), minlength=len(V))


def edge_lengths(V, F) -> np.ndarray:
    """Per-face edge lengths ``(#F, 3)`` (libigl order): column c is the edge opposite corner c,
    i.e. ``[|v1 - v2|, |v2 - v0|, |v0 - v1|]``."""
    V, F = as_mesh_arrays(V, F)
    P = V[F]
    return np.stack(
        [
            np.linalg.norm(P[:, 1] - P[:, 2], axis=1),
            np.linalg.norm(P[:, 2] - P[:, 0], axis=1),
            np.linalg.norm(P[:, 0] - P[:, 1], axis=1),
        ],
        axis=1,
    )


def vertex_graph_edges(F) -> np.ndarray:
    """Unique undirected edges ``(E, 2)`` int64 of the triangles ``F``, each with ``i < j``, sorted."""
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.sort(E, axis=1)
    E = E[E[:, 0] != E[:, 1]]
    return np.unique(E, axis=0)


def face_adjacency(F) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of faces sharing an edge.

    Returns ``(pairs (k, 2) int64, edges (k, 2) int64)``: ``pairs[r] = (f, g)`` with ``f < g`` share the
    undirected edge ``edges[r] = (i, j)``, ``i < j``. At a non-manifold edge (more than two faces) every
    pair of its faces is listed. Rows are sorted by edge, then by face pair.
    """
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    m = len(F)
    if m == 0:
        return np.zeros((0, 2), np.int64), np.zeros((0, 2), np.int64)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    fid = np.tile(np.arange(m, dtype=np.int64), 3)
    order = np.lexsort((fid, E[:, 1], E[:, 0]))
    E, fid = E[order], fid[order]
    new = np.ones(len(E), bool)
    new[1:] = np.any(E[1:] != E[:-1], axis=1)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(E)))
    pairs, edges = [], []
    for c in np.unique(counts[counts >= 2]):
        s = starts[counts == c]
        iu, ju = np.triu_indices(c, k=1)
        pairs.append(np.stack([fid[s[:, None] + iu], fid[s[:, None] + ju]], axis=-1).reshape(-1, 2))
        edges.append(np.repeat(E[s], len(iu), axis=0))
    if not pairs:
        return np.zeros((0, 2), np.int64), np.zeros((0, 2), np.int64)
    pairs = np.sort(np.concatenate(pairs), axis=1)
    edges = np.concatenate(edges)
    order = np.lexsort((pairs[:, 1], pairs[:, 0], edges[:, 1], edges[:, 0]))
    return pairs[order], edges[order]


def dihedral_angles(V, F) -> tuple[np.ndarray, np.ndarray]:
    """Signed bending angle at every interior edge.

    Returns ``(pairs (k, 2), angles (k,))`` with ``pairs`` as in :func:`face_adjacency`. The angle is
    the one between the two face normals (``pi`` minus the interior dihedral angle), in [-pi, pi]:
    0 for coplanar faces, positive where the surface is convex (the second face's far vertex lies
    below the first face's plane), negative where concave. Degenerate faces give 0.
    """
    V, F = as_mesh_arrays(V, F)
    pairs, edges = face_adjacency(F)
    N = face_normals(V, F)
    n0, n1 = N[pairs[:, 0]], N[pairs[:, 1]]
    cos = np.clip(np.sum(n0 * n1, axis=1), -1.0, 1.0)
    sin = np.linalg.norm(np.cross(n0, n1), axis=1)
    ang = np.arctan2(sin, cos)
    # far vertex of the second face: the corner not on the shared edge
    G = F[pairs[:, 1]]
    far = np.where(
        (G[:, 0] != edges[:, 0]) & (G[:, 0] != edges[:, 1]),
        G[:, 0],
        np.where((G[:, 1] != edges[:, 0]) & (G[:, 1] != edges[:, 1]), G[:, 1], G[:, 2]),
    )
    side = np.sum(n0 * (V[far] - V[edges[:, 0]]), axis=1)
    return pairs, np.where(side > 0, -ang, ang)


def poisson_disk_sample(V, F, radius: float, *, seed: int = 0, oversample: int = 10):
    """Poisson-disk samples on the surface, no two closer than ``radius`` (Euclidean distance).

    Returns ``(P (n, 3), N (n, 3))``: sample positions and the unit normals of the faces they lie on.

    Method (the one of MeshLab's ``generate_sampling_poisson_disk``: a Monte Carlo pool pruned to a
    Poisson-disk set): a pool of ``oversample`` points per disk of radius ``radius / 2`` of surface
    area (at most 4 million), drawn area-uniformly with ``np.random.default_rng(seed)`` in random
    order, then pruned in rounds on a grid of cells of side ``radius / sqrt(3)`` (a cell holds at most
    one sample): in round k every cell still without a sample offers its k-th pool point; offers
    closer than ``radius`` to a sample are dropped, and among the rest the greedy independent set in
    pool order is kept. The result is maximal for the pool (every pool point lies within ``radius`` of
    a sample). Written here rather than calling pymeshlab because pymeshlab's sampler draws from a
    process-wide generator with no seed parameter (two calls in one process return different sets);
    this one is deterministic for a seed. Distances are Euclidean, not geodesic.
    """
    V, F = as_mesh_arrays(V, F)
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    areas = face_areas(V, F)
    total = float(areas.sum())
    if total <= 0:
        raise ValueError("mesh has zero surface area")
    rng = np.random.default_rng(seed)
    n_pool = int(min(max(oversample * total / (np.pi * (radius / 2) ** 2), 16), 4_000_000))
    face = rng.choice(len(F), size=n_pool, p=areas / total)
    u, v = rng.random(n_pool), rng.random(n_pool)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    tri = V[F[face]]
    pool = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
    keep = _poisson_prune(pool, radius)
    return pool[keep], face_normals(V, F)[face[keep]]


def _poisson_prune(pool: np.ndarray, radius: float) -> np.ndarray:
    """Indices (sorted) of a maximal subset of ``pool (n, 3)`` with pairwise distances >= ``radius``,
    preferring earlier points (see :func:`poisson_disk_sample`)."""
    h = radius / np.sqrt(3.0)
    cell = np.floor((pool - pool.min(axis=0)) / h).astype(np.int64)
    dims = cell.max(axis=0) + 1
    key = (
        np.ravel_multi_index(cell.T, tuple(dims))
        if np.prod(dims.astype(float)) < 2**62
        else (np.unique(cell, axis=0, return_inverse=True)[1].reshape(-1))
    )
    order = np.lexsort((np.arange(len(pool)), key))
    sorted_key = key[order]
    start = np.r_[True, sorted_key[1:] != sorted_key[:-1]]
    group = np.cumsum(start) - 1
    rank = np.arange(len(pool)) - np.flatnonzero(start)[group]
    rank_of = np.empty(len(pool), np.int64)
    rank_of[order] = rank
    cell_of = np.empty(len(pool), np.int64)
    cell_of[order] = group
    n_cells = int(group[-1]) + 1
    filled = np.zeros(n_cells, bool)
    by_rank = np.argsort(rank_of, kind="stable")  # round k offers by_rank[bounds[k]:bounds[k + 1]], pool order
    bounds = np.searchsorted(rank_of[by_rank], np.arange(int(rank.max()) + 2))
    accepted: list[np.ndarray] = []
    n_filled = 0
    tree = None
    r_test = radius * (1 - 1e-12)
    for k in range(int(rank.max()) + 1):
        if n_filled == n_cells:
            break
        cand = by_rank[bounds[k] : bounds[k + 1]]
        cand = cand[~filled[cell_of[cand]]]
        if len(cand) == 0:
            continue
        if tree is not None:
            d, _ = tree.query(pool[cand], distance_upper_bound=r_test)
            cand = cand[~np.isfinite(d)]
            if len(cand) == 0:
                continue
        win = cand[_greedy_independent_set(pool[cand], radius, cand)]
        filled[cell_of[win]] = True
        n_filled += len(win)
        accepted.append(win)
        tree = cKDTree(pool[np.concatenate(accepted)])
    return np.sort(np.concatenate(accepted)) if accepted else np.zeros(0, np.int64)


def _greedy_independent_set(points: np.ndarray, radius: float, priority: np.ndarray) -> np.ndarray:
    """Indices (sorted by priority) of the greedy maximal set of points pairwise >= ``radius`` apart.

    Visiting points by increasing ``priority`` and keeping those with no kept point closer than
    ``radius`` equals the fixed point of "keep every undecided point whose priority is the lowest among
    its undecided neighbours; drop their neighbours", which is computed here with sparse arrays.
    """
    n = len(points)
    pairs = cKDTree(points).query_pairs(radius * (1 - 1e-12), output_type="ndarray")
    if len(pairs) == 0:
        return np.argsort(priority)
    A = sp.coo_matrix(
        (np.ones(2 * len(pairs)), (np.r_[pairs[:, 0], pairs[:, 1]], np.r_[pairs[:, 1], pairs[:, 0]])), shape=(n, n)
    ).tocsr()
    state = np.zeros(n, np.int8)  # 0 undecided, 1 kept, -1 dropped
    prio = priority.astype(np.float64)
    indptr, indices = A.indptr, A.indices
    has_nb = np.diff(indptr) > 0
    starts = indptr[:-1][has_nb]
    row = np.repeat(np.arange(n), np.diff(indptr))
    while True:
        und = state == 0
        if not und.any():
            break
        # lowest priority among undecided neighbours (segment minima over the CSR rows)
        nb_prio = np.where(und[indices], prio[indices], np.inf)
        low = np.full(n, np.inf)
        low[has_nb] = np.minimum.reduceat(nb_prio, starts)
        win = und & (prio < low)
        state[win] = 1
        hit = np.zeros(n, bool)
        hit[indices[win[row]]] = True
        state[hit & (state == 0)] = -1
    kept = np.flatnonzero(state == 1)
    return kept[np.argsort(priority[kept])]


def simplify(
    V, F, n_faces: int, *, preserve_boundary: bool = False, preserve_topology: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decimate to about ``n_faces`` triangles and map every fine vertex to a coarse one.

    Uses pymeshlab's quadric edge collapse (``meshing_decimation_quadric_edge_collapse`` with
    ``optimalplacement`` on, ``preservetopology`` and ``preserveboundary`` as asked), then maps each
    fine vertex to its nearest coarse vertex (Euclidean). Returns
    ``(Vc (#Vc, 3), Fc (#Fc, 3), fine_to_coarse (#V,) int64)``; when ``n_faces >= #F`` the mesh is
    returned unchanged with the identity map.
    """
    import pymeshlab

    V, F = as_mesh_arrays(V, F)
    if n_faces < 4:
        raise ValueError(f"n_faces must be >= 4, got {n_faces}")
    if len(F) == 0:
        raise ValueError("cannot simplify a mesh without faces")
    if n_faces >= len(F):
        return V.copy(), F.copy(), np.arange(len(V), dtype=np.int64)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=V, face_matrix=F.astype(np.int32)))
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(n_faces),
        preservetopology=bool(preserve_topology),
        optimalplacement=True,
        autoclean=True,
        preserveboundary=bool(preserve_boundary),
        boundaryweight=1000.0 if preserve_boundary else 1.0,
    )
    m = ms.current_mesh()
    Vc = np.asarray(m.vertex_matrix(), dtype=np.float64)
    Fc = np.asarray(m.face_matrix(), dtype=np.int64)
    Vc, Fc = remove_unreferenced(Vc, Fc)[:2]
    _, f2c = cKDTree(Vc).query(V)
    return Vc, Fc, f2c.astype(np.int64)


def remove_unreferenced(V, F) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drop vertices no face uses. Returns ``(V2, F2, old_index (#V2,))``."""
    V = np.asarray(V)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    used = np.zeros(len(V), bool)
    used[F.ravel()] = True
    old = np.flatnonzero(used)
    remap = np.full(len(V), -1, np.int64)
    remap[old] = np.arange(len(old))
    return V[old], remap[F], old


def clip_by_planes(V, F, normals, offsets, *, src_face=None, cap: bool = False):
    """Keep the part of the mesh on the side ``n . x <= d`` of every plane, splitting triangles exactly.

    Parameters
    ----------
    V : (#V, 3) float, F : (#F, 3) int
    normals : (k, 3) float plane normals (need not be unit; the test is ``n . x <= d``)
    offsets : (k,) float plane offsets ``d``
    src_face : (#F,) int, optional; source index carried along (defaults to ``arange(#F)``)

    Returns
    -------
    V2 (#V2, 3), F2 (#F2, 3), src_face (#F2,) int64: the index of the input face each output face came
    from. Cut faces are left open unless ``cap``: then after each plane the boundary loops lying on it
    are closed by :func:`cap_plane` (cap faces get ``src_face = -1``; meant for closed meshes).
    Points where an edge crosses a plane are computed once per edge from its endpoints in a fixed
    order, so faces that shared an edge still share the new
    vertex and two clips that cut the same edge by the same plane give bitwise-equal points. A vertex
    within ``TOL`` x (bbox diagonal) of a plane counts as on it (kept, never split), so no sliver
    triangles appear; unused vertices are dropped, faces with repeated corners removed.
    """
    V, F, normals, offsets, src, eps = checked_plane_args(V, F, normals, offsets, src_face)
    for n, d in zip(normals, offsets, strict=True):
        if len(F) == 0:
            break
        V, F, src = split_by_plane(V, F, src, n, d, eps * np.linalg.norm(n))[:3]
        if cap and len(F):
            scale = np.linalg.norm(n)
            C = cap_plane(V, F, n, d / scale, tol=eps * 10)
            F = np.concatenate([F, C])
            src = np.concatenate([src, np.full(len(C), -1, np.int64)])
    V, F, _ = remove_unreferenced(V, F)
    return V, F, src


def split_by_plane(V, F, src, n, d, eps):
    """Split every triangle by the plane ``n . x = d``.

    Returns ``(V2, F_in, src_in, F_out, src_out)``: the faces on the ``n . x <= d`` side and on the
    other side; crossing points are appended to ``V`` (shared by both sides).
    """
    s = V @ n - d
    s[np.abs(s) <= eps] = 0.0
    out = (s > 0).view(np.uint8)
    n_out = out[F[:, 0]] + out[F[:, 1]] + out[F[:, 2]]
    out = out.view(bool)
    whole_in, whole_out = n_out == 0, n_out == 3
    mixed = np.flatnonzero((n_out == 1) | (n_out == 2))
    if len(mixed) == 0:
        return V, F[whole_in], src[whole_in], F[whole_out], src[whole_out]
    Fm = F[mixed]
    om = out[Fm]
    # rotate each mixed triangle so its odd vertex (the one alone on its side) is corner 0
    odd_is_out = n_out[mixed] == 1
    odd = np.where(odd_is_out[:, None], om, ~om)
    first = np.argmax(odd, axis=1)
    R = np.take_along_axis(Fm, (first[:, None] + np.arange(3)[None, :]) % 3, axis=1)
    # crossed edges (a, b) and (a, c), a the odd vertex; an endpoint with s == 0 is reused as is
    ekeys = np.sort(np.concatenate([R[:, [0, 1]], R[:, [0, 2]]]), axis=1)
    uniq, inv = np.unique(ekeys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    i, j = uniq[:, 0], uniq[:, 1]
    si, sj = s[i], s[j]
    on_i, on_j = si == 0, sj == 0
    crossing = si * sj < 0
    t = np.zeros(len(uniq))
    t[crossing] = si[crossing] / (si[crossing] - sj[crossing])
    pts = V[i] + t[:, None] * (V[j] - V[i])
    new_idx = np.full(len(uniq), -1, np.int64)
    new_idx[on_i] = i[on_i]
    new_idx[on_j & ~on_i] = j[on_j & ~on_i]
    new_idx[crossing] = len(V) + np.arange(int(crossing.sum()))
    V2 = np.concatenate([V, pts[crossing]])
    m = len(mixed)
    ab, ac = new_idx[inv[:m]], new_idx[inv[m:]]
    a, b, c = R[:, 0], R[:, 1], R[:, 2]
    src_m = src[mixed]
    tri = np.stack([a, ab, ac], axis=1)  # the odd vertex's side
    quad1 = np.stack([ab, b, c], axis=1)  # the other side, as two triangles
    quad2 = np.stack([ab, c, ac], axis=1)
    ins = ~odd_is_out
    F_in = np.concatenate([F[whole_in], tri[ins], quad1[odd_is_out], quad2[odd_is_out]])
    S_in = np.concatenate([src[whole_in], src_m[ins], src_m[odd_is_out], src_m[odd_is_out]])
    F_out = np.concatenate([F[whole_out], tri[odd_is_out], quad1[ins], quad2[ins]])
    S_out = np.concatenate([src[whole_out], src_m[odd_is_out], src_m[ins], src_m[ins]])
    gi, go = _nondegenerate(F_in), _nondegenerate(F_out)
    return V2, F_in[gi], S_in[gi], F_out[go], S_out[go]


def _nondegenerate(F: np.ndarray) -> np.ndarray:
    return (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])


def split_by_planes(V, F, normals, offsets):
    """Cut every triangle along every plane ``n . x = d``, keeping both sides.

    Returns ``(V2, F2, src_face)``: a mesh with the same surface whose faces each lie on one side of
    every plane (so they can be grouped into cells by their centroids); neighbouring groups share
    the vertices along the cuts exactly. Same crossing-point rule and tolerance as
    :func:`clip_by_planes`.
    """
    V, F, normals, offsets, src, eps = checked_plane_args(V, F, normals, offsets, None)
    for n, d in zip(normals, offsets, strict=True):
        # only faces with corners strictly on both sides change: split those, keep the rest in place
        e = eps * np.linalg.norm(n)
        s = V @ n - d
        pos = (s > e).view(np.uint8)
        neg = (s < -e).view(np.uint8)
        cross = (pos[F[:, 0]] | pos[F[:, 1]] | pos[F[:, 2]]) & (neg[F[:, 0]] | neg[F[:, 1]] | neg[F[:, 2]])
        mixed = cross.view(bool)
        if not mixed.any():
            continue
        V, Fi, Si, Fo, So = split_by_plane(V, F[mixed], src[mixed], n, d, e)
        F = np.concatenate([F[~mixed], Fi, Fo])
        src = np.concatenate([src[~mixed], Si, So])
    V, F, _ = remove_unreferenced(V, F)
    return V, F, src


def checked_plane_args(V, F, normals, offsets, src_face):
    """The arguments of a cut by planes, checked: ``(V, F, normals (k, 3), offsets (k,), src (#F,),
    eps)``, ``src`` the source face of each face (``arange`` when ``src_face`` is None) and ``eps``
    the side tolerance (:data:`TOL` of the bounding-box diagonal, at least 1)."""
    V, F = as_mesh_arrays(V, F)
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1)
    if len(normals) != len(offsets):
        raise ValueError(f"got {len(normals)} normals but {len(offsets)} offsets")
    if not (np.all(np.isfinite(normals)) and np.all(np.isfinite(offsets))):
        raise ValueError("plane normals and offsets must be finite")
    if np.any(np.linalg.norm(normals, axis=1) == 0):
        raise ValueError("a plane normal is the zero vector")
    src = np.arange(len(F), dtype=np.int64) if src_face is None else np.asarray(src_face, np.int64).copy()
    if len(src) != len(F):
        raise ValueError(f"src_face must have {len(F)} entries, got {len(src)}")
    diag = float(np.linalg.norm(np.ptp(V, axis=0))) if len(V) else 0.0
    return V, F, normals, offsets, src, TOL * max(diag, 1.0)


def clip_by_box(V, F, lo, hi, *, cap: bool = False):
    """Keep the part of the mesh inside the axis-aligned box ``lo <= x <= hi`` (see :func:`clip_by_planes`,
    also for ``cap``).

    Returns ``(V2, F2, src_face)``. Raises ValueError when ``lo > hi`` on some axis.
    """
    lo = np.asarray(lo, dtype=np.float64).reshape(3)
    hi = np.asarray(hi, dtype=np.float64).reshape(3)
    if np.any(lo > hi):
        raise ValueError(f"box lo {lo.tolist()} exceeds hi {hi.tolist()}")
    eye = np.eye(3)
    normals = np.concatenate([eye, -eye])
    offsets = np.concatenate([hi, -lo])
    return clip_by_planes(V, F, normals, offsets, cap=cap)


def weld(V, F, tol: float, *, return_index: bool = False):
    """Merge vertices closer than ``tol`` (transitively) and drop faces that collapse.

    Each cluster of vertices linked by distances ``<= tol`` becomes one vertex placed at the cluster's
    lowest-index member (see :func:`merge_vertices`). Returns ``(V2 (#V2, 3), F2 (#F2, 3))``, plus
    ``old_to_new (#V,)`` when ``return_index``. Unreferenced vertices are kept (as their own clusters).
    """
    V, F = as_mesh_arrays(V, F)
    if not tol >= 0:
        raise ValueError(f"tol must be >= 0, got {tol}")
    pairs = cKDTree(V).query_pairs(tol, output_type="ndarray") if len(V) else np.zeros((0, 2), np.int64)
    return merge_vertices(V, F, pairs, return_index=return_index)


def merge_vertices(V, F, pairs, *, return_index: bool = False):
    """Merge the vertices linked by ``pairs (k, 2)`` (transitively) and drop faces that collapse.

    Each connected cluster becomes one vertex at its lowest-index member's position; clusters are
    numbered in the order of their lowest members. Returns ``(V2, F2)`` (+ ``old_to_new (#V,)``).
    """
    V, F = as_mesh_arrays(V, F)
    n = len(V)
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    ncomp, comp = connected_components(G, directed=False)
    rep = np.full(ncomp, n, np.int64)
    np.minimum.at(rep, comp, np.arange(n))
    order = np.argsort(rep)
    new_of_comp = np.empty(ncomp, np.int64)
    new_of_comp[order] = np.arange(ncomp)
    old_to_new = new_of_comp[comp]
    V2 = V[rep[order]]
    F2 = old_to_new[F]
    F2 = F2[_nondegenerate(F2)]
    if return_index:
        return V2, F2, old_to_new
    return V2, F2


def boundary_loops(F, *, mask=None) -> list[np.ndarray]:
    """Closed loops of boundary half-edges (edges whose opposite half-edge no face has).

    ``mask (#V,) bool`` optionally restricts to half-edges with both end points in the mask. Each loop
    is an int64 array of vertex indices in the faces' orientation (so the surface lies to the left
    of the loop seen from outside). Chains that do not close (non-manifold junctions) are dropped.
    """
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    H = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    if len(H) == 0:
        return []
    n = int(H.max()) + 1
    key = H[:, 0] * n + H[:, 1]
    twin = H[:, 1] * n + H[:, 0]
    B = H[~np.isin(key, twin)]
    if mask is not None:
        mask = np.asarray(mask, bool)
        B = B[mask[B[:, 0]] & mask[B[:, 1]]]
    nxt: dict[int, int] = {}
    for a, b in B.tolist():
        nxt.setdefault(a, b)
    loops, seen = [], set()
    for start in list(nxt):
        if start in seen:
            continue
        loop, v = [], start
        while v in nxt and v not in seen:
            seen.add(v)
            loop.append(v)
            v = nxt[v]
        if v == start and len(loop) >= 3:
            loops.append(np.asarray(loop, np.int64))
    return loops


def _signed_area(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _point_in_polygon(p: np.ndarray, P: np.ndarray) -> bool:
    x, y = p
    xi, yi = P[:, 0], P[:, 1]
    xj, yj = np.roll(xi, 1), np.roll(yi, 1)
    cond = (yi > y) != (yj > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = (xj - xi) * (y - yi) / (yj - yi) + xi
    return bool(np.sum(cond & (x < xc)) % 2)


def _segments_cross(a, b, P: np.ndarray) -> bool:
    """Whether segment a-b properly crosses any edge of the closed polygon P."""
    C, D = P, np.roll(P, -1, axis=0)

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    o1, o2 = orient(a, b, C), orient(a, b, D)
    o3, o4 = orient(C, D, a), orient(C, D, b)
    return bool(np.any((o1 * o2 < 0) & (o3 * o4 < 0)))


def triangulate_polygons(P2, loops: list[np.ndarray], *, best_ear: bool = False) -> np.ndarray:
    """Triangulate the region bounded by ``loops`` (vertex indices into ``P2 (n, 2)``), holes included.

    Counter-clockwise loops are outer boundaries, clockwise loops holes (each hole belongs to the
    smallest outer loop containing it). Holes are joined to their outer loop by a bridge from their
    rightmost vertex to the nearest outer vertex it can see, then the polygon is ear-clipped: the
    first ear found in turn, or with ``best_ear`` the ear with the largest smallest angle each time
    (:func:`_best_ear_clip`, which never clips a zero-area ear).
    Returns ``(k, 3)`` int64 triangles, counter-clockwise; a polygon that cannot be clipped (self-
    intersecting input) is skipped.
    """
    P2 = np.asarray(P2, dtype=np.float64)
    outers, holes = [], []
    for loop in loops:
        a = _signed_area(P2[loop])
        if a > 0:
            outers.append((a, list(loop)))
        elif a < 0:
            holes.append(list(loop))
    outers.sort(key=lambda t: t[0])
    polys = [o[1] for o in outers]
    members: list[list[list[int]]] = [[] for _ in polys]
    for h in holes:
        for k, poly in enumerate(polys):
            if _point_in_polygon(P2[h[0]], P2[poly]):
                members[k].append(h)
                break
    tris: list[list[int]] = []
    for poly, hs in zip(polys, members, strict=True):
        poly = list(poly)
        for h in sorted(hs, key=lambda h: -P2[h].max(axis=0)[0]):
            m = int(np.argmax(P2[h][:, 0]))
            M = P2[h[m]]
            order = np.argsort(np.linalg.norm(P2[poly] - M, axis=1))
            all_edges = np.concatenate([P2[poly]] + [P2[x] for x in hs])
            pick = None
            for i in order:
                if not _segments_cross(M, P2[poly[i]], all_edges):
                    pick = int(i)
                    break
            if pick is None:
                pick = int(order[0])
            h_rot = h[m:] + h[: m + 1]
            poly = poly[: pick + 1] + h_rot + [poly[pick]] + poly[pick + 1 :]
        tris.extend(_best_ear_clip(P2, poly) if best_ear else _ear_clip(P2, poly))
    return np.asarray(tris, np.int64).reshape(-1, 3)


def _triangle_min_angles(A, B, C) -> np.ndarray:
    """Smallest interior angle (radians) of each triangle ``A, B, C (k, 2)``."""
    out = np.full(len(A), np.pi)
    for p, q, r in ((A, B, C), (B, C, A), (C, A, B)):
        e1, e2 = q - p, r - p
        den = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        cos = np.divide(np.einsum("ij,ij->i", e1, e2), den, out=np.ones(len(A)), where=den > 0)
        out = np.minimum(out, np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def _best_ear_clip(P2: np.ndarray, poly: list[int]) -> list[list[int]]:
    """Ear clipping of the simple polygon ``poly`` (counter-clockwise) that clips, each time, the
    ear whose triangle has the largest smallest angle; ears with twice-area below
    ``tol.ear_area`` times the squared extent (three collinear corners) are never clipped, so a
    straight side's vertices end up in fans from across the polygon rather than in slivers of
    zero area. [] when it gets stuck."""
    Q = P2[poly]
    n = len(poly)
    flat = tol.ear_area * float(np.ptp(Q, axis=0).max()) ** 2 if n else 0.0
    alive = list(range(n))
    out: list[list[int]] = []
    while len(alive) > 3:
        idx = np.asarray(alive)
        a, c = np.roll(idx, 1), np.roll(idx, -1)
        A, B, C = Q[a], Q[idx], Q[c]
        cross = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
        score = np.where(cross > flat, _triangle_min_angles(A, B, C), -1.0)
        for j in np.argsort(-score, kind="stable"):
            if score[j] < 0:
                return []
            if not _ear_blocked(Q, idx, a[j], idx[j], c[j], flat):
                out.append([poly[a[j]], poly[idx[j]], poly[c[j]]])
                alive.pop(int(j))
                break
        else:
            return []
    out.append([poly[k] for k in alive])
    return out


def _ear_blocked(Q, idx, a, b, c, tol: float) -> bool:
    """Whether a polygon vertex of ``Q[idx]`` other than the corners lies in triangle a, b, c or
    within ``tol`` (twice-area) of its sides: a vertex on the diagonal a-c blocks the ear, which
    would otherwise leave a remainder of zero area."""
    R = Q[idx]
    same = np.all(R == Q[a], axis=1) | np.all(R == Q[b], axis=1) | np.all(R == Q[c], axis=1)
    R = R[~same]
    A, B, C = Q[a], Q[b], Q[c]
    d1 = (B[0] - A[0]) * (R[:, 1] - A[1]) - (B[1] - A[1]) * (R[:, 0] - A[0])
    d2 = (C[0] - B[0]) * (R[:, 1] - B[1]) - (C[1] - B[1]) * (R[:, 0] - B[0])
    d3 = (A[0] - C[0]) * (R[:, 1] - C[1]) - (A[1] - C[1]) * (R[:, 0] - C[0])
    return bool(np.any((d1 >= -tol) & (d2 >= -tol) & (d3 >= -tol)))


def _ear_clip(P2: np.ndarray, poly: list[int]) -> list[list[int]]:
    """Ear clipping of the simple polygon ``poly`` (counter-clockwise); [] when it gets stuck."""
    n = len(poly)
    Q = P2[poly]
    e = np.roll(Q, -1, axis=0) - Q
    turn = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    if len(set(poly)) == n and np.all(turn > 0):  # strictly convex: a fan is valid
        return [[poly[0], poly[k], poly[k + 1]] for k in range(1, n - 1)]
    nxt = np.roll(np.arange(n), -1)
    prv = np.roll(np.arange(n), 1)
    alive = np.ones(n, bool)
    out: list[list[int]] = []
    remaining, k, since_clip = n, 0, 0
    while remaining > 3:
        if since_clip > remaining:
            return []
        a, c = prv[k], nxt[k]
        A, B, C = Q[a], Q[k], Q[c]
        cross = (B[0] - A[0]) * (C[1] - A[1]) - (B[1] - A[1]) * (C[0] - A[0])
        ear = cross > 0
        if ear:
            R = Q[alive]
            same = np.all(R == A, axis=1) | np.all(R == B, axis=1) | np.all(R == C, axis=1)
            R = R[~same]
            d1 = (B[0] - A[0]) * (R[:, 1] - A[1]) - (B[1] - A[1]) * (R[:, 0] - A[0])
            d2 = (C[0] - B[0]) * (R[:, 1] - B[1]) - (C[1] - B[1]) * (R[:, 0] - B[0])
            d3 = (A[0] - C[0]) * (R[:, 1] - C[1]) - (A[1] - C[1]) * (R[:, 0] - C[0])
            ear = not np.any((d1 >= 0) & (d2 >= 0) & (d3 >= 0))
        if ear:
            out.append([poly[a], poly[k], poly[c]])
            alive[k] = False
            nxt[a], prv[c] = c, a
            remaining -= 1
            since_clip = 0
            k = a
        else:
            since_clip += 1
            k = c
    k = int(np.flatnonzero(alive)[0])
    out.append([poly[prv[k]], poly[k], poly[nxt[k]]])
    return out


def cap_plane(V, F, normal, offset, *, tol: float = 1e-9) -> np.ndarray:
    """Cap faces ``(k, 3)`` closing the boundary loops of ``F`` that lie on the plane ``n . x = d``.

    The caps face along ``+normal`` (outwards for a solid kept on the ``n . x <= d`` side) and use
    only existing vertices. Vertices within ``tol`` of each other are treated as one (so a soup whose
    sides do not share vertices still has closed loops); loops are found by :func:`boundary_loops`
    among vertices within ``tol`` of the plane and triangulated by :func:`triangulate_polygons`.
    """
    V, F = as_mesh_arrays(V, F)
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    _, _, old_to_new = weld(V, F, tol, return_index=True)
    rep = np.full(int(old_to_new.max()) + 1 if len(V) else 0, -1, np.int64)
    rep[old_to_new[::-1]] = np.arange(len(V))[::-1]  # lowest original index of each welded vertex
    W = V[rep]
    G = old_to_new[F]
    G = G[(G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 2] != G[:, 0])]
    on = np.abs(W @ n - offset) <= tol
    loops = boundary_loops(G, mask=on)
    if not loops:
        return np.zeros((0, 3), np.int64)
    # orthonormal frame (e1, e2, n): a counter-clockwise loop in (e1, e2) bounds a region facing +n
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    P2 = np.stack([W @ e1, W @ e2], axis=1)
    # the surface's boundary runs clockwise seen from +n around the solid's section: reverse it
    return rep[triangulate_polygons(P2, [loop[::-1] for loop in loops])]
