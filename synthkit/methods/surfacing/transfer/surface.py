"""A region of a mesh carrying a signal, in the form the transfer stages use.

A :class:`Signal` is defined per face corner, so texture seams and per-face values need no
welding: ``values (#F, 3, C)`` (vertex colours, PLY attributes, displacement vectors) interpolated
barycentrically, or ``uv (#F, 3, 2)`` into ``texture (H, W, C)`` read bilinearly (v up).
A :class:`Surface` is the region's submesh (``V (#V, 3)``, ``F (#F, 3)`` with vertices welded),
its signal, per-face tangent frames taken from potpourri3d's vertex frames (the frames its log map
is expressed in), a cached :class:`potpourri3d.MeshVectorHeatSolver` for vector-heat log maps and
the support mesh's vertex graph for local ones (:mod:`.expmap`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.core.mesh import face_adjacency, face_areas, face_normals, remove_unreferenced, vertex_normals
from synthkit.methods.surfacing.transfer.expmap import exp_map, vertex_faces, vertex_graph

__all__ = ["Signal", "Surface", "make_surface", "bilinear", "split_nonmanifold", "LOG_MAP_CACHE", "mean_edge",
           "texel_size", "prefiltered"]

LOG_MAP_CACHE = 32 * 2**20
"""Bytes of log maps a surface keeps (at least the latest): 200 maps of a 10k-vertex surface."""


def bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``img (H, W, C)`` read at ``uv (n, 2)`` (u right, v up, [0, 1] spans the image; clamped at
    the border): ``(n, C)`` float64."""
    H, W = img.shape[:2]
    x = np.clip(uv[:, 0] * W - 0.5, 0, W - 1)
    y = np.clip((1.0 - uv[:, 1]) * H - 0.5, 0, H - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return (top * (1 - fy) + bot * fy).astype(np.float64)


@dataclass
class Signal:
    """``phi``: per-corner ``values (#F, 3, C)``, or per-corner ``uv (#F, 3, 2)`` into ``texture``.

    ``kind`` is ``color``, ``texture``, ``displacement`` or ``attribute``."""

    kind: str
    values: np.ndarray | None = None
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None

    @property
    def channels(self) -> int:
        return int(self.texture.shape[2] if self.values is None else self.values.shape[2])

    def subset(self, faces: np.ndarray) -> Signal:
        """The signal of the faces ``faces (k,)`` only."""
        if self.values is not None:
            return Signal(self.kind, values=self.values[faces])
        return Signal(self.kind, uv=self.uv[faces], texture=self.texture)

    def uv_at(self, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """Texture coordinates ``(n, 2)`` at ``faces (n,)``, barycentric ``bary (n, 3)``."""
        return np.einsum("nk,nkc->nc", bary, self.uv[faces])

    def sample(self, faces: np.ndarray, bary: np.ndarray, *, nearest: bool = False) -> np.ndarray:
        """Signal ``(n, C)`` at ``faces (n,)`` with barycentric coordinates ``bary (n, 3)``;
        ``nearest``: the value of the nearest corner (or texel), so no new value is made."""
        if nearest and self.values is not None:
            return self.values[faces, np.argmax(bary, axis=1)].astype(np.float64)
        if nearest:
            H, W = self.texture.shape[:2]
            uv = self.uv_at(faces, bary)
            x = np.clip(np.floor(uv[:, 0] * W), 0, W - 1).astype(np.int64)
            y = np.clip(np.floor((1.0 - uv[:, 1]) * H), 0, H - 1).astype(np.int64)
            return self.texture[y, x].astype(np.float64)
        if self.values is not None:
            return np.einsum("nk,nkc->nc", bary, self.values[faces])
        return bilinear(self.texture, self.uv_at(faces, bary))


@dataclass
class Surface:
    """A region submesh with its signal (see the module docstring).

    ``face_ids (#F,)`` are the faces of the full mesh, ``vertex_ids (#V,)`` its vertices;
    ``pairs (k, 2)`` adjacent faces and ``edges (k, 2)`` their shared edge; ``X``, ``Y``, ``N``
    ``(#F, 3)`` the face frames; ``vertex_frames`` ``(#V, 3, 3)`` potpourri3d's (X, Y, N) rows."""

    V: np.ndarray
    F: np.ndarray
    face_ids: np.ndarray
    vertex_ids: np.ndarray
    signal: Signal | None
    pairs: np.ndarray
    edges: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    N: np.ndarray
    areas: np.ndarray
    vertex_frames: np.ndarray
    _solver: object = field(default=None, repr=False)
    _support_index: np.ndarray | None = field(default=None, repr=False)
    up: np.ndarray | None = None
    _planar: bool | None = field(default=None, repr=False)
    _neighbours: tuple | None = field(default=None, repr=False)
    _plane_tree: cKDTree | None = field(default=None, repr=False)
    _log_maps: dict = field(default_factory=dict, repr=False)
    _support_mesh: tuple | None = field(default=None, repr=False)
    _graph: tuple | None = field(default=None, repr=False)

    @property
    def plane_coordinates(self) -> np.ndarray:
        """``(#V, 2)`` coordinates of a planar surface's vertices in its first face's frame."""
        return self.V @ np.stack([self.X[0], self.Y[0]], axis=1)

    @property
    def plane_tree(self) -> cKDTree:
        """Tree of a planar surface's face centroids in :attr:`plane_coordinates`, built once."""
        if self._plane_tree is None:
            P = self.plane_coordinates[self.F]
            self._plane_tree = cKDTree((P[:, 0] + P[:, 1] + P[:, 2]) / 3.0)
        return self._plane_tree

    @property
    def neighbours(self) -> tuple[np.ndarray, np.ndarray]:
        """Face adjacency from ``pairs`` in CSR form: ``(indptr (#F + 1,), indices (2 #pairs,))``, the
        neighbours of face ``f`` being ``indices[indptr[f]:indptr[f + 1]]``; built once."""
        if self._neighbours is None:
            n = len(self.F)
            A = sp.csr_matrix((np.ones(2 * len(self.pairs), np.int8),
                               (self.pairs.ravel(), self.pairs[:, ::-1].ravel())), shape=(n, n))
            self._neighbours = (A.indptr.astype(np.int64), A.indices.astype(np.int64))
        return self._neighbours

    @property
    def planar(self) -> bool:
        """Whether every face lies in one plane (normals within 1e-9 of the first face's, vertices
        within 1e-9 of the size from its plane), as an image's grid does: its log maps are then the
        plane's own coordinates, exact and without overlaps."""
        if self._planar is None:
            n0 = self.N[0]
            size = max(float(np.ptp(self.V, axis=0).max()), 1e-300)
            self._planar = bool(np.all(self.N @ n0 > 1 - 1e-9)
                                and np.abs((self.V - self.V[0]) @ n0).max() <= 1e-9 * size)
        return self._planar

    def orient(self, up) -> None:
        """Face frames with ``X = up x N`` (level, when ``up`` is the vertical) and ``Y = N x X``;
        faces whose normal is parallel to ``up`` keep their frame. Sets ``up (3,)`` (unit), which the
        patches then hold on every face (:func:`..param.mutual_patch`)."""
        self.up = np.asarray(up, np.float64) / max(float(np.linalg.norm(up)), 1e-300)
        X = np.cross(self.up[None, :], self.N)
        n = np.linalg.norm(X, axis=1)
        ok = n > 1e-6
        self.X[ok] = X[ok] / n[ok, None]
        self.Y[ok] = np.cross(self.N[ok], self.X[ok])

    @property
    def centroids(self) -> np.ndarray:
        return self.V[self.F].mean(axis=1)

    @property
    def area(self) -> float:
        return float(self.areas.sum())

    def local_log_map(self, vertex: int, stop: float, normal: np.ndarray | None = None) -> np.ndarray:
        """Log map ``(#V, 2)`` of the surface from ``vertex`` in its potpourri3d tangent frame by the
        discrete exponential map (:func:`.expmap.exp_map`) over the support mesh, NaN beyond ``stop``
        (estimated geodesic distance): only the vertices within ``stop`` are visited. ``normal (3,)``:
        the seed's tangent plane instead of its vertex normal's (the seed face's, so its first ring
        is laid in that face's plane, not in the average of two walls at a corner)."""
        if self._graph is None:
            Vs, Fs = self._support_mesh if self._support_index is not None else (self.V, self.F)
            indptr, indices = vertex_graph(Fs, len(Vs))
            self._graph = (Vs, indptr, indices, vertex_normals(Vs, Fs), Fs) + vertex_faces(Fs, len(Vs))
        Vs, indptr, indices, N, Fs, fptr, vf = self._graph
        v = int(vertex)
        s = v if self._support_index is None else int(self._support_index[v])
        if normal is not None:
            N = N.copy()
            N[s] = normal
        e1 = self.vertex_frames[v, 0] - (self.vertex_frames[v, 0] @ N[s]) * N[s]
        e1 /= max(float(np.linalg.norm(e1)), 1e-300)
        U = exp_map(Vs, indptr, indices, N, s, e1, np.cross(N[s], e1), float(stop), Fs, fptr, vf, True)
        return U if self._support_index is None else U[self._support_index]

    def log_map(self, vertex: int) -> np.ndarray:
        """Log map ``(#V, 2)`` (read-only) of the surface from ``vertex``, in its potpourri3d tangent
        frame (computed over the support mesh, so the region's own border does not bend it). The
        latest maps are kept, up to :data:`LOG_MAP_CACHE` bytes: a seed that cannot be placed is
        retried with other matches from the same vertex (house1's walls: 482 maps of 140 vertices)."""
        v = int(vertex)
        if v in self._log_maps:
            self._log_maps[v] = self._log_maps.pop(v)  # most recent last
            return self._log_maps[v]
        if self._support_index is None:
            L = np.asarray(self._solver.compute_log_map(v), np.float64)
        else:
            L = np.asarray(self._solver.compute_log_map(int(self._support_index[v])), np.float64)[self._support_index]
        L.setflags(write=False)
        while self._log_maps and (len(self._log_maps) + 1) * L.nbytes > LOG_MAP_CACHE:
            self._log_maps.pop(next(iter(self._log_maps)))
        self._log_maps[v] = L
        return L


def _face_frames(V, F, vframes):
    N = face_normals(V, F)
    X = vframes[F[:, 0], 0]
    X = X - (X * N).sum(axis=1, keepdims=True) * N
    bad = np.linalg.norm(X, axis=1) < 1e-9
    X[bad] = (V[F[bad, 1]] - V[F[bad, 0]])
    X /= np.maximum(np.linalg.norm(X, axis=1, keepdims=True), 1e-300)
    return X, np.cross(N, X), N


def _support(V, F, faces, region_vertices, margin: float):
    """Faces ``(k,)`` of ``F`` with a corner within ``margin`` of the region's vertices, or None
    when they are the region's own faces."""
    if margin <= 0:
        return None
    near = np.zeros(len(V), bool)
    d, _ = cKDTree(V[region_vertices]).query(V, distance_upper_bound=margin)
    near[np.isfinite(d)] = True
    sup = np.flatnonzero(near[F].any(axis=1))
    return None if len(sup) == len(faces) else sup


def _solver_over(V, F, faces, vertex_ids, support):
    """potpourri3d vector heat solver over the support faces, the index of each surface vertex in it
    and the support mesh ``(Vs, Fs)`` (all None without a support)."""
    import potpourri3d as pp3d

    if support is None:
        return None, None, None
    Vs, Fs, old = remove_unreferenced(V, F[support])
    ok = (Fs[:, 0] != Fs[:, 1]) & (Fs[:, 1] != Fs[:, 2]) & (Fs[:, 0] != Fs[:, 2]) & (face_areas(Vs, Fs) > 0)
    Vs, Fs, old2 = remove_unreferenced(Vs, Fs[ok])
    pos = np.full(len(V), -1, np.int64)
    pos[old[old2]] = np.arange(len(old2))
    index = pos[vertex_ids]
    if (index < 0).any():
        return None, None, None
    return pp3d.MeshVectorHeatSolver(Vs, Fs), index, (Vs, Fs)


def make_surface(V, F, faces, signal: Signal | None, *, weld_tol: float = 0.0, largest: bool = True,
                 margin: float = 0.0) -> Surface:
    """The surface of ``faces (k,)`` of ``V (#V, 3)``, ``F (#F, 3)`` carrying ``signal`` (of the full
    mesh), vertices welded within ``weld_tol`` (texture seams), degenerate faces dropped and, with
    ``largest``, reduced to its largest connected piece. Log maps run over the faces within
    ``margin`` of the region (0: the region alone; without welding only). ValueError when the
    region is empty or not manifold (potpourri3d's log maps need a manifold mesh; a non-manifold
    support margin falls back to the region alone)."""
    import potpourri3d as pp3d

    faces = np.asarray(faces, np.int64)
    if not len(faces):
        raise ValueError("region is empty")
    V2, F2, old = remove_unreferenced(np.asarray(V, np.float64), np.asarray(F, np.int64)[faces])
    if weld_tol > 0:
        from synthkit.core.mesh import weld

        _, _, o2n = weld(V2, F2, weld_tol, return_index=True)
        F2 = o2n[F2]
        keep_v, F2r = np.unique(F2, return_inverse=True)
        V2, F2, old = V2[keep_v], F2r.reshape(-1, 3), old[keep_v]
    ok = (F2[:, 0] != F2[:, 1]) & (F2[:, 1] != F2[:, 2]) & (F2[:, 0] != F2[:, 2]) & (face_areas(V2, F2) > 0)
    pairs, _ = face_adjacency(F2[ok])
    keep = _largest_piece(int(ok.sum()), pairs) if largest else np.arange(int(ok.sum()))
    sel = np.flatnonzero(ok)[keep]
    V3, F3, old3 = remove_unreferenced(V2, F2[sel])
    pairs, edges = face_adjacency(F3)
    vertex_ids = old[old3]
    V0, F0 = np.asarray(V, np.float64), np.asarray(F, np.int64)
    support = _support(V0, F0, faces, vertex_ids, margin) if weld_tol == 0 else None
    try:
        big, index, mesh = _solver_over(V0, F0, faces, vertex_ids, support)
    except RuntimeError:  # geometry-central refuses non-manifold support: log maps over the region alone
        big, index, mesh = None, None, None
    if big is not None:
        solver = big
    else:
        try:
            solver = pp3d.MeshVectorHeatSolver(V3, F3)
        except RuntimeError:  # not a manifold (bowties, double-sided faces, edges of 3+ faces): cut, try again
            F3, split = split_nonmanifold(F3)
            V3, old3 = V3[split], old3[split]
            vertex_ids, index = old[old3], None
            pairs, edges = face_adjacency(F3)
            solver = _manifold_solver(V3, F3)
    frames = np.stack(solver.get_tangent_frames(), axis=1)
    if index is not None:
        frames = frames[index]
    X, Y, N = _face_frames(V3, F3, frames)
    sig = None if signal is None else signal.subset(faces[sel])
    return Surface(V3, F3, faces[sel], vertex_ids, sig, pairs, edges, X, Y, N, face_areas(V3, F3), frames, solver,
                   index, _support_mesh=mesh)


def split_nonmanifold(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``F (#F, 3)`` cut into a manifold, consistently wound mesh without changing any face's corners'
    positions: two faces stay joined across an edge only when they are the only two faces on it and
    run along it in opposite directions; every vertex is then split into one copy per fan of faces
    joined around it (so faces touching only at a vertex, coincident double-sided faces and edges
    of three or more faces no longer share vertices). ``(F2 (#F, 3), old (#V2,))``, ``old`` the
    vertex each new vertex copies."""
    F = np.asarray(F, np.int64)
    n = 3 * len(F)
    pairs, edges = face_adjacency(F)
    _, which, count = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    corner = [np.stack([np.argmax(F[pairs[:, s]] == edges[:, end, None], axis=1) for end in (0, 1)], 1)
              for s in (0, 1)]  # (k, 2) corner of the edge's ends in each face of the pair
    forward = [(c[:, 1] - c[:, 0]) % 3 == 1 for c in corner]
    joined = (count[which.ravel()] == 1) & (forward[0] != forward[1])
    links = [np.stack([3 * pairs[joined, 0] + corner[0][joined, end], 3 * pairs[joined, 1] + corner[1][joined, end]], 1)
             for end in (0, 1)]
    L = np.concatenate(links)
    A = sp.coo_matrix((np.ones(len(L)), (L[:, 0], L[:, 1])), shape=(n, n))
    _, comp = connected_components(A, directed=False)
    old = np.zeros(comp.max() + 1, np.int64)
    old[comp] = F.ravel()
    return comp.reshape(-1, 3), old


def _manifold_solver(V, F):
    import potpourri3d as pp3d

    try:
        return pp3d.MeshVectorHeatSolver(V, F)
    except RuntimeError as exc:
        raise ValueError(f"the region is not a manifold surface (potpourri3d: {str(exc).splitlines()[0]})") from None


def _largest_piece(n: int, pairs: np.ndarray) -> np.ndarray:
    if n == 0:
        raise ValueError("region has no non-degenerate faces")
    A = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, comp = connected_components(A, directed=False)
    return np.flatnonzero(comp == np.bincount(comp).argmax())


def mean_edge(surface: Surface) -> float:
    """Mean edge length of ``surface``."""
    return float(np.linalg.norm(surface.V[surface.edges[:, 0]] - surface.V[surface.edges[:, 1]], axis=1).mean())


def texel_size(source: Surface) -> float:
    """The size of a texel of the source's texture on its surface (source units):
    ``sqrt(surface area / texture area covered, in texels)``."""
    sig = source.signal
    H, W = sig.texture.shape[:2]
    uv = sig.uv * [W, H]
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    uv_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    return float(np.sqrt(source.area / max(uv_area, 1e-300)))


def prefiltered(source: Surface, spacing: float) -> Signal:
    """The source's texture blurred to the target's sampling: a Gaussian of ``spacing / 2``
    (source units) in texels (:func:`texel_size`), so vertex samples read the texture's local mean,
    not aliased texels."""
    sig = source.signal
    sigma = 0.5 * spacing / texel_size(source)
    if sigma < 0.5:
        return sig
    import cv2

    blurred = cv2.GaussianBlur(sig.texture.astype(np.float32), (0, 0), sigmaX=float(sigma))
    return Signal(sig.kind, uv=sig.uv, texture=blurred.astype(np.float64))
