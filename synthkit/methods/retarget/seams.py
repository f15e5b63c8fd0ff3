"""Stitching one labeling into a mesh (section III-B): the copies of the input each output voxel
takes, welded along the seams between labels, with T-junctions closed, short seam edges collapsed,
flat regions re-triangulated and slivers flipped across the seams.

Arrays in normalised units (the model's longest side spans [-1, 1]); ``attr (#F, 3, k)`` are the
corner values (:mod:`~synthkit.methods.retarget.corners`) carried through every step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from synthkit.core.mesh import merge_vertices
from synthkit.methods.retarget.corners import carry
from synthkit.methods.retarget.synthesis import (
    RetargetProblem,
    VoxelGrid,
    assemble,
    collapse_short_seam_edges,
    flip_sliver_edges,
    merge_coplanar_faces,
    repair_t_junctions,
    unique_faces,
)

__all__ = ["Retargeted", "stitch", "weld_seams", "on_voxel_planes", "SEAM_COLLAPSE"]

SEAM_COLLAPSE = 0.5
"""Seam edges shorter than this many dense spacings are collapsed where that improves the faces'
shape (:func:`~synthkit.methods.retarget.synthesis.collapse_short_seam_edges`): finer than the
descriptors see, and fanned across a face they make slivers."""


@dataclass
class Retargeted:
    """One synthesis result in normalised units: ``V (n, 3)``, ``F (m, 3)`` (the retargeted mesh,
    flat regions re-triangulated across seams), ``labelled_F (k, 3)`` with ``face_label (k,)`` (the
    same surface with every face inside one label's copy, for ``labels.ply``), the grid, the
    problem (labels, shapes), the labeling ``(N,)`` and its energy; ``attr (m, 3, k)`` the
    corner values of ``F`` (:mod:`~synthkit.methods.retarget.corners`) when the input had them."""

    V: np.ndarray
    F: np.ndarray
    face_label: np.ndarray
    grid: VoxelGrid
    problem: RetargetProblem
    labeling: np.ndarray
    energy: float
    cycles: int
    labelled_F: np.ndarray | None = None
    attr: np.ndarray | None = None


def stitch(Vn, F, attr, grid: VoxelGrid, problem: RetargetProblem, result, *, weld_tol: float, dense_radius: float):
    """The retargeted mesh of ``result`` (an alpha-expansion result on ``problem``, over ``grid``)
    from the normalised input ``Vn (#V, 3)``, ``F (#F, 3)``: assemble the labeling's copies, weld
    them along the seams (``weld_tol``), close T-junctions, collapse seam edges shorter than
    :data:`SEAM_COLLAPSE` x ``dense_radius``, re-triangulate flat regions and flip slivers (per
    label for ``labelled_F``, across seams for ``F``), carrying the corner values
    ``attr (#F, 3, k)`` through every step."""
    Vc, Fo, fl, A = assemble(grid.to_canonical(Vn), F, grid, problem, result.labels, attr)
    Vw, Fw, old_to_new = weld_seams(Vc, Fo, fl, grid, weld_tol)
    Fm = old_to_new[Fo]
    alive = (Fm[:, 0] != Fm[:, 1]) & (Fm[:, 1] != Fm[:, 2]) & (Fm[:, 2] != Fm[:, 0])
    fl, A = fl[alive], _take(A, alive)
    keep = unique_faces(Vw, Fw)
    Fw, fl, A = Fw[keep], fl[keep], _take(A, keep)
    F0 = Fw
    on_seam = on_voxel_planes(Vw, grid, weld_tol)
    Vw, Fw, src = repair_t_junctions(Vw, Fw, tol=weld_tol, split_at=on_seam)
    fl, A = fl[src], carry(Vw, Fw, F0, src, A)
    F0 = Fw
    Fw, src = collapse_short_seam_edges(Vw, Fw, on_seam, SEAM_COLLAPSE * dense_radius)
    fl, A = fl[src], carry(Vw, Fw, F0, src, A)
    Fl, src = merge_coplanar_faces(Vw, Fw, fl, tol=weld_tol, attr=A, active=on_seam[Fw].any(axis=1))
    fl, Al = fl[src], carry(Vw, Fl, Fw, src, A)
    F0 = Fl
    Fl = flip_sliver_edges(Vw, Fl, fl, attr=Al, active=on_seam[Fl].any(axis=1))
    Al = carry(Vw, Fl, F0, np.arange(len(Fl)), Al)
    Fw, src = merge_coplanar_faces(Vw, Fl, None, tol=weld_tol, attr=Al, active=on_seam[Fl].any(axis=1))
    A = carry(Vw, Fw, Fl, src, Al)
    F0 = Fw
    Fw = flip_sliver_edges(Vw, Fw, attr=A, active=on_seam[Fw].any(axis=1))
    A = carry(Vw, Fw, F0, np.arange(len(Fw)), A)
    used = np.unique(Fl)
    remap = np.full(len(Vw), -1)
    remap[used] = np.arange(len(used))
    return Retargeted(
        Vw[used], remap[Fw], fl, grid, problem, result.labels, result.energy, result.cycles,
        labelled_F=remap[Fl], attr=A,
    )


def _take(A, rows):
    """``A[rows]``, None when ``A`` is None."""
    return None if A is None else A[rows]


def on_voxel_planes(V, grid: VoxelGrid, tol: float) -> np.ndarray:
    """``(n,) bool``: the normalised vertices ``V (n, 3)`` within ``tol`` of a voxel face plane."""
    frac = grid.to_canonical(V) - grid.origin
    return ((np.abs(frac - np.rint(frac)) / np.linalg.norm(grid.inverse, axis=1)) <= tol).any(axis=1)


def weld_seams(Vc, F, face_label, grid: VoxelGrid, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weld the assembled copies along their seams only.

    ``Vc (n, 3)`` canonical vertices of :func:`~synthkit.methods.retarget.synthesis.assemble`
    (one block of vertices per label), ``F (m, 3)``, ``face_label (m,)``. Two vertices are merged
    when they are within ``tol`` (normalised units) of each other, belong to different labels'
    copies and lie within ``tol`` of a voxel face plane (a seam between two labels' voxels may run
    across any axis); every other vertex is kept as it is, so parts of the input
    that only touch (a baluster standing on a rail, the unwelded UV seams of an asset) keep their
    own vertices, as in the input.

    Returns ``(V (#V2, 3) normalised, F2 (#F2, 3), old_to_new (n,))`` as :func:`~synthkit.core.mesh.weld`.
    """
    Vc = np.asarray(Vc, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    Vn = grid.to_normalised(Vc)
    pairs = np.zeros((0, 2), np.int64)
    if len(Vc):
        vlab = np.full(len(Vc), -1, np.int64)
        vlab[F.reshape(-1)] = np.repeat(np.asarray(face_label, np.int64), 3)
        frac = Vc - grid.origin
        dist = np.abs(frac - np.rint(frac)) / np.linalg.norm(grid.inverse, axis=1)  # normalised units
        on_seam = np.flatnonzero((dist <= tol).any(axis=1) & (vlab >= 0))
        if len(on_seam) > 1:
            pairs = on_seam[cKDTree(Vn[on_seam]).query_pairs(tol, output_type="ndarray")]
            pairs = pairs[vlab[pairs[:, 0]] != vlab[pairs[:, 1]]]
    return merge_vertices(Vn, F, pairs, return_index=True)
