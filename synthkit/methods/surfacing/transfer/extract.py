"""Extraction (section 4.5), kernel blending and geometry transfer (4.6).

Extraction copies: every corner of a covered target face is mapped through its face's patch to a
source face and barycentric position, and the signal (or, for textures, the texture coordinate)
is read there (the paper's first option; :mod:`.refine` adds its adaptive refinement first). Vertex values come from the
corners around the vertex: ``blend: kernel`` averages them weighted by face area (the simple
kernel blend across patch seams, one ring wide), ``blend: poisson`` solves for the vertex values
whose gradients best match every patch's own (Poisson blending, the paper's named improvement:
:func:`poisson_values`), ``blend: none`` takes the corner of the first covered face (with
``sampling: nearest``, every output value is then a source value). :func:`seam_visibility`
measures how much the seams stand out.

Geometry: the source's displacement field is the source minus its smoothed copy (implicit
umbrella smoothing over a given length, one sparse solve). A displacement is carried in the
source face's frame (along its two domain directions and its normal) and rebuilt in the target
face's frame of the same patch, scaled by ``scale``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from synthkit.core.mesh import face_adjacency, vertex_graph_edges
from synthkit.methods.surfacing.transfer.surface import Surface
from synthkit.methods.surfacing.transfer.synth import Result

__all__ = ["corner_sources", "corner_values", "vertex_values", "poisson_values", "seam_visibility", "smooth",
           "displacement_field", "transfer_displacement", "BLEND_EDGES",
           "boundary_edges"]

BLEND_EDGES = 10.0
"""``blend: poisson``: a seam's jump is spread over about this many mean edge lengths."""


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
                  blend: str = "kernel", V: np.ndarray | None = None) -> np.ndarray:
    """Per-vertex ``(#V, C)`` from corner ``values (#F, 3, C)`` (NaN rows: uncovered faces) of
    ``F (#F, 3)`` with face ``areas (#F,)``; NaN where no covered face touches the vertex.
    ``blend: poisson`` needs the positions ``V (#V, 3)``."""
    C = values.shape[2]
    covered = np.isfinite(values[:, 0, 0])
    out = np.full((n_vertices, C), np.nan)
    if blend == "poisson":
        kernel = vertex_values(F, values, areas, n_vertices)
        return poisson_values(V, F, values, kernel)
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


def _gradient_operator(V: np.ndarray, F: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """``G (3 #F, #V)``: the gradient of a piecewise-linear function per face (rows x, y, z of face f
    at ``3f .. 3f + 2``), the gradients ``(#F, 3, 3)`` of the faces' three hat functions and the face
    areas ``(#F,)``."""
    P = V[F]
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area2 = np.maximum(np.linalg.norm(n, axis=1), 1e-300)
    n /= area2[:, None]
    hats = np.stack([np.cross(n, P[:, (i + 2) % 3] - P[:, (i + 1) % 3]) / area2[:, None] for i in range(3)], axis=1)
    rows = (3 * np.arange(len(F))[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1)
    cols = np.repeat(F[:, :, None], 3, axis=2)
    G = sp.csr_matrix((hats.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * len(F), len(V)))
    return G, hats, 0.5 * area2


def poisson_values(V: np.ndarray, F: np.ndarray, values: np.ndarray, anchor: np.ndarray, *,
                   blend_edges: float = BLEND_EDGES) -> np.ndarray:
    """Per-vertex ``(#V, C)`` values whose gradient on every covered face best matches the gradient
    of that face's own corner ``values (#F, 3, C)`` (NaN rows: uncovered), in the least-squares
    sense weighted by face area, held weakly to ``anchor (#V, C)`` (the kernel blend, which fixes
    the level): ``(G^T A G + w M) c = G^T A g + w M anchor`` with M the vertex areas and
    ``w = 1 / (blend_edges * mean edge)^2``, so a seam's jump spreads over about ``blend_edges``
    edge lengths while each patch keeps its detail; clamped to the range of the corner values per
    channel (a gradient fit can overshoot it: no negative roughness, no colour out of the source's
    range). Vertices no covered face touches are NaN."""
    V, F = np.asarray(V, np.float64), np.asarray(F, np.int64)
    covered = np.isfinite(values[:, 0, 0])
    Fc, vals = F[covered], values[covered]
    used = np.unique(Fc)
    local = np.searchsorted(used, Fc)
    G, hats, area = _gradient_operator(V[used], local)
    g = np.einsum("fid,fic->fdc", hats, vals).reshape(-1, vals.shape[2])  # (3 #Fc, C)
    A = sp.diags(np.repeat(area, 3))
    mass = np.bincount(local.ravel(), weights=np.repeat(area / 3.0, 3), minlength=len(used))
    edge = float(np.linalg.norm(V[Fc] - V[np.roll(Fc, 1, axis=1)], axis=2).mean())
    w = 1.0 / (blend_edges * edge) ** 2
    M = sp.diags(w * mass)
    lhs = (G.T @ A @ G + M).tocsc()
    out = np.full((len(V), values.shape[2]), np.nan)
    solved = np.asarray(spla.splu(lhs).solve(G.T @ (A @ g) + M @ anchor[used]))
    out[used] = np.clip(solved, vals.min(axis=(0, 1)), vals.max(axis=(0, 1)))
    return out


def seam_visibility(V: np.ndarray, F: np.ndarray, patch_of: np.ndarray, vertex_vals: np.ndarray) -> float:
    """How much patch seams stand out in per-vertex ``vertex_vals (#V, C)``: the mean gradient
    magnitude of the covered faces along a seam (sharing an edge with a face of another patch) over
    that of the other covered faces (1: seams no sharper than the detail itself; NaN without seams
    or interior faces). ``patch_of (#F,)``: -1 uncovered."""
    V, F = np.asarray(V, np.float64), np.asarray(F, np.int64)
    G, _, _ = _gradient_operator(V, F)
    vals = np.nan_to_num(vertex_vals)
    grad = np.linalg.norm((G @ vals).reshape(len(F), -1), axis=1)
    pairs, _ = face_adjacency(F)
    a, b = patch_of[pairs[:, 0]], patch_of[pairs[:, 1]]
    cross = (a >= 0) & (b >= 0) & (a != b)
    seam = np.zeros(len(F), bool)
    seam[pairs[cross].ravel()] = True
    inner = (patch_of >= 0) & ~seam
    if not seam.any() or not inner.any():
        return float("nan")
    return float(grad[seam].mean() / max(grad[inner].mean(), 1e-300))


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
