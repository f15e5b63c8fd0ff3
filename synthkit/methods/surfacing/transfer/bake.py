"""Blended textures through UVs (issue 29): a texture atlas baked per texture pair, and how much
its patch seams show.

Read through UVs into the source image (``blend: none``), each patch shows the source's own texels,
so a patch border is a jump between two unrelated places of the source. With ``blend: poisson``
(or ``kernel``) the texture takes the correction the vertex values got: per corner,
``d = blended vertex value - the corner's own (prefiltered) value``, interpolated over the face and
added to the full-resolution source texture read through the patch (the leveling of Lempitsky and
Ivanov, "Seamless mosaicing of image-based texture maps", 2007, with the Poisson fit of
:func:`.extract.poisson_values` as the leveling function): the low frequencies are the blended
ones, the detail the source's. The leveling cannot join two unrelated places of a texture (a stone
edge meeting mortar), so near a seam the texture is also feathered (:func:`feathered`): every patch
whose accepted faces reach a point contributes its own levelled texture, weighted by vertex weights
that are 1 on the patch's own faces, fall linearly to 0 over a band and are 0 wherever the patch
maps nothing, so the result is continuous across a seam wherever the two patches overlap
(docs/findings/surface-by-numbers.md). A correction cannot be expressed through UVs into the
source, so the texture is baked (:func:`bake`): each patch's faces, laid out by their domain coordinates (the
patch's own parameterization, without overlaps), are one chart of an atlas at a given texel size,
packed in shelves with a gutter of ``GUTTER`` texels filled from the nearest texel.

:func:`texture_seam_visibility` measures the seams of any such texture.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.ndimage import distance_transform_edt
from scipy.sparse.csgraph import dijkstra

from synthkit.core.mesh import barycentric, face_adjacency, vertex_graph_edges

__all__ = ["GUTTER", "MAX_SIDE", "OWNER_WEIGHT", "Atlas", "Blend", "feathered", "bake", "shelf_pack",
           "texture_seam_visibility"]

GUTTER = 2
"""Texels around each chart filled from its nearest texel, so bilinear reads and mipmaps at a
chart's rim do not pick up its neighbour."""
MAX_SIDE = 2048
"""The atlas's largest side in texels: above it the texel grows until the charts fit."""


@dataclass
class Atlas:
    """``image (H, W, C) float32``, ``uv (#F, 3, 2)`` corner UVs into it (NaN on faces without a patch;
    u right, v up) and the ``texel`` size used (domain units)."""

    image: np.ndarray
    uv: np.ndarray
    texel: float


def shelf_pack(sizes: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Positions ``(n, 2)`` (row, column) of rectangles ``sizes (n, 2)`` (height, width) packed in
    shelves, tallest first, in a strip as wide as the square root of their total area (at least the
    widest); and the packed height and width."""
    sizes = np.asarray(sizes, np.int64).reshape(-1, 2)
    width = int(max(sizes[:, 1].max(initial=1), np.ceil(np.sqrt((sizes[:, 0] * sizes[:, 1]).sum()))))
    pos = np.zeros((len(sizes), 2), np.int64)
    x = y = shelf = 0
    for i in np.argsort(-sizes[:, 0], kind="stable"):
        h, w = sizes[i]
        if x + w > width:
            x, y, shelf = 0, y + shelf, 0
        pos[i] = (y, x)
        x, shelf = x + w, max(shelf, h)
    return pos, int(y + shelf), width


def _raster_ids(T: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``(h, w) int32`` index of the triangle ``T (n, 3, 2)`` (chart pixel coordinates, x right, y
    down, texel centres at half-integers) covering each texel centre; -1 where none."""
    import cv2

    ids = np.full(shape, -1, np.int32)
    pts = np.round((T - 0.5) * 256.0).astype(np.int32)
    for i in range(len(T)):
        cv2.fillPoly(ids, [pts[i]], color=int(i), shift=8)
    return ids


def _chart_frames(corner_uv, patch_of, texel):
    patches = np.unique(patch_of[patch_of >= 0])
    lo = np.array([corner_uv[patch_of == p].reshape(-1, 2).min(axis=0) for p in patches]).reshape(-1, 2)
    hi = np.array([corner_uv[patch_of == p].reshape(-1, 2).max(axis=0) for p in patches]).reshape(-1, 2)
    sizes = (np.ceil((hi - lo) / texel).astype(np.int64) + 1 + 2 * GUTTER)[:, ::-1]
    return patches, lo, hi, sizes


def bake(corner_uv: np.ndarray, patch_of: np.ndarray, colour: Callable, texel: float, *,
         channels: int = 3, max_side: int = MAX_SIDE) -> Atlas:
    """Bake the texture of the covered faces into one atlas.

    ``corner_uv (#F, 3, 2)`` are the faces' domain coordinates, ``patch_of (#F,)`` their patch (-1:
    none) and ``colour(faces (n,), bary (n, 3)) -> (n, C)`` the colour at points of the faces.
    ``texel`` is the texel size in domain units (grown until the atlas fits ``max_side``)."""
    corner_uv, patch_of = np.asarray(corner_uv, np.float64), np.asarray(patch_of)
    ids, lo, hi, sizes = _chart_frames(corner_uv, patch_of, texel)
    pos, H, W = shelf_pack(sizes)
    while max(H, W) > max_side:
        texel *= 1.02 * max(H, W) / max_side
        ids, lo, hi, sizes = _chart_frames(corner_uv, patch_of, texel)
        pos, H, W = shelf_pack(sizes)
    image = np.zeros((H, W, channels), np.float32)
    uv = np.full(corner_uv.shape, np.nan)
    for c, p in enumerate(ids):
        faces = np.flatnonzero(patch_of == p)
        # chart pixel coordinates: x right from lo, y down from hi (domain y up = image v up)
        X = np.stack([(corner_uv[faces, :, 0] - lo[c, 0]) / texel + GUTTER,
                      (hi[c, 1] - corner_uv[faces, :, 1]) / texel + GUTTER], axis=2)
        y0, x0 = pos[c]
        uv[faces] = np.stack([(x0 + X[..., 0]) / W, 1.0 - (y0 + X[..., 1]) / H], axis=2)
        image[y0:y0 + sizes[c, 0], x0:x0 + sizes[c, 1]] = _chart(X, faces, colour, corner_uv[faces], lo[c], hi[c],
                                                                texel, tuple(sizes[c]), channels)
    return Atlas(image, uv, float(texel))


def _chart(X, faces, colour, Q, lo, hi, texel, shape, channels) -> np.ndarray:
    """One chart ``shape + (C,)``: the colour at every texel centre inside the patch's faces (chart
    pixel corners ``X (n, 3, 2)``, domain corners ``Q (n, 3, 2)``), the rest from the nearest one."""
    tri = _raster_ids(X, shape)
    inside = tri >= 0
    out = np.zeros(shape + (channels,), np.float32)
    if not inside.any():
        return out
    r, c = np.nonzero(inside)
    D = np.c_[lo[0] + (c + 0.5 - GUTTER) * texel, hi[1] - (r + 0.5 - GUTTER) * texel]
    f = tri[r, c]
    out[r, c] = colour(faces[f], barycentric(Q[f], D[:, None])[:, 0])
    _, (ri, ci) = distance_transform_edt(~inside, return_indices=True)
    return out[ri, ci]


def _edge_points(V, F, face, i, j, t, step):
    """Points ``(n, 3)`` on the edges ``(V[i], V[j])`` at ``t (n,)`` moved into ``face (n,)`` by
    ``min(step / 2, a quarter of the face's height over the edge)``, their barycentric coordinates
    in it ``(n, 3)`` and the distance moved ``(n,)``."""
    P = V[F[face]]
    a, b = V[i], V[j]
    e = b - a
    le = np.maximum(np.linalg.norm(e, axis=1), 1e-300)
    third = P.sum(axis=1) - a - b  # the corner off the edge
    w = third - a
    perp = w - ((w * e).sum(1) / le**2)[:, None] * e
    height = np.maximum(np.linalg.norm(perp, axis=1), 1e-300)
    move = np.minimum(0.5 * step, 0.25 * height)
    x = a + t[:, None] * e + (move / height)[:, None] * perp
    e1, e2, r = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0], x - P[:, 0]
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    r1, r2 = (r * e1).sum(1), (r * e2).sum(1)
    den = np.maximum(d11 * d22 - d12 * d12, 1e-300)
    b1, b2 = (d22 * r1 - d12 * r2) / den, (d11 * r2 - d12 * r1) / den
    return np.stack([1 - b1 - b2, b1, b2], axis=1), move


def texture_seam_visibility(V: np.ndarray, F: np.ndarray, patch_of: np.ndarray, colour: Callable, step: float, *,
                            samples: int = 8) -> float:
    """How much patch seams stand out in a texture read by ``colour(faces (n,), bary (n, 3)) -> (n, C)``
    on the covered faces of ``V, F`` (``patch_of (#F,)``, -1 uncovered): across every edge between
    two covered faces, the colour is read at ``samples`` points along it, each moved by ``step / 2``
    (at most a quarter of the face's height) into either face; the colour difference over the
    distance between the two points, averaged (by edge length) over seam edges (faces of two
    patches) and divided by the same over the other edges: 1 when a seam is no sharper than the
    texture's own detail at that step. NaN without seam or inner edges."""
    V, F = np.asarray(V, np.float64), np.asarray(F, np.int64)
    pairs, edges = face_adjacency(F)
    pf, pg = patch_of[pairs[:, 0]], patch_of[pairs[:, 1]]
    keep = (pf >= 0) & (pg >= 0)
    pairs, edges, seam = pairs[keep], edges[keep], (pf != pg)[keep]
    if not seam.any() or seam.all():
        return float("nan")
    t = (np.arange(samples) + 0.5) / samples
    n = len(pairs)
    i, j, tt = np.repeat(edges[:, 0], samples), np.repeat(edges[:, 1], samples), np.tile(t, n)
    side = []
    for k in range(2):
        face = np.repeat(pairs[:, k], samples)
        bary, move = _edge_points(V, F, face, i, j, tt, step)
        side.append((colour(face, bary), move))
    jump = np.linalg.norm(side[0][0] - side[1][0], axis=1) / np.maximum(side[0][1] + side[1][1], 1e-300)
    length = np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1)
    per_edge = jump.reshape(n, samples).mean(axis=1)
    ratio = np.average(per_edge[seam], weights=length[seam]) / max(np.average(per_edge[~seam],
                                                                                weights=length[~seam]), 1e-300)
    return float(ratio)


OWNER_WEIGHT = 1e-3
"""Weight of a face's own patch added everywhere on the face, so a point no blend weight reaches
(a patch whose neighbours do not map there) shows its own patch."""


@dataclass
class Blend:
    """The texture of a synthesized surface, feathered across patch seams (module docstring): one
    row per (face, patch) pair that contributes there: ``face (n,)``, ``patch (n,)``, the face's
    corners in the patch's domain ``uv (n, 3, 2)``, corner blend ``weight (n, 3)``, whether the
    patch is the face's own ``owner (n,)``, the corner correction ``d (n, 3, C)`` (or None), rows
    sorted by face with ``start (#F + 1,)`` offsets; ``read(src_faces, src_bary) -> (n, C)`` reads
    the source texture at full resolution."""

    face: np.ndarray
    patch: np.ndarray
    uv: np.ndarray
    weight: np.ndarray
    owner: np.ndarray
    start: np.ndarray
    patches: list
    read: Callable
    d: np.ndarray | None = None

    def _rows(self, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Query index ``q`` and row ``r`` of every (query, contributing row) pair."""
        first, count = self.start[faces], self.start[faces + 1] - self.start[faces]
        q = np.repeat(np.arange(len(faces)), count)
        offset = np.arange(len(q)) - np.repeat(np.cumsum(count) - count, count)
        return q, first[q] + offset

    def sources(self, rows: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Source faces ``(n,)`` and barycentric ``(n, 3)`` of domain points ``Q (n, 2)`` of ``rows``."""
        src, bary = np.zeros(len(rows), np.int64), np.zeros((len(rows), 3))
        of = self.patch[rows]
        for p in np.unique(of):
            m = of == p
            src[m], bary[m], _ = self.patches[p].to_source(Q[m])
        return src, bary

    def colour(self, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """Colour ``(n, C)`` at points ``bary (n, 3)`` of ``faces (n,)``: each contributing patch's
        texture (plus its correction) weighted by its interpolated corner weights."""
        q, r = self._rows(np.asarray(faces, np.int64))
        b = bary[q]
        col = self.read(*self.sources(r, np.einsum("nk,nkc->nc", b, self.uv[r])))
        if self.d is not None:
            col = col + np.einsum("nk,nkc->nc", b, self.d[r])
        w = np.einsum("nk,nk->n", b, self.weight[r]) + OWNER_WEIGHT * self.owner[r]
        out = np.zeros((len(faces), col.shape[1]))
        np.add.at(out, q, w[:, None] * col)
        return np.clip(out / np.bincount(q, weights=w, minlength=len(faces))[:, None], 0.0, 1.0)


def _patch_weights(V, F, graph, patch_of, p: int, accepted: np.ndarray, band: float) -> np.ndarray:
    """Vertex weights ``(#V,)`` of patch ``p``: 1 on its own faces' corners, falling linearly to 0 at
    ``band`` (shortest path along edges) away from them, and 0 on every vertex that a covered face
    outside the patch's accepted faces ``accepted (k,)`` touches (there the patch maps nothing)."""
    own = np.unique(F[patch_of == p])
    if band <= 0:
        w = np.zeros(len(V))
        w[own] = 1.0
    else:
        dist = dijkstra(graph, directed=False, indices=own, min_only=True, limit=band)
        w = np.clip(1.0 - dist / band, 0.0, 1.0)
    inside = np.zeros(len(F), bool)
    inside[accepted] = True
    w[F[(patch_of >= 0) & ~inside].ravel()] = 0.0
    return w


def feathered(V: np.ndarray, F: np.ndarray, patch_of: np.ndarray, corner_uv: np.ndarray, patches, band: float,
              read: Callable, *, smooth: Callable | None = None, blended: np.ndarray | None = None) -> Blend:
    """The :class:`Blend` of a synthesized surface ``V, F`` (``patch_of (#F,)``, owner domain corners
    ``corner_uv (#F, 3, 2)``, ``patches`` with their accepted ``faces`` and ``corner_uv``), feathered
    over ``band`` (surface units; 0: each face shows its own patch only). With ``blended (#V, C)``
    (the blended vertex values) each row carries the correction ``blended - smooth(...)`` at its
    corners, ``smooth`` reading the signal the vertex values were made of."""
    E = vertex_graph_edges(F)
    length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    graph = sp.csr_matrix((length, (E[:, 0], E[:, 1])), shape=(len(V), len(V)))
    parts = []
    for p in np.unique(patch_of[patch_of >= 0]):
        patch = patches[p]
        w = _patch_weights(V, F, graph, patch_of, p, patch.faces, band)
        own = np.flatnonzero(patch_of == p)
        parts.append((own, np.full(len(own), p), corner_uv[own], w[F[own]], np.ones(len(own), bool)))
        near = (w[F[patch.faces]].max(axis=1) > 0) & (patch_of[patch.faces] >= 0) & (patch_of[patch.faces] != p)
        near &= band > 0
        parts.append((patch.faces[near], np.full(int(near.sum()), p), patch.corner_uv[near], w[F[patch.faces[near]]],
                      np.zeros(int(near.sum()), bool)))
    face, patch, uv, weight, owner = (np.concatenate([part[i] for part in parts]) for i in range(5))
    order = np.argsort(face, kind="stable")
    face, patch, uv, weight, owner = face[order], patch[order], uv[order], weight[order], owner[order]
    start = np.searchsorted(face, np.arange(len(F) + 1))
    out = Blend(face, patch, uv, weight, owner, start, patches, read)
    if blended is not None:
        rows = np.repeat(np.arange(len(face)), 3)
        src, bary = out.sources(rows, uv.reshape(-1, 2))
        out.d = blended[F[face]] - smooth(src, bary).reshape(len(face), 3, -1)
    return out
