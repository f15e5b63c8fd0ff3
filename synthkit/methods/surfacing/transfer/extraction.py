"""Extraction of a transfer (section 4.5): the work mesh and each pair's prepared surfaces, the patch
layout over the work mesh's faces, and the values, texture corners and baked atlases the output
shows, from the synthesized patches."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import trimesh

from synthkit.core.mesh import barycentric, face_areas, face_normals
from synthkit.methods.surfacing.transfer.bake import bake, feathered
from synthkit.methods.surfacing.transfer.extract import (
    corner_sources,
    corner_values,
    transfer_displacement,
    vertex_values,
)
from synthkit.methods.surfacing.transfer.surface import Signal, Surface, texel_size
from synthkit.methods.surfacing.transfer.synth import Result as Synthesized

__all__ = ["Prepared", "WorkMesh", "Layout", "Extracted", "layout_of", "face_errors", "border_vertices",
           "texture_blend", "extract"]


@dataclass
class Prepared:
    """One pair ready to synthesize: surfaces, compared channels, patch radius, config key, the
    source's unfiltered texture and the scale (target units per source unit)."""

    target: Surface
    source: Surface
    channels: list[int] | None
    radius: float
    key: str
    texture: np.ndarray | None = None
    scale: float = 1.0


@dataclass
class WorkMesh:
    """The target as the transfer works on it: texture seams welded (face order kept) and faces
    wound consistently, refined by
    ``extraction.subdivide`` midpoint steps. ``parent (#F,)`` is each face's face in the input,
    ``colors (#V, 3)`` the input's colours (vertex colours or the texture at the vertices) or None."""

    mesh: trimesh.Trimesh
    parent: np.ndarray
    colors: np.ndarray | None
    original: np.ndarray | None = None
    texture: np.ndarray | None = None


@dataclass
class Extracted:
    """The target mesh's new ``positions (#V, 3)``, ``colors (#V, 3)`` in [0, 1], ``attributes`` and
    the patch id per face ``patch_ids (#F,)`` (-1 outside the target regions); for texture pairs the
    corner ``uv (#F, 3, 2)``, the ``material (#F,)`` and, when blended, the baked atlas image of
    pair k in ``atlases[k]``."""

    positions: np.ndarray
    colors: np.ndarray
    attributes: dict
    patch_ids: np.ndarray
    uv: np.ndarray | None = None
    material: np.ndarray | None = None
    atlases: dict = field(default_factory=dict)


@dataclass
class Layout:
    """Per face of the work mesh: its ``pair (#F,)`` (-1 outside every target region), ``patch
    (#F,)`` (-1 uncovered), corner domain coordinates ``uv (#F, 3, 2)`` and the face of the
    synthesis mesh it was refined from, ``origin (#F,)``."""

    pair: np.ndarray
    patch: np.ndarray
    uv: np.ndarray
    origin: np.ndarray

    def result(self, k: int, res: Synthesized) -> SimpleNamespace:
        """Pair ``k``'s patches over the whole work mesh, in the form the extract stages read."""
        return SimpleNamespace(patch_of=np.where(self.pair == k, self.patch, -1), corner_uv=self.uv,
                               patches=res.patches)


def layout_of(work: WorkMesh, preps, results) -> Layout:
    nF = len(work.mesh.faces)
    out = Layout(np.full(nF, -1, np.int64), np.full(nF, -1, np.int64), np.zeros((nF, 3, 2)), np.arange(nF))
    for k, (prep, (res, _)) in enumerate(zip(preps, results, strict=True)):
        f = prep.target.face_ids
        out.pair[f], out.patch[f], out.uv[f] = k, res.patch_of, res.corner_uv
    return out


def face_errors(layout: Layout, preps, results) -> tuple[np.ndarray, np.ndarray]:
    """Signal error of the linear reconstruction at edge midpoints ``(#F, 3)`` and centres ``(#F,)``
    (NaN where not covered), in the channels the pair compares."""
    nF = len(layout.pair)
    mid, centre = np.full((nF, 3), np.nan), np.full(nF, np.nan)
    for k, (prep, (res, _)) in enumerate(zip(preps, results, strict=True)):
        for p in np.unique(layout.patch[(layout.pair == k) & (layout.patch >= 0)]):
            faces = np.flatnonzero((layout.pair == k) & (layout.patch == p))
            Q = layout.uv[faces]
            probes = np.concatenate([Q, 0.5 * (Q + np.roll(Q, -1, axis=1)), Q.mean(axis=1, keepdims=True)], axis=1)
            f, b, _ = res.patches[p].to_source(probes.reshape(-1, 2))
            v = prep.source.signal.sample(f, b).reshape(len(faces), 7, -1)
            v = v if prep.channels is None else v[..., prep.channels]
            linear = 0.5 * (v[:, :3] + np.roll(v[:, :3], -1, axis=1))
            mid[faces] = np.linalg.norm(v[:, 3:6] - linear, axis=2)
            centre[faces] = np.linalg.norm(v[:, 6] - v[:, :3].mean(axis=1), axis=1)
    return mid, centre


def border_vertices(F_full: np.ndarray, region_faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """``(#V,) bool``: vertices of the region that faces outside it use too."""
    inside = np.zeros(len(F_full), bool)
    inside[region_faces] = True
    used_in, used_out = np.zeros(n_vertices, bool), np.zeros(n_vertices, bool)
    used_in[F_full[inside].ravel()] = True
    used_out[F_full[~inside].ravel()] = True
    return used_in & used_out


def texture_corners(ext: Extracted, work: WorkMesh, k: int, prep: Prepared, res) -> None:
    """Corner UVs into pair ``k``'s source texture (material ``k + 1``) on its covered faces."""
    nF = len(work.mesh.faces)
    if ext.uv is None:
        ext.uv, ext.material = np.full((nF, 3, 2), np.nan), np.zeros(nF, np.int64)
        if work.original is not None:
            ext.uv[:] = work.original
    src, bary = corner_sources(res, nF)
    faces = np.flatnonzero((src >= 0).all(axis=1))
    ext.uv[faces] = prep.source.signal.uv_at(src[faces].ravel(), bary[faces].reshape(-1, 3)).reshape(-1, 3, 2)
    ext.material[faces] = k + 1


def texture_blend(prep: Prepared, r: Synthesized, ex, *, blend: str | None = None):
    """The :class:`.bake.Blend` of the texture of ``r`` on ``prep.target``: the full-resolution source
    texture through the patches, feathered over ``ex.feather`` patch radii and corrected to the
    vertex values of ``blend`` (default ``ex.blend``; none: neither)."""
    blend = ex.blend if blend is None else blend
    nearest = ex.sampling == "nearest"
    t = prep.target
    sharp = Signal("texture", uv=prep.source.signal.uv, texture=prep.texture)
    read = lambda f, b: sharp.sample(f, b, nearest=nearest)  # noqa: E731
    if blend == "none":
        return feathered(t.V, t.F, r.patch_of, r.corner_uv, r.patches, 0.0, read)
    corner = corner_values(r, prep.source, len(t.F))
    vals = vertex_values(t.F, corner, t.areas, len(t.V), blend=blend, V=t.V)
    return feathered(t.V, t.F, r.patch_of, r.corner_uv, r.patches, ex.feather * prep.radius, read,
                     smooth=prep.source.signal.sample, blended=vals)


def bake_texture(ext: Extracted, k: int, prep: Prepared, res: Synthesized, layout: Layout, ex) -> None:
    """Pair ``k``'s blended texture (:func:`texture_blend`) baked into an atlas over the work mesh's
    faces (refined faces read through the synthesis face they came from)."""
    tex = texture_blend(prep, res, ex)
    local = np.full(int(layout.origin.max()) + 1, -1, np.int64)
    local[prep.target.face_ids] = np.arange(len(prep.target.face_ids))
    mine = layout.result(k, res)

    def colour(faces, bary):
        s = local[layout.origin[faces]]
        uv = np.einsum("nk,nkc->nc", bary, layout.uv[faces])
        return tex.colour(s, barycentric(res.corner_uv[s], uv[:, None])[:, 0])

    atlas = bake(mine.corner_uv, mine.patch_of, colour, texel_size(prep.source) * prep.scale)
    faces = np.flatnonzero(mine.patch_of >= 0)
    ext.uv[faces] = atlas.uv[faces]
    ext.atlases[k] = atlas.image


def extract(pairs, ex, work: WorkMesh, layout: Layout, preps, results) -> Extracted:
    """The output's values over ``work`` from each pair's ``results``: positions, colours, attributes,
    patch ids, texture corners and baked atlases (``pairs``: ``transfer.pairs``; ``ex``:
    ``transfer.extraction``)."""
    mesh = work.mesh
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    nV, original = len(V), work.colors
    ext = Extracted(V.copy(), np.full((nV, 3), 0.75) if original is None else original.copy(), {},
                    np.full(len(F), -1, np.int64))
    areas, offset = face_areas(V, F), 0
    for k, (pair, prep, (res, _)) in enumerate(zip(pairs, preps, results, strict=True)):
        mine = layout.result(k, res)
        cov = mine.patch_of >= 0
        ext.patch_ids[cov] = mine.patch_of[cov] + offset
        offset += len(res.patches)
        if pair.signal == "texture":
            texture_corners(ext, work, k, prep, mine)
        if pair.signal == "displacement":
            frame = SimpleNamespace(V=V, F=F, N=face_normals(V, F))
            corner = transfer_displacement(mine, frame, prep.source, prep.source.signal.values[..., :3],
                                           scale=pair.scale)
        else:
            corner = corner_values(mine, prep.source, len(F), nearest=ex.sampling == "nearest")
        vals = vertex_values(F, corner, areas, nV, blend=ex.blend, V=V)
        ids = np.flatnonzero(np.isfinite(vals[:, 0]))
        if pair.signal == "displacement":
            ext.positions[ids] += vals[ids]
        elif pair.signal == "attribute":
            ext.attributes.setdefault(pair.attribute, np.zeros((nV, vals.shape[1])))[ids] = vals[ids]
        else:
            new = np.clip(vals[ids], 0, 1)
            if original is not None and ex.blend != "none":
                border = border_vertices(F, np.flatnonzero(layout.pair == k), nV)[ids]
                new[border] = 0.5 * (new[border] + original[ids[border]])
            ext.colors[ids] = new
            if pair.signal == "texture" and ex.blend != "none":
                bake_texture(ext, k, prep, res, layout, ex)
    return ext
