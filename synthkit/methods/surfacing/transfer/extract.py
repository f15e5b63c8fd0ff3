"""Extraction (section 4.5), kernel blending and geometry transfer (4.6).

Extraction copies: every corner of a covered target face is mapped through its face's patch to a
source face and barycentric position, and the signal (or, for textures, the texture coordinate)
is read there (the paper's first option; :mod:`.refine` adds its adaptive refinement first). Vertex values come from the
corners around the vertex: ``blend: kernel`` averages them weighted by face area (the simple
kernel blend across patch seams, one ring wide), ``blend: none`` takes the corner of the first
covered face (with ``sampling: nearest``, every output value is then a source value).

Geometry: the source's displacement field is the source minus its smoothed copy (implicit
umbrella smoothing over a given length, one sparse solve). A displacement is carried in the
source face's frame (along its two domain directions and its normal) and rebuilt in the target
face's frame of the same patch, scaled by ``scale``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from synthkit.core.mesh import vertex_graph_edges
from synthkit.methods.surfacing.transfer.surface import Surface
from synthkit.methods.surfacing.transfer.synth import Result

__all__ = ["corner_sources", "corner_values", "vertex_values", "smooth", "displacement_field", "transfer_displacement"]


def corner_sources(result: Result, n_faces: int):
    """Source face ``(#F, 3)`` (-1 uncovered), barycentric ``(#F, 3, 3)`` and patch of every target
    corner."""
    src = np.full((n_faces, 3), -1, np.int64)
    bary = np.zeros((n_faces, 3, 3))
    for p in np.unique(result.patch_of[result.patch_of >= 0]):
        faces = np.flatnonzero(result.patch_of == p)
        f, b, _ = result.patches[p].to_source(result.corner_uv[faces].reshape(-1, 2))
        src[faces], bary[faces] = f.reshape(-1, 3), b.reshape(-1, 3, 3)
    return src, bary


def corner_values(result: Result, source: Surface, n_faces: int, *, nearest: bool = False) -> np.ndarray:
    """Signal ``(#F, 3, C)`` at every target corner (NaN uncovered)."""
    src, bary = corner_sources(result, n_faces)
    out = np.full((n_faces, 3, source.signal.channels), np.nan)
    ok = src >= 0
    out[ok] = source.signal.sample(src[ok], bary[ok], nearest=nearest)
    return out


def vertex_values(F: np.ndarray, values: np.ndarray, areas: np.ndarray, n_vertices: int, *,
                  blend: str = "kernel") -> np.ndarray:
    """Per-vertex ``(#V, C)`` from corner ``values (#F, 3, C)`` (NaN rows: uncovered faces) of
    ``F (#F, 3)`` with face ``areas (#F,)``; NaN where no covered face touches the vertex."""
    C = values.shape[2]
    covered = np.isfinite(values[:, 0, 0])
    out = np.full((n_vertices, C), np.nan)
    if blend == "none":
        faces = np.flatnonzero(covered)[::-1]
        for k in range(3):
            out[F[faces, k]] = values[faces, k]
        return out
    w = np.where(covered, areas, 0.0)
    num = np.zeros((n_vertices, C))
    den = np.zeros(n_vertices)
    for k in range(3):
        np.add.at(num, F[:, k], np.nan_to_num(values[:, k]) * w[:, None])
        np.add.at(den, F[:, k], w)
    has = den > 0
    out[has] = num[has] / den[has, None]
    return out


def smooth(V: np.ndarray, F: np.ndarray, *, length: float, edge: float | None = None) -> np.ndarray:
    """Implicit umbrella smoothing ``(#V, 3)`` of ``V (#V, 3)`` over the edges of ``F``: solve
    ``(D + t (D - A)) X = D V`` with ``t = (length / edge)^2`` (``edge``: the mean edge length of
    ``V`` unless given, so the same operator can smooth another field), boundary vertices held, so
    detail of wavelength ``lambda`` keeps about ``1 / (1 + (2 pi length / lambda)^2)`` of its
    amplitude and an open flat piece does not shrink."""
    E = vertex_graph_edges(F)
    n = len(V)
    A = sp.coo_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n)).tocsr()
    deg = np.asarray(A.sum(axis=1)).ravel()
    if edge is None:
        edge = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean())
    t = (length / edge) ** 2
    held = np.zeros(n)
    held[np.unique(boundary_edges(F))] = 1.0
    free = sp.diags(1.0 - held)
    M = (sp.diags(deg) + t * free @ (sp.diags(deg) - A)).tocsc()
    return np.asarray(spla.spsolve(M, sp.diags(deg) @ np.asarray(V, np.float64)))


def boundary_edges(F: np.ndarray) -> np.ndarray:
    """Edges ``(k, 2)`` used by exactly one face of ``F``."""
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(E, axis=0, return_counts=True)
    return uniq[count == 1].reshape(-1, 2)


def displacement_field(V: np.ndarray, F: np.ndarray, *, length: float) -> np.ndarray:
    """Displacement ``(#V, 3)``: ``V`` minus its smoothed copy (:func:`smooth`)."""
    return np.asarray(V, np.float64) - smooth(V, F, length=length)


def _target_frames(V: np.ndarray, F: np.ndarray, corner_uv: np.ndarray) -> np.ndarray:
    """``(n, 3, 2)`` maps from domain vectors to 3-D tangent vectors of target faces ``F (n, 3)``."""
    P = V[F]
    Q = corner_uv
    A = np.stack([Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0]], axis=2)
    B = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)
    return B @ np.linalg.inv(A)


def transfer_displacement(result: Result, target: Surface, source: Surface, field: np.ndarray, *,
                          scale: float) -> np.ndarray:
    """Displacement ``(#F, 3, 3)`` at every target corner (NaN uncovered): the source field
    ``field (#Fs, 3, 3)`` per source corner, split into its domain part (through the source
    triangle's Jacobian) and its normal part, rebuilt with the target face's frame and normal."""
    n = len(target.F)
    out = np.full((n, 3, 3), np.nan)
    for p in np.unique(result.patch_of[result.patch_of >= 0]):
        faces = np.flatnonzero(result.patch_of == p)
        patch = result.patches[p]
        tri, bary, _ = patch.locator.locate(result.corner_uv[faces].reshape(-1, 2))
        sf = patch.src_faces[tri]
        d = np.einsum("nk,nkc->nc", bary, field[sf])
        dn = (d * source.N[sf]).sum(axis=1)
        dom = np.einsum("nij,nj->ni", patch.jacobians(source, tri), d)
        Mt = np.repeat(_target_frames(target.V, target.F[faces], result.corner_uv[faces]), 3, axis=0)
        Nt = np.repeat(target.N[faces], 3, axis=0)
        out[faces] = (np.einsum("nij,nj->ni", Mt, dom) + scale * dn[:, None] * Nt).reshape(-1, 3, 3)
    return out
