"""Retargeting by stitching translated copies with a multi-label graph cut (Wu et al., III-B, V).

Pure functions over arrays. Geometry is handled in *canonical* coordinates ``c = B^-1 x`` where the
columns of ``B (3, 3)`` are the principal offsets (and dummy directions) in normalised units: a
principal offset is one unit step along a canonical axis and a voxel is a unit cube (Fig. 7).

- :func:`grid_phase` / :class:`VoxelGrid`: the input's voxel grid Omega_in (integer-aligned cubes
  shifted by a phase chosen so voxel faces avoid the surface).
- :func:`label_set`: the offset space Phi (eq. 2) as integer shifts, one label per copy.
- :class:`RetargetProblem`: unary (0 / inf) and pairwise (eq. 4) terms on the 26-connected output
  grid; :meth:`RetargetProblem.solve` runs alpha-expansion.
- :func:`assemble`: cut the input along the seams of the labeling and place each label's region;
  :func:`repair_t_junctions` closes seams between differently tessellated copies.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from synthkit.core.descriptors import descriptor_distances
from synthkit.core.graphcut import ExpansionResult, alpha_expansion
from synthkit.core.mesh import boundary_loops, triangulate_polygons, weld
from synthkit.methods.retarget.corners import carry, same_map

__all__ = ["VoxelGrid", "grid_phase", "make_grid", "label_set", "hausdorff", "RetargetProblem", "label_regions",
           "seam_planes", "assemble", "collapse_short_seam_edges", "flip_sliver_edges", "repair_t_junctions",
           "unique_faces", "sliver_figures", "merge_coplanar_faces", "SLIVER_DEG", "POSITION_TOL"]


@dataclass(frozen=True)
class VoxelGrid:
    """A grid of unit voxels in canonical coordinates.

    basis : (3, 3) columns = step vectors in normalised units; inverse : (3, 3) = basis^-1.
    origin : (3,) canonical corner of voxel (0, 0, 0); shape : (3,) int voxels per axis.
    """

    basis: np.ndarray
    inverse: np.ndarray
    origin: np.ndarray
    shape: np.ndarray

    def to_canonical(self, X) -> np.ndarray:
        """Canonical coordinates ``(n, 3)`` of normalised points ``X (n, 3)``."""
        return np.asarray(X, dtype=np.float64) @ self.inverse.T

    def to_normalised(self, C) -> np.ndarray:
        """Normalised coordinates ``(n, 3)`` of canonical points ``C (n, 3)``."""
        return np.asarray(C, dtype=np.float64) @ self.basis.T

    def voxel_of(self, C) -> np.ndarray:
        """Integer voxel index ``(n, 3)`` of canonical points (may lie outside ``shape``)."""
        return np.floor(np.asarray(C, dtype=np.float64) - self.origin).astype(np.int64)

    @property
    def n_voxels(self) -> int:
        return int(np.prod(self.shape))


POSITION_TOL = 1e-6
"""Normalised distance within which two vertices are one position when a mesh's cleanliness is
judged (:func:`unique_faces`): the OBJ and glTF assets store 6-7 digits."""


def grid_phase(C, plane_distance, *, parallel=None, n_phases: int = 32) -> np.ndarray:
    """Per canonical axis, the phase in [0, 1) of the voxel faces that cuts the least surface.

    ``C (n, 3)`` are canonical coordinates of the dense samples; ``plane_distance (3,)`` the
    canonical distance that counts as "on a face" per axis; ``parallel (n, 3) bool`` marks the
    samples whose surface is nearly parallel to the faces of each axis (all samples when None;
    a surface crossing a face is cut cleanly, one lying along it is not). For each of
    ``n_phases`` candidate phases the marked samples within that distance of a face
    ``c_i = phase + k`` are counted; the phase
    is the centre of the longest (circular) run of candidates with the minimum count. The paper
    only says copies must be aligned with the grid; putting faces where the surface is sparse
    keeps boards, frames and floors whole inside one voxel and avoids faces coplanar with a cut.
    """
    C = np.asarray(C, dtype=np.float64).reshape(-1, 3)
    phases = np.arange(n_phases) / n_phases
    out = np.zeros(3)
    for i in range(3):
        frac = np.mod(C[:, i][None, :] - phases[:, None], 1.0)
        near = np.minimum(frac, 1.0 - frac) < plane_distance[i]
        if parallel is not None:
            near &= parallel[None, :, i]
        counts = near.sum(axis=1)
        best = counts == counts.min()
        # longest circular run of minimal phases
        run, best_len, best_end = 0, 0, 0
        for k in range(2 * n_phases):
            run = run + 1 if best[k % n_phases] else 0
            run = min(run, n_phases)
            if run > best_len:
                best_len, best_end = run, k
        centre = best_end - (best_len - 1) / 2.0
        out[i] = np.mod(centre, n_phases) / n_phases
    return out


def make_grid(basis, dense_P, dense_N, extent_P, *, dense_radius: float = 0.02) -> VoxelGrid:
    """The input voxel grid for step vectors ``basis (3, 3)`` (columns), with the phase of
    :func:`grid_phase` from the dense samples ``dense_P (n, 3)`` with normals ``dense_N (n, 3)``
    (a sample counts as parallel to a face when its normal is within 45 degrees of the face
    normal), covering all of ``extent_P (m, 3)`` (the mesh vertices), normalised units."""
    B = np.asarray(basis, dtype=np.float64)
    inv = np.linalg.inv(B)
    row_norm = np.linalg.norm(inv, axis=1)
    plane_distance = dense_radius * row_norm
    parallel = np.abs(np.asarray(dense_N) @ (inv / row_norm[:, None]).T) > np.sqrt(0.5)
    phase = grid_phase(np.asarray(dense_P) @ inv.T, plane_distance, parallel=parallel)
    Cx = np.asarray(extent_P, dtype=np.float64) @ inv.T
    k0 = np.floor(Cx.min(axis=0) - phase)
    k1 = np.ceil(Cx.max(axis=0) - phase)
    shape = np.maximum(k1 - k0, 1).astype(np.int64)
    return VoxelGrid(B, inv, phase + k0, shape)


def label_set(steps, *, margin=(0, 0, 0)) -> np.ndarray:
    """The offset space Phi (eq. 2) as integer shifts ``(M, 3) int64``: along axis i the shifts
    ``min(0, s_i) - m_i .. max(0, s_i) + m_i`` for ``steps s (3,)`` and ``margin m (3,)``, so
    ``M = prod(|s_i| + 1 + 2 m_i)``; label 0 is the identity when it is in the set."""
    steps = np.asarray(steps, dtype=np.int64).reshape(3)
    margin = np.asarray(margin, dtype=np.int64).reshape(3)
    ranges = [range(min(0, s) - m, max(0, s) + m + 1) for s, m in zip(steps, margin, strict=True)]
    L = np.array(list(itertools.product(*ranges)), dtype=np.int64).reshape(-1, 3)
    ident = np.flatnonzero((L == 0).all(axis=1))
    if len(ident):
        L = np.concatenate([L[ident], np.delete(L, ident, axis=0)])
    return L


def hausdorff(A, B) -> float:
    """Hausdorff distance between descriptor sets ``A (a, d)`` and ``B (b, d)`` under L2."""
    D = descriptor_distances(A, B)
    return float(max(D.min(axis=1).max(), D.min(axis=0).max()))


_NEIGHBOURS = np.array([d for d in itertools.product((-1, 0, 1), repeat=3) if d > (0, 0, 0)], dtype=np.int64)
"""The 13 forward offsets of the 26-neighbourhood (each undirected edge once)."""


class RetargetProblem:
    """The MRF of eq. 3 on the output grid Omega.

    Parameters
    ----------
    in_shape : (3,) int voxels of the input grid.
    steps : (3,) int steps per axis (negative shrinks); the output has ``in_shape + steps`` voxels.
    voxel_sets : list of ``(k_v, d)`` descriptor arrays, one per input voxel in C order (flat
        index ``np.ravel_multi_index``); an empty array marks an empty voxel.
    margin : (3,) int extra shifts beyond the steps on each side (0 in the paper).
    pins : optional list of ``(voxel (3,), shift (3,))``: the output voxel must use that copy.

    Terms: the unary cost of label ``l`` at output voxel ``x`` is 0 when the source voxel
    ``x - l`` lies in the input grid, infinite otherwise. On every axis with more than one shift,
    the first and last layers of the output must copy the first and last layers of the input (the
    paper's energy has no term for the model's ends: without it shrinking could just crop the
    model; when growing it is already implied). The pairwise cost of eq. 4 between 26-neighbours
    ``x, x'`` with labels ``l_a, l_b`` is ``d_H(G(x - l_a), G(x - l_b)) + d_H(G(x' - l_a), G(x' - l_b))``
    with ``G`` the voxel's descriptor set (voxels outside the input are empty), 0 for two empty
    sets and infinite for an empty against a non-empty one. Hausdorff distances are computed once
    per (source voxel, label difference) pair that can occur.
    """

    def __init__(self, in_shape, steps, voxel_sets, *, margin=(0, 0, 0), pins=()):
        self.in_shape = np.asarray(in_shape, dtype=np.int64).reshape(3)
        self.steps = np.asarray(steps, dtype=np.int64).reshape(3)
        self.out_shape = self.in_shape + self.steps
        if np.any(self.out_shape < 1):
            raise ValueError(f"steps {self.steps.tolist()} leave no voxel of an input of {self.in_shape.tolist()}")
        if len(voxel_sets) != int(np.prod(self.in_shape)):
            raise ValueError(f"need {int(np.prod(self.in_shape))} voxel sets, got {len(voxel_sets)}")
        self.labels = label_set(self.steps, margin=margin)
        self.nodes = np.array(list(itertools.product(*[range(n) for n in self.out_shape])), dtype=np.int64)
        n, m = len(self.nodes), len(self.labels)
        src = self.nodes[:, None, :] - self.labels[None, :, :]  # (N, M, 3)
        inside = np.all((src >= 0) & (src < self.in_shape), axis=2)
        self.source = np.where(
            inside, np.ravel_multi_index(tuple(np.clip(src, 0, self.in_shape - 1).T), self.in_shape).T, -1
        )
        unary = np.where(inside, 0.0, np.inf)
        for axis in range(3):
            if len(np.unique(self.labels[:, axis])) < 2:
                continue
            first = self.nodes[:, axis] == 0
            last = self.nodes[:, axis] == self.out_shape[axis] - 1
            unary[first[:, None] & (src[:, :, axis] != 0)] = np.inf
            unary[last[:, None] & (src[:, :, axis] != self.in_shape[axis] - 1)] = np.inf
        for voxel, shift in pins:
            voxel = np.asarray(voxel, dtype=np.int64).reshape(3)
            shift = np.asarray(shift, dtype=np.int64).reshape(3)
            if np.any(voxel < 0) or np.any(voxel >= self.out_shape):
                raise ValueError(f"pinned voxel {voxel.tolist()} outside the output grid {self.out_shape.tolist()}")
            hit = np.flatnonzero((self.labels == shift).all(axis=1))
            if len(hit) == 0:
                raise ValueError(f"pinned shift {shift.tolist()} is not a label (labels span {self._span()})")
            row = int(np.ravel_multi_index(tuple(voxel), self.out_shape))
            keep = unary[row, hit[0]]
            if not np.isfinite(keep):
                raise ValueError(
                    f"pinned voxel {voxel.tolist()} with shift {shift.tolist()} copies from outside the input"
                )
            unary[row] = np.inf
            unary[row, hit[0]] = keep
        self.unary = unary
        self.edges = self._edges()
        self.empty = np.array([len(s) == 0 for s in voxel_sets] + [True])  # index -1 = outside
        self._hausdorff_table(voxel_sets)
        self.n_nodes, self.n_labels = n, m

    def _span(self) -> str:
        return f"{self.labels.min(axis=0).tolist()}..{self.labels.max(axis=0).tolist()}"

    def _edges(self) -> np.ndarray:
        grid = np.arange(len(self.nodes)).reshape(tuple(self.out_shape))
        pairs = []
        for d in _NEIGHBOURS:
            sl_a = tuple(slice(max(0, -k), n - max(0, k)) for k, n in zip(d, self.out_shape, strict=True))
            sl_b = tuple(slice(max(0, k), n - max(0, -k)) for k, n in zip(d, self.out_shape, strict=True))
            a, b = grid[sl_a].reshape(-1), grid[sl_b].reshape(-1)
            if len(a):
                pairs.append(np.stack([a, b], axis=1))
        return np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)

    def _hausdorff_table(self, voxel_sets) -> None:
        """``self.table[s, k] = d_H(G(s), G(s + delta_k))`` for the label differences ``delta_k``."""
        L = self.labels
        diffs = (L[:, None, :] - L[None, :, :]).reshape(-1, 3)
        self.deltas, inv = np.unique(diffs, axis=0, return_inverse=True)
        self.delta_index = inv.reshape(len(L), len(L))
        n_in = int(np.prod(self.in_shape))
        table = np.zeros((n_in, len(self.deltas)))
        coords = np.array(list(itertools.product(*[range(k) for k in self.in_shape])), dtype=np.int64)
        index = {tuple(d): k for k, d in enumerate(self.deltas.tolist())}
        done = np.zeros(len(self.deltas), bool)
        for k, delta in enumerate(self.deltas):
            if done[k] or not delta.any():
                done[k] = True
                continue
            back = index[tuple((-delta).tolist())]
            tgt = coords + delta
            ok = np.all((tgt >= 0) & (tgt < self.in_shape), axis=1)
            for s in np.flatnonzero(ok):
                t = int(np.ravel_multi_index(tuple(tgt[s]), self.in_shape))
                if len(voxel_sets[s]) and len(voxel_sets[t]):
                    table[s, k] = table[t, back] = hausdorff(voxel_sets[s], voxel_sets[t])
            done[k] = done[back] = True
        self.table = table

    def _term(self, nodes, la, lb) -> np.ndarray:
        sa, sb = self.source[nodes, la], self.source[nodes, lb]
        ea, eb = self.empty[sa], self.empty[sb]
        val = self.table[np.maximum(sa, 0), self.delta_index[la, lb]]
        return np.where(ea & eb, 0.0, np.where(ea != eb, np.inf, val))

    def pairwise(self, eidx, la, lb) -> np.ndarray:
        """Eq. 4 for edges ``eidx (k,)`` with labels ``la`` (first node) and ``lb`` (second node)."""
        e = self.edges[eidx]
        cost = self._term(e[:, 0], la, lb) + self._term(e[:, 1], la, lb)
        return np.where(la == lb, 0.0, cost)

    def solve(self, *, rng=None, max_cycles: int = 20) -> ExpansionResult:
        """Alpha-expansion from the identity-nearest labeling; infinite results are returned as is."""
        return alpha_expansion(
            self.unary, self.edges, self.pairwise, max_cycles=max_cycles, rng=rng, allow_infinite=True
        )

    def volume(self, labeling) -> np.ndarray:
        """Label indices ``(N,)`` reshaped to the output grid ``out_shape``."""
        return np.asarray(labeling).reshape(tuple(self.out_shape))


def label_regions(problem: RetargetProblem, labeling) -> dict[int, np.ndarray]:
    """Label index -> ``(n_in,) bool`` mask of the input voxels its output voxels copy from."""
    labeling = np.asarray(labeling, dtype=np.int64)
    n_in = int(np.prod(problem.in_shape))
    regions = {}
    for lab in np.unique(labeling):
        src = problem.source[labeling == lab, lab]
        mask = np.zeros(n_in, bool)
        mask[src[src >= 0]] = True
        regions[int(lab)] = mask
    return regions


def seam_planes(regions: dict[int, np.ndarray], shape) -> tuple[np.ndarray, np.ndarray]:
    """Canonical-axis planes ``(normals (k, 3), positions (k,))`` relative to the grid origin that
    separate a voxel of some label's region from a voxel outside it: the only cuts needed."""
    shape = tuple(int(n) for n in shape)
    normals, offsets = [], []
    for axis in range(3):
        for k in range(1, shape[axis]):
            for mask in regions.values():
                m = mask.reshape(shape)
                if np.any(np.take(m, k - 1, axis=axis) != np.take(m, k, axis=axis)):
                    normals.append(np.eye(3)[axis])
                    offsets.append(float(k))
                    break
    return np.array(normals).reshape(-1, 3), np.array(offsets)


def _box_counts(mask, lo, hi) -> np.ndarray:
    """Number of true voxels of ``mask (X, Y, Z) bool`` in each inclusive box ``lo..hi (m, 3)``."""
    S = np.zeros(tuple(np.asarray(mask.shape) + 1), np.int64)
    S[1:, 1:, 1:] = mask.astype(np.int64).cumsum(0).cumsum(1).cumsum(2)
    a, b = lo, hi + 1
    total = np.zeros(len(lo), np.int64)
    for corner in itertools.product((0, 1), repeat=3):
        idx = tuple(np.where(np.array(corner)[None, :] == 1, b, a).T)
        total += (-1) ** (3 - sum(corner)) * S[idx]
    return total


def _face_boxes(Vc, F, grid: VoxelGrid) -> tuple[np.ndarray, np.ndarray]:
    """Inclusive voxel index boxes ``(lo (m, 3), hi (m, 3))`` of the faces' bounding boxes
    (a face lying on a voxel face belongs to the voxel above it, as its centroid does)."""
    shape = np.asarray(grid.shape, dtype=np.int64)
    rel = np.asarray(Vc)[F] - grid.origin
    eps = 1e-9
    lo = np.clip(np.floor(rel.min(axis=1) + eps), 0, shape - 1).astype(np.int64)
    hi = np.clip(np.floor(rel.max(axis=1) - eps), 0, shape - 1).astype(np.int64)
    return lo, np.maximum(hi, lo)


def _cut_to_region(Vc, F, grid: VoxelGrid, mask3, normals, offsets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The part of the faces ``F`` inside the region ``mask3 (X, Y, Z) bool``: ``(V2, F2, src (m2,))``
    with the vertices of ``Vc`` kept at their indices, cut points appended and each piece's face of
    ``F``. Faces are cut plane by plane, and after each cut only the pieces whose voxel box still
    straddles the region are cut further, so a face is split only where the region's boundary
    passes through it."""
    from synthkit.core.mesh import checked_plane_args, split_by_plane

    V, F, normals, offsets, src, eps = checked_plane_args(Vc, F, normals, offsets, None)
    done, done_src = [], []

    def sort_out(V, F, src):
        lo, hi = _face_boxes(V, F, grid)
        count = _box_counts(mask3, lo, hi)
        volume = np.prod(hi - lo + 1, axis=1)
        done.append(F[count == volume])
        done_src.append(src[count == volume])
        part = (count > 0) & (count < volume)
        return F[part], src[part]

    F, src = sort_out(V, F, src)
    for n, d in zip(normals, offsets, strict=True):
        if len(F) == 0:
            break
        e = eps * np.linalg.norm(n)
        sd = V @ n - d
        mixed = (sd > e)[F].any(axis=1) & (sd < -e)[F].any(axis=1)
        if not mixed.any():
            continue
        V, Fi, Si, Fo, So = split_by_plane(V, F[mixed], src[mixed], n, d, e)
        F, src = sort_out(V, np.concatenate([F[~mixed], Fi, Fo]), np.concatenate([src[~mixed], Si, So]))
    if len(F):  # pieces crossing no plane but straddling by their box: keep by the centroid
        vox = np.clip(grid.voxel_of(V[F].mean(axis=1)), 0, np.asarray(grid.shape) - 1)
        inside = mask3[tuple(vox.T)]
        done.append(F[inside])
        done_src.append(src[inside])
    return V, np.concatenate(done), np.concatenate(done_src)


def assemble(
    Vc, F, grid: VoxelGrid, problem: RetargetProblem, labeling, attr=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The output mesh: ``(Vc (n, 3) canonical, F (m, 3), face_label (m,) int, attr (m, 3, k) or
    None)``, not welded; ``attr`` carries the input faces' corner values ``attr (#F, 3, k)``
    (:mod:`~synthkit.methods.retarget.corners`) onto every copy and cut piece.

    Output voxel ``x`` with label ``l`` takes the input inside voxel ``x - l`` translated by ``l``
    (canonical units), so copies stay aligned with the grid. Done per label, cutting only what
    must be cut: a face whose bounding box of voxels lies wholly inside the label's region is
    copied whole, one that touches none of it is left out, and only the faces straddling the
    region's boundary are split (exactly, shared cut vertices) along the planes of
    :func:`seam_planes` and kept by their pieces' centroids (why: docs/findings/retarget.md,
    "Cutting per label"). Where a split face meets an uncut neighbour of the same copy, the cut
    point is a T-junction on the neighbour's edge, closed by :func:`repair_t_junctions` after the
    weld.
    """
    Vc = np.asarray(Vc, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    regions = label_regions(problem, labeling)
    normals, offsets = seam_planes(regions, grid.shape)
    shape = tuple(int(n) for n in grid.shape)
    Vs, Fs, Ls, As = [], [], [], []
    off = 0
    for lab, mask in regions.items():
        if len(F) == 0:
            break
        V2, Fl, src = _cut_to_region(Vc, F, grid, mask.reshape(shape), normals, offsets + normals @ grid.origin)
        if len(Fl) == 0:
            continue
        used, inv = np.unique(Fl, return_inverse=True)
        Vs.append(V2[used] + problem.labels[lab])
        Fs.append(inv.reshape(-1, 3) + off)
        Ls.append(np.full(len(Fl), lab, dtype=np.int64))
        As.append(carry(V2, Fl, F, src, attr))
        off += len(used)
    if not Vs:
        empty = None if attr is None else np.zeros((0, 3, attr.shape[2]))
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), empty
    return np.concatenate(Vs), np.concatenate(Fs), np.concatenate(Ls), None if attr is None else np.concatenate(As)


SLIVER_DEG = 1.0
"""A face with an interior angle below this many degrees is a sliver (:func:`sliver_figures`)."""


def collapse_short_seam_edges(V, F, on_seam, max_length: float) -> tuple[np.ndarray, np.ndarray]:
    """Collapse interior edges of ``F (m, 3)`` shorter than ``max_length`` whose two vertices both
    lie on a seam plane (``on_seam (n,) bool`` over ``V (n, 3)``) and that carry a sliver: each
    moves its higher-index vertex onto the lower one, shortest edges first, one collapse per
    vertex. A collapse is made only when one of the two faces over the edge has an angle below
    :data:`SLIVER_DEG`, the moved vertex is on no open edge and the smallest angle of the faces
    around the edge grows (:func:`_smallest_angle`; the faces over the edge are dropped, the others
    must keep their orientation). Returns ``(F2 (m2, 3), src (m2,))``.

    Both ends lie on the plane, so a collapse moves a vertex along the seam only (by at most
    ``max_length``); cut points are numbered after the input's vertices, so where one end is an
    input vertex it is the one that stays. Why: docs/findings/retarget.md, "Short seam edges"."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3).copy()
    Ek = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    E, counts = np.unique(Ek, axis=0, return_counts=True)
    on_open = np.zeros(len(V), bool)
    on_open[E[counts == 1].reshape(-1)] = True
    length = np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)
    cand = np.flatnonzero((length < max_length) & (counts == 2) & on_seam[E[:, 0]] & on_seam[E[:, 1]])
    touched = np.zeros(len(V), bool)
    incident = _incidence(F, len(V))
    for e in cand[np.argsort(length[cand], kind="stable")]:
        a, b = E[e]
        if touched[a] or touched[b] or on_open[b]:
            continue
        around = np.array(sorted(incident[a] | incident[b]), np.int64)
        moved = np.where(F[around] == b, a, F[around])
        alive = (moved[:, 0] != moved[:, 1]) & (moved[:, 1] != moved[:, 2]) & (moved[:, 2] != moved[:, 0])
        if _smallest_angle(V, F[around][~alive]) >= np.radians(SLIVER_DEG):
            continue  # no sliver over the edge: leave the geometry alone
        if not _turns_less_than(V, F[around][alive], moved[alive], 0.5):
            continue
        if _smallest_angle(V, moved[alive]) <= _smallest_angle(V, F[around]):
            continue
        F[around] = moved
        touched[[a, b]] = True  # neither is visited again, so their incidence is not updated
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])
    return F[keep], np.flatnonzero(keep)


def _incidence(F: np.ndarray, n: int) -> list[set[int]]:
    """The faces of ``F (m, 3)`` around each of the ``n`` vertices."""
    flat = np.asarray(F, dtype=np.int64).reshape(-1)
    faces = (np.argsort(flat, kind="stable") // 3).tolist()
    bounds = np.r_[0, np.cumsum(np.bincount(flat, minlength=n))].tolist()
    return [set(faces[bounds[v] : bounds[v + 1]]) for v in range(n)]


def _face_min_angles(V, F) -> np.ndarray:
    """``(k,)`` smallest interior angle (radians) of each face ``F (k, 3)`` of ``V (n, 3)`` (0 for
    a face with a zero-length edge)."""
    tri = V[F]
    out = np.full(len(F), np.pi)
    for k in range(3):
        e1, e2 = tri[:, (k + 1) % 3] - tri[:, k], tri[:, (k + 2) % 3] - tri[:, k]
        den = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        cos = np.divide(np.einsum("ij,ij->i", e1, e2), den, out=np.ones(len(F)), where=den > 0)
        out = np.minimum(out, np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def _smallest_angle(V, F) -> float:
    """Smallest interior angle (radians) over the faces ``F (k, 3)`` of ``V``; pi when empty."""
    return float(_face_min_angles(V, F).min()) if len(F) else float(np.pi)


def _turns_less_than(V, before, after, min_cos: float) -> bool:
    """Whether each face ``after (k, 3)`` keeps a normal within ``arccos(min_cos)`` of the same
    face ``before (k, 3)``."""
    n0 = np.cross(V[before[:, 1]] - V[before[:, 0]], V[before[:, 2]] - V[before[:, 0]])
    n1 = np.cross(V[after[:, 1]] - V[after[:, 0]], V[after[:, 2]] - V[after[:, 0]])
    dots = np.einsum("ij,ij->i", n0, n1)
    return bool(np.all(dots >= min_cos * np.linalg.norm(n0, axis=1) * np.linalg.norm(n1, axis=1)))


def flip_sliver_edges(V, F, face_label=None, *, max_rounds: int = 4, attr=None, active=None) -> np.ndarray:
    """``F2 (m, 3)``: ``F (m, 3)`` with the longest edge of each sliver (an angle below
    :data:`SLIVER_DEG`) flipped where the face across it is coplanar (normals within 1e-9), has the
    same ``face_label`` (when given) and appearance map (:func:`same_map` of the corner values
    ``attr (m, 3, k)``, when given), the two form a convex quad and the flip raises the pair's
    smallest angle. The surface is unchanged (a coplanar pair covers the same quad either way) and
    faces keep their rows, so labels stay valid and each face's new corner values are its old
    face's map at the new corners (``carry(V, F2, F, arange(m), attr)``). Only the slivers among
    ``active (m,) bool`` (all when None) are tried first; later rounds revisit the faces around a
    flip. Rounds repeat until nothing flips.

    Why the flips and ``active``: docs/findings/retarget.md, "Slivers after the seam collapse" and
    "Slivers of the input"."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3).copy()
    lab = None if face_label is None else np.asarray(face_label).reshape(-1)
    incident = _incidence(F, len(V))
    todo = np.arange(len(F)) if active is None else np.flatnonzero(active)  # faces whose neighbourhood changed
    for _ in range(max_rounds):
        changed: set[int] = set()
        for f in todo[_face_min_angles(V, F[todo]) < np.radians(SLIVER_DEG)]:
            g = _flip_longest_edge(V, F, int(f), lab, incident, attr)
            if g is not None:
                for v in np.concatenate([F[f], F[g]]).tolist():
                    changed |= incident[v]
        if not changed:
            break
        todo = np.array(sorted(changed), np.int64)
    return F


def _flip_longest_edge(V, F, f: int, lab, incident: list[set[int]], attr=None) -> int | None:
    """Flip the longest edge of face ``f`` in place (see :func:`flip_sliver_edges`), keeping
    ``incident`` (:func:`_incidence`) up to date; the face across it when it did, else None."""
    tri = F[f]
    lengths = np.linalg.norm(V[np.roll(tri, -1)] - V[tri], axis=1)
    k = int(np.argmax(lengths))
    a, b, c = (int(x) for x in (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]))  # edge a-b, c opposite
    across = incident[a] & incident[b]
    if len(across) != 2:
        return None
    g = next(x for x in across if x != f)
    if lab is not None and lab[g] != lab[f]:
        return None
    if attr is not None and not same_map(V[F[[f]]], attr[[f]], V[F[[g]]], attr[[g]])[0]:
        return None
    d = int(F[g][~np.isin(F[g], [a, b])][0])
    if incident[c] & incident[d]:
        return None  # c-d is an edge already: the flip would double it
    new = np.array([[a, d, c], [d, b, c]])  # f's orientation: a -> b -> c
    n_old = np.cross(V[b] - V[a], V[c] - V[a])
    n_new = np.cross(V[new[:, 1]] - V[new[:, 0]], V[new[:, 2]] - V[new[:, 0]])
    n_g = np.cross(V[F[g][1]] - V[F[g][0]], V[F[g][2]] - V[F[g][0]])
    unit = np.linalg.norm(n_old) * np.linalg.norm(n_g)
    if unit == 0 or np.dot(n_old, n_g) < (1 - 1e-9) * unit:
        return None  # not coplanar (or degenerate)
    if np.any(n_new @ n_old <= 0):
        return None  # the quad is not convex across the edge
    if _smallest_angle(V, new) <= _smallest_angle(V, F[[f, g]]):
        return None
    F[f], F[g] = new  # f: a, d, c (leaves b, joins d); g: d, b, c (leaves a, joins c)
    incident[b].discard(f)
    incident[d].add(f)
    incident[a].discard(g)
    incident[c].add(g)
    return g


def repair_t_junctions(V, F, *, tol: float, max_rounds: int = 8, split_at=None) -> tuple[np.ndarray, np.ndarray]:
    """Split boundary edges at boundary vertices lying on them (within ``tol``), so that two
    copies cut by the same seam plane but tessellated differently share their seam vertices.

    ``V (n, 3)``, ``F (m, 3)`` welded; ``split_at (n,) bool`` (all when None) marks the vertices
    that may split an edge. Each round splits, for every face with such an edge, that
    edge into a fan from the opposite corner; rounds repeat until nothing changes. Returns
    ``(V, F2 (m2, 3), src (m2,))`` with the new faces' source face. Vertices are not moved, so no
    geometry is invented.

    The pipeline passes the vertices on voxel planes, where seams cut and copies meet, so the
    input's own junctions stay as they are (docs/findings/retarget.md, "T-junctions of the input").
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    src = np.arange(len(F))
    for _ in range(max_rounds):
        E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        key = np.sort(E, axis=1)
        uniq, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        inv = inv.reshape(-1)
        boundary = counts[inv] == 1
        if not boundary.any():
            break
        bverts = np.unique(E[boundary])
        if split_at is not None:
            bverts = bverts[np.asarray(split_at, bool)[bverts]]
        if len(bverts) == 0:
            break
        tree = cKDTree(V[bverts])
        splits: dict[int, list[tuple[float, int]]] = {}
        for row in np.flatnonzero(boundary):
            a, b = E[row]
            pa, pb = V[a], V[b]
            length = np.linalg.norm(pb - pa)
            if length <= tol:
                continue
            near = tree.query_ball_point((pa + pb) / 2, length / 2 + tol)
            d = (pb - pa) / length
            hits = []
            for j in near:
                v = int(bverts[j])
                if v in (a, b):
                    continue
                t = (V[v] - pa) @ d
                if tol < t < length - tol and np.linalg.norm(V[v] - pa - t * d) <= tol:
                    hits.append((t, v))
            if hits:
                face = row % len(F)
                splits.setdefault(face, [(row // len(F), sorted(hits))])
        if not splits:
            break
        keep = np.ones(len(F), bool)
        new_faces, new_src = [], []
        for face, [(corner, hits)] in splits.items():
            keep[face] = False
            a, b, c = F[face, corner], F[face, (corner + 1) % 3], F[face, (corner + 2) % 3]
            chain = [a] + [v for _, v in hits] + [b]
            for p, q in zip(chain[:-1], chain[1:], strict=True):
                new_faces.append([p, q, c])
                new_src.append(src[face])
        F = np.concatenate([F[keep], np.array(new_faces, dtype=np.int64)])
        src = np.concatenate([src[keep], np.array(new_src, dtype=np.int64)])
    return V, F, src


def _smallest_first(F: np.ndarray) -> np.ndarray:
    """``F (m, 3)`` with each face's vertex cycle rotated to start at its smallest index, so that
    two faces over the same vertices in the same orientation are equal rows."""
    first = np.argmin(F, axis=1)
    return np.take_along_axis(F, (first[:, None] + np.arange(3)[None, :]) % 3, axis=1)


def unique_faces(V, F, *, tol: float = POSITION_TOL) -> np.ndarray:
    """``keep (m,) bool``: False for each face of ``F (m, 3)`` over the same three vertices of
    ``V (n, 3)`` (welded by position within ``tol``) in the same cyclic orientation as an earlier
    face, i.e. a surface stored twice (docs/findings/retarget.md, "Surfaces stored twice in the
    input"). Faces in the opposite orientation (double-sided walls) are kept."""
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if len(F) == 0:
        return np.ones(0, bool)
    _, _, old_to_new = weld(V, np.zeros((0, 3), np.int64), tol, return_index=True)
    _, index = np.unique(_smallest_first(old_to_new[F]), axis=0, return_index=True)
    keep = np.zeros(len(F), bool)
    keep[index] = True
    return keep


def sliver_figures(V, F) -> dict:
    """Retargeting's extra figures beside :func:`synthkit.core.quality.mesh_quality` for
    ``V (n, 3)``, ``F (m, 3)``: ``min_angle_deg``, the smallest interior angle over the faces (0 for
    a zero-area sliver, None without faces; clipping leaves slivers where a cut passes close to a
    vertex), and ``sliver_faces``, the faces with an angle below :data:`SLIVER_DEG`."""
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if len(F) == 0:
        return {"min_angle_deg": None, "sliver_faces": 0}
    smallest = np.degrees(_face_min_angles(np.asarray(V, dtype=np.float64), F))
    return {"min_angle_deg": float(smallest.min()), "sliver_faces": int((smallest < SLIVER_DEG).sum())}


def merge_coplanar_faces(
    V, F, face_label=None, *, tol: float = 1e-7, attr=None, active=None
) -> tuple[np.ndarray, np.ndarray]:
    """Re-triangulate each connected region of coplanar faces (of one label) with fewer faces.

    ``V (n, 3)`` welded, ``F (m, 3)``, ``face_label (m,)`` or None, ``attr (m, 3, k)`` the faces'
    corner values or None (:mod:`~synthkit.methods.retarget.corners`). Faces are grouped when they
    share an edge (used by exactly those two faces), have the same label (when labels are given),
    lie in one plane (unit normals within ``1e-9`` of each other's direction and plane offsets
    within ``tol``) and show one affine appearance map (:func:`same_map`: same material, UVs and
    colours continuous and affine across the pair); a region whose faces drift off its first
    face's map is kept as it is, and so is a region without a face of ``active (m,) bool`` (all
    when None; the pipeline passes the faces touching a seam plane: a region away from every seam
    is the input's own, and re-triangulating it would cost time growing with the mesh). New faces
    take the map of their region (``src``). A region of three
    or more faces is replaced by the ear-clipping triangulation of its boundary loops
    (:func:`synthkit.core.mesh.triangulate_polygons`, holes included) when that uses fewer faces
    and covers the same area (relative ``1e-9``); otherwise it is kept. Every boundary vertex is
    kept, so neighbouring regions stay conforming; only vertices inside a flat region go. With
    labels, labels are never mixed, so every face still lies on its own copy of the input (the
    labelled output); without, the pieces of two copies that continue one flat surface across a
    seam become one region (the retargeted mesh). Returns ``(F2 (m2, 3),
    src (m2,))`` with each new face's source face (one face of its region).

    Why: docs/findings/retarget.md, "Flat regions".
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    m = len(F)
    lab = np.zeros(m, np.int64) if face_label is None else np.asarray(face_label, dtype=np.int64).reshape(-1)
    if m == 0:
        return F, np.arange(0)
    comp, area2, nrm = _coplanar_regions(V, F, lab, tol, attr)
    pid = weld(V, np.zeros((0, 3), np.int64), POSITION_TOL, return_index=True)[2]
    region_faces, region_loops, locked, n_touch = _region_loops(V, F, comp, area2, attr, pid, active)
    for _ in range(4):
        straight_in = np.zeros(len(V), np.int64)
        for loops in region_loops.values():
            for lp in loops:
                np.add.at(straight_in, pid[lp[_collinear(V, lp, tol)]], 1)
        drop = ((n_touch > 0) & (straight_in == n_touch) & ~locked)[pid]
        keep = np.ones(m, bool)
        new_faces, new_src = [], []
        failed = False
        for c, loops in region_loops.items():
            faces = region_faces[c]
            drops_here = any(drop[lp].any() for lp in loops)
            if len(faces) < 3 and not drops_here:
                continue  # nothing to gain
            tris = _retriangulate(V, F, faces, [lp[~drop[lp]] for lp in loops], nrm, area2, tol)
            if tris is None:
                if drops_here:
                    locked[pid[F[faces]].reshape(-1)] = True
                    failed = True
                continue
            keep[faces] = False
            new_faces.append(tris)
            new_src.append(np.full(len(tris), faces[0]))
        if not failed:
            break
    else:  # still failing: keep every vertex, only re-triangulate regions that need none dropped
        return F, np.arange(m)
    F2 = np.concatenate([F[keep]] + new_faces) if new_faces else F
    src = np.concatenate([np.flatnonzero(keep)] + new_src) if new_faces else np.arange(m)
    return F2, src


def _region_loops(V, F, comp, area2, attr, pid, active=None) -> tuple[dict, dict, np.ndarray, np.ndarray]:
    """The faces ``{region: (k,)}`` and boundary loops ``{region: [loop, ...]}`` of the regions
    :func:`merge_coplanar_faces` may re-triangulate, ``locked (n,) bool`` and ``n_touch (n,)``
    over the positions ``pid (n,)`` (vertices welded by position, so that an asset's UV-seam twins
    of a vertex are dropped together or not at all): locked are the positions touching more than
    two regions or a region that stays as it is, ``n_touch`` counts the regions at each.

    A region stays as it is when it has no ``active`` face, its faces have zero area, several
    appearance maps, or a vertex
    inside it (on none of its loops) that another region uses: building-small-a's walls stand on
    the inside of its floor slab, and re-triangulating the slab without the wall's foot vertices
    left the wall's bottom edge hanging (T-junctions, open edges)."""
    ncomp = int(comp.max()) + 1
    sizes = np.bincount(comp, minlength=ncomp)
    vc = np.unique(np.stack([pid[F].reshape(-1), np.repeat(comp, 3)], axis=1), axis=0)
    n_touch = np.bincount(vc[:, 0], minlength=len(V))
    locked = n_touch > 2
    members = np.argsort(comp, kind="stable")
    starts = np.r_[0, np.cumsum(sizes)]
    live = np.ones(ncomp, bool) if active is None else np.bincount(comp, weights=active, minlength=ncomp) > 0
    live &= area2[members[starts[:-1]]] > 0
    locked[pid[F[~live[comp]]].reshape(-1)] = True
    region_faces = {c: members[starts[c] : starts[c + 1]] for c in np.flatnonzero(live).tolist()}
    region_loops = {}
    for c, f in region_faces.items():
        first = np.full(len(f), f[0])
        loops = boundary_loops(F[f])
        inner = np.setdiff1d(pid[F[f]], pid[np.concatenate(loops)] if loops else np.zeros(0, np.int64))
        if (
            not loops
            or (n_touch[inner] > 1).any()
            or (attr is not None and not same_map(V[F[first]], attr[first], V[F[f]], attr[f]).all())
        ):
            locked[pid[F[f]].reshape(-1)] = True
            continue
        region_loops[c] = loops
    return region_faces, region_loops, locked, n_touch


def _coplanar_regions(V, F, lab, tol: float, attr=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Connected regions of coplanar faces of one label: ``(comp (m,), area2 (m,) twice the face
    areas, nrm (m, 3) unit normals)``. Two faces join when they share an edge used by exactly
    those two, have the same label, non-zero areas, normals within ``1e-9``, plane offsets
    within ``tol`` and one appearance map (:func:`same_map` of their corner values ``attr``)."""
    m = len(F)
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area2 = np.linalg.norm(cr, axis=1)
    nrm = np.divide(cr, area2[:, None], out=np.zeros_like(cr), where=area2[:, None] > 0)
    off = np.einsum("ij,ij->i", nrm, V[F[:, 0]])
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    fid = np.tile(np.arange(m), 3)
    _, inv, counts = np.unique(E, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    order = np.argsort(inv, kind="stable")
    two = counts[inv[order]] == 2
    a, b = fid[order[two][0::2]], fid[order[two][1::2]]
    same = (
        (lab[a] == lab[b])
        & (area2[a] > 0)
        & (area2[b] > 0)
        & (np.einsum("ij,ij->i", nrm[a], nrm[b]) >= 1 - 1e-9)
        & (np.abs(off[a] - off[b]) <= tol)
    )
    if attr is not None and same.any():
        same[same] = same_map(V[F[a[same]]], attr[a[same]], V[F[b[same]]], attr[b[same]])
    G = sp.coo_matrix((np.ones(int(same.sum())), (a[same], b[same])), shape=(m, m))
    _, comp = connected_components(G, directed=False)
    return comp, area2, nrm


def _collinear(V, loop: np.ndarray, tol: float) -> np.ndarray:
    """``(len(loop),) bool``: the loop vertex lies strictly between its two loop neighbours, within ``tol``."""
    P, Q, X = V[np.roll(loop, 1)], V[np.roll(loop, -1)], V[loop]
    d = Q - P
    ln = np.linalg.norm(d, axis=1)
    t = np.einsum("ij,ij->i", X - P, d) / np.where(ln > 0, ln, 1.0)
    off_line = np.linalg.norm(X - P - t[:, None] * d / np.where(ln > 0, ln, 1.0)[:, None], axis=1)
    return (ln > 0) & (t > 0) & (t < ln) & (off_line <= tol)


def _retriangulate(V, F, faces: np.ndarray, loops: list[np.ndarray], nrm, area2, tol: float) -> np.ndarray | None:
    """Ear-clipping triangulation ``(k, 3)`` of a flat region's boundary ``loops`` (its ``faces``),
    or None unless it has at most as many faces, the region's orientation, the same area and no
    flat triangle (a corner within ``tol`` of the line through the other two: a vertex kept on a
    straight stretch of the loop, because the region across it needs it, can be clipped as a
    sliver of float noise, which is a collapsed face and, by position, a T-junction)."""
    if not all(len(lp) >= 3 for lp in loops):
        return None
    n = nrm[faces[0]]
    u = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    P2 = np.zeros((len(V), 2))
    verts = np.unique(F[faces])
    P2[verts] = np.stack([V[verts] @ u, V[verts] @ w], axis=1)
    tris = triangulate_polygons(P2, loops, best_ear=True)
    if not 0 < len(tris) <= len(faces):
        return None
    t2 = np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]])
    total = area2[faces].sum()
    double = np.linalg.norm(t2, axis=1)
    same_area = abs(double.sum() - total) <= 1e-9 * total
    longest = np.linalg.norm(V[tris] - V[np.roll(tris, 1, axis=1)], axis=2).max(axis=1)
    flat = double <= tol * longest
    return tris if bool(np.all(t2 @ n > 0)) and same_area and not flat.any() else None
