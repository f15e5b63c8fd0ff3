"""The texture stage of ``synthkit reshape`` (``texture: reshape`` or ``continue``; section 4 of
Cabral et al.), over the scene's arrays and :class:`~synthkit.methods.reshape.options.TextureOptions`.

For each piece, each textured surface (a surface whose material has a texture: the ``map_Kd`` its
MTL names, or the image of a mesh given in memory) whose world edge lengths changed is reshaped by
:func:`texture.surface.reshape_surface`; a surface whose edges kept their lengths (every ratio
within ``UNCHANGED_TOL`` of 1, or no texture-space edge that would move by ``unchanged_texels``,
half a texel by default: the least squares geometry solve changes every edge a little) keeps its
UVs and material, so its texture comes back unchanged. Each texture is analysed once
(:func:`texture.surface.analyse_texture`), in the order surfaces first use it, so the tile seeds
drawn from the run's ``rng`` are the same for a given seed.

Errors are :class:`KeyedError` (a ValueError) naming the file and the surface, and carrying the
config ``key`` a value of which is at fault: a grid spacing below one texel
(``texture_reshape.spacing``), a bake over ``texture_reshape.max_side``; None when the input is: a
textured surface without UVs, UVs spanning a whole tile on a texture that is not toroidal, a
failed reshape. Pieces whose textures are not given (a GLB's are embedded) keep the naive stretch.
"""

from __future__ import annotations

import hashlib
import logging
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from synthkit.errors import KeyedError
from synthkit.methods.reshape.handles import PieceRange
from synthkit.methods.reshape.options import TextureOptions
from synthkit.methods.reshape.texture.atlas import pack_atlas, to_atlas
from synthkit.methods.reshape.texture.extend import extend_surface, extend_tiled, patch_mask
from synthkit.methods.reshape.texture.surface import analyse_texture, reshape_surface
from synthkit.methods.reshape.textured import Retexture, TexturedMesh

__all__ = ["SurfaceJob", "surface_jobs", "reshape_jobs", "atlas_entries", "texture_metrics",
           "check_uv", "safe_name", "UNCHANGED_TOL", "WORST"]

log = logging.getLogger("synthkit")

UNCHANGED_TOL = 1e-9
"""A surface whose edge length ratios all lie within this of 1 is untouched."""

MIN_UV_AREA = 16.0
"""Texels a surface's UVs must cover to get a deformation grid."""

WHOLE_TILE_SLACK = 1e-2
"""UVs spanning a tile plus at most this (share of a tile) still read as one tile, clamped."""

WORST = {"grid_nodes": max, "equations": max, "factor_ms": max, "solve_ms": max, "bake_ms": max,
         "rigid_scale_error": max, "stochastic_stretch": max, "detail_energy_ratio": min, "tiles": min,
         "baseline_rigid_scale_error": max, "baseline_detail_energy_ratio": min}
"""Per-surface metrics and how their worst case over surfaces is taken (report top level)."""


@dataclass
class SurfaceJob:
    """One changed textured surface: its name, piece, faces ``(k,)`` (piece-local), render vertices
    ``(c,)`` (piece-local), material, texture path, corners ``C (c, 2)`` texels, triangles ``F (k, 3)``
    and contour ``segments (S, 2)`` over them, edge length ratios (callable), toroidal flag and the
    corners' world positions before ``P0 (c, 3)`` and after ``P1 (c, 3)``."""

    name: str
    piece: int
    faces: np.ndarray
    vertices: np.ndarray
    material: str
    texture: object
    C: np.ndarray
    F: np.ndarray
    segments: np.ndarray
    ratio: object
    toroidal: bool
    P0: np.ndarray
    P1: np.ndarray


def _contour(F: np.ndarray) -> np.ndarray:
    """Edges ``(S, 2)`` used by exactly one triangle of ``F (k, 3)``, oriented as in their triangle."""
    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(he, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return he[counts[inv.reshape(-1)] == 1]


def check_uv(source, name, material, path, UV, toroidal) -> tuple[bool, np.ndarray]:
    """Whether the surface ``name`` of the mesh read from ``source`` is toroidal, and its UVs
    ``(c, 2)`` as read. With ``toroidal`` "auto" a surface is toroidal only when its UVs leave
    [0, 1] and span more than a whole tile (plus :data:`WHOLE_TILE_SLACK`) along an axis; otherwise
    they are moved by whole tiles into [0, 1] (by the tile holding their centre) and a small
    excursion past [0, 1] is clamped (house atlases have UVs 0.14 texel outside). A ``material``
    listed in ``toroidal`` is toroidal whatever its UVs. KeyedError for missing UVs, or for UVs
    spanning a whole tile when ``toroidal`` lists other materials only."""
    if np.isnan(UV).any():
        raise KeyedError(None, f"{source}: surface {name} (material {material}) has no UVs, but its texture "
                               f"{path.name} needs them")
    outside = bool(((UV < -1e-9) | (UV > 1 + 1e-9)).any())
    whole = outside and bool((np.ptp(UV, axis=0) > 1 + WHOLE_TILE_SLACK).any())
    toroidal = whole if toroidal == "auto" else material in toroidal
    if toroidal:
        return True, UV
    if whole:
        lo, hi = UV.min(axis=0), UV.max(axis=0)
        raise KeyedError(None, f"{source}: surface {name} (material {material}) has UVs spanning a whole tile "
                               f"(u {lo[0]:.4g}..{hi[0]:.4g}, v {lo[1]:.4g}..{hi[1]:.4g}) but texture {path.name} "
                               "is not toroidal (texture_reshape.toroidal)")
    shift = np.floor(0.5 * (UV.min(axis=0) + UV.max(axis=0)))
    return False, np.clip(UV - shift, 0.0, 1.0)


def _ratio(a, b, i, j) -> np.ndarray:
    """Edge length ratios ``(m,)`` new/old of edges ``(i, j)`` between rows of ``a``, ``b`` ``(c, 3)``
    (1 for an edge of zero rest length)."""
    rest = np.linalg.norm(a[i] - a[j], axis=1)
    new = np.linalg.norm(b[i] - b[j], axis=1)
    return np.divide(new, rest, out=np.ones_like(rest), where=rest > 1e-12)


def _degenerate(C, F) -> str | None:
    """Why the texture-space triangles ``F`` over ``C (c, 2)`` (texels) cannot carry a grid, or None:
    less than MIN_UV_AREA texels in all, or folded (triangles of both orientations, as mirrored
    atlas patches have)."""
    d1, d2 = C[F[:, 1]] - C[F[:, 0]], C[F[:, 2]] - C[F[:, 0]]
    area = 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    if np.abs(area).sum() < MIN_UV_AREA:
        return f"its UVs cover {np.abs(area).sum():.3g} texels (fewer than {MIN_UV_AREA:g})"
    big = np.abs(area) > 1e-9 * np.abs(area).max()
    if (area[big] > 0).any() and (area[big] < 0).any():
        return "its UVs are folded (triangles of both orientations)"
    return None


def _texture(path, images, read, spacing: float) -> tuple[int, int]:
    """``(W, H)`` of the texture at ``path`` (``read(path)`` once into ``images``); KeyedError on
    ``texture_reshape.spacing`` when the grid spacing is below one of its texels."""
    if path not in images:
        images[path] = read(path)
    H, W = images[path].shape[:2]
    if spacing * min(H, W) < 1:
        raise KeyedError("texture_reshape.spacing",
                         f"{spacing:g} of {path.name} ({W} x {H}) is {spacing * min(H, W):.3g} texels, below one texel")
    return W, H


@dataclass
class _Piece:
    """What :func:`_piece_jobs` reads of one piece: its index, mesh, render vertices in the scene
    (``r``), first face in the scene and material -> texture path."""

    index: int
    mesh: TexturedMesh
    r: PieceRange
    fstart: int
    textures: dict


def _piece_jobs(piece: _Piece, face_surface, V0, V1, options: TextureOptions, read, images,
                skipped) -> tuple[list[SurfaceJob], int]:
    """The changed textured surfaces of one piece and the number of its textured surfaces left
    untouched (no texture-space edge would move by ``unchanged_texels``); surfaces whose UVs cannot
    carry a grid go into ``skipped`` (name -> reason) and keep the naive stretch."""
    jobs, untouched = [], 0
    mesh, r = piece.mesh, piece.r
    Fp = mesh.F
    surf = face_surface[piece.fstart:piece.fstart + len(Fp)]
    for k, s in enumerate(np.unique(surf)):
        faces = np.flatnonzero(surf == s)
        material = mesh.materials[int(mesh.face_material[faces[0]])]
        path = piece.textures.get(material)
        if path is None:
            continue
        verts = np.unique(Fp[faces])
        Fl = np.searchsorted(verts, Fp[faces])
        a, b = (V0[r.start + verts], V1[r.start + verts])
        e = np.vstack([Fl[:, [0, 1]], Fl[:, [1, 2]], Fl[:, [2, 0]]])
        change = np.abs(_ratio(a, b, e[:, 0], e[:, 1]) - 1)
        if change.max() <= UNCHANGED_TOL:
            untouched += 1
            continue
        name = f"{r.name}.{material}.{k}"
        toroidal, UV = check_uv(mesh.source, name, material, path, mesh.UV[verts], options.toroidal)
        W, H = _texture(path, images, read, options.params.spacing)
        C = np.column_stack([UV[:, 0] * W, (1.0 - UV[:, 1]) * H])
        if (change * np.linalg.norm(C[e[:, 0]] - C[e[:, 1]], axis=1)).max() < options.unchanged_texels:
            untouched += 1
            continue
        reason = _degenerate(C, Fl)
        if reason:
            skipped[name] = reason
            log.warning("%s: surface %s keeps the naive stretch: %s", mesh.source, name, reason)
            continue
        seg = _contour(Fl)
        seg = seg[np.linalg.norm(C[seg[:, 1]] - C[seg[:, 0]], axis=1) > 1e-9]  # duplicated corners
        jobs.append(SurfaceJob(name, piece.index, faces, verts, material, path, C, Fl, seg,
                               lambda i, j, a=a, b=b: _ratio(a, b, i, j), toroidal, a, b))
    return jobs, untouched


def surface_jobs(meshes: list[TexturedMesh], textures: list[dict | None], ranges: list[PieceRange],
                 face_surface: np.ndarray, V0: np.ndarray, V1: np.ndarray, *, options: TextureOptions,
                 read: Callable[[Path], np.ndarray], images: dict, skipped: dict) -> tuple[list[SurfaceJob], int]:
    """Every changed textured surface of the scene's pieces ``meshes`` (render vertices ``ranges``
    of the scene's ``V0 (#V, 3)`` before and ``V1 (#V, 3)`` after, faces in order, surface of each
    face ``face_surface (#F,)``), with per piece material -> texture path (None: textures that
    stay as they are), and the number of untouched textured surfaces. ``images`` (path -> texture,
    ``read(path)`` on first use) is filled as read, ``skipped`` (surface -> reason) with the
    surfaces that keep the naive stretch."""
    jobs, fstart, untouched = [], 0, 0
    for p, (mesh, found, r) in enumerate(zip(meshes, textures, ranges, strict=True)):
        if found is not None:
            piece = _Piece(p, mesh, r, fstart, found)
            more, kept = _piece_jobs(piece, face_surface, V0, V1, options, read, images, skipped)
            jobs += more
            untouched += kept
        fstart += len(mesh.F)
    return jobs, untouched


def safe_name(name: str) -> str:
    """``name`` with every run of characters other than letters, digits, ``_.-`` replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def reshape_jobs(jobs, images, rng, *, options: TextureOptions) -> dict:
    """Run every job: per surface name ``(job, result, analysis)``. With ``texture: continue`` a
    non-toroidal surface whose map is affine is extended (:func:`texture.extend.extend_surface`,
    analysis None), the others take the paper's reshape. A surface mapping the same
    texels as an earlier one, stretched alike (front and back walls of the houses share their atlas
    patch), shares its result. A stage ValueError becomes a KeyedError naming the surface."""
    params, analyses, results, done = options.params, {}, {}, {}
    for job in jobs:
        same = _job_key(job)
        if same in done:
            results[job.name] = (job, *results[done[same]][1:])
            continue
        done[same] = job.name
        if options.mode == "continue":
            img = images[job.texture]
            ext = (extend_tiled(job.C, job.F, job.P0, job.P1, img.shape) if job.toroidal
                   else extend_surface(img, job.C, job.F, job.P0, job.P1, rng))
            if ext is not None:
                results[job.name] = (job, ext, None)
                continue
        key = (job.texture, job.toroidal)
        if key not in analyses:
            analyses[key] = analyse_texture(images[job.texture], wrap=job.toroidal, params=params, rng=rng)
        try:
            res = reshape_surface(job.C, job.F, job.segments, job.ratio, analyses[key], toroidal=job.toroidal,
                                  params=params, rng=rng)
        except ValueError as exc:
            if "max_side" in str(exc):
                raise KeyedError("texture_reshape.max_side", f"surface {job.name}: {exc}") from None
            raise KeyedError(None, f"{job.texture}: surface {job.name}: texture reshape failed: {exc}") from None
        results[job.name] = (job, res, analyses[key])
    return results


def _job_key(job) -> tuple:
    """What makes two jobs bake the same patch: texture, wrap, texel corners, triangles and the
    edge length ratios (rounded to 1e-6)."""
    e = np.vstack([job.F[:, [0, 1]], job.F[:, [1, 2]], job.F[:, [2, 0]]])
    ratio = np.round(job.ratio(e[:, 0], e[:, 1]), 6)
    return (job.texture, job.toroidal, np.round(job.C, 6).tobytes(), job.F.tobytes(), ratio.tobytes())


def _own_entry(job, res) -> Retexture:
    """A surface written with its own material and PNG named by its surface number (toroidal: its
    UVs repeat the baked tile)."""
    UV = np.zeros((int(job.vertices.max()) + 1, 2))
    UV[job.vertices] = res.UV
    material = safe_name(f"{job.material}_retex{job.name.rsplit('.', 1)[1]}")
    return Retexture(job.faces, UV, material, f"{material}.png", res.texture)


def _untouched_faces(mesh, material, done, taken) -> np.ndarray:
    """Faces of ``material`` not reshaped (``done``), with UVs in [0, 1] and no render vertex in
    ``taken (#V,) bool``: they move into the atlas's source area."""
    faces = np.setdiff1d(np.flatnonzero(mesh.face_material == mesh.materials.index(material)), done)
    uv = mesh.UV[mesh.F[faces]]
    ok = np.all(np.isfinite(uv) & (uv >= -1e-9) & (uv <= 1 + 1e-9), axis=(1, 2)) & ~taken[mesh.F[faces]].any(axis=1)
    return faces[ok]


def _source_in_use(mesh, faces, shape) -> np.ndarray:
    """``(H, W) bool``: the texels of a texture of ``shape`` that the ``faces`` of ``mesh`` map,
    grown by two texels (bilinear sampling at their edges reads them)."""
    H, W = shape[:2]
    C = np.column_stack([mesh.UV[:, 0] * W, (1.0 - mesh.UV[:, 1]) * H])
    used = patch_mask(C, mesh.F[faces], shape, erode=False).astype(np.uint8)
    return cv2.dilate(used, np.ones((5, 5), np.uint8)).astype(bool)


def _content(img: np.ndarray) -> tuple:
    """Key of an image's content: equal patches (a roof's front and back slopes) are packed once."""
    return img.shape, hashlib.sha256(np.ascontiguousarray(img).tobytes()).hexdigest()


def _material_atlas(mesh, material, items, source) -> tuple[Retexture, list, dict]:
    """One input material's atlas: the Retexture of its packed and untouched faces, the entries of
    surfaces that keep their own PNG (sharing a render vertex with one already packed) and per
    packed surface its atlas box. Source texels no untouched face maps are black (they compress);
equal patches are packed once."""
    res_of = {_content(res.texture): res for _, _, res in items}
    taken, faces, own = np.zeros(len(mesh.V), bool), [], []
    packed = []
    for name, job, res in items:
        if taken[job.vertices].any():
            own.append(_own_entry(job, res))
            continue
        taken[job.vertices] = True
        faces.append(job.faces)
        packed.append((name, job, res))
    rest = _untouched_faces(mesh, material, np.concatenate(faces), taken)
    source = np.where(_source_in_use(mesh, rest, source.shape)[..., None], source, 0).astype(source.dtype)
    atlas, spot0, spots = pack_atlas(source, [r.texture for r in res_of.values()])
    slot = {key: spots[i] for i, key in enumerate(res_of)}
    UV, boxes, file = np.zeros((len(mesh.V), 2)), {}, f"{safe_name(material)}_atlas.png"
    for name, job, res in packed:
        spot = slot[_content(res.texture)]
        UV[job.vertices] = to_atlas(res.UV, spot, atlas.shape)
        boxes[name] = ([spot.x, spot.y, spot.w, spot.h], file)
    corners = np.unique(mesh.F[rest])
    UV[corners] = to_atlas(mesh.UV[corners], spot0, atlas.shape)
    return Retexture(np.concatenate(faces + [rest]), UV, file[:-4], file, atlas), own, boxes


def atlas_entries(meshes: list[TexturedMesh], results, images) -> tuple[dict, dict]:
    """The Retexture entries per piece index of ``meshes``: per (piece, input material) one atlas (the source, its
    texels no untouched face maps black, and every non-toroidal reshaped surface's patch,
    :func:`texture.atlas.pack_atlas`) holding
    the material's reshaped and untouched faces; toroidal surfaces continued by their UVs share one
    copy of their tile per material (``<material>_tiled``); other toroidal surfaces (and a surface
    sharing a render vertex with one already packed) keep their own PNG. Also per surface name its ``[x, y, w, h]``
    box in its atlas (texels) and the atlas file."""
    entries, boxes, groups = {}, {}, {}
    tiled = {}
    for name, (job, res, _) in results.items():
        if job.toroidal and res.texture is None:
            tiled.setdefault((job.piece, job.material), []).append((job, res))
        elif job.toroidal:
            entries.setdefault(job.piece, []).append(_own_entry(job, res))
        else:
            groups.setdefault((job.piece, job.material), []).append((name, job, res))
    for (p, material), items in groups.items():
        entry, own, placed = _material_atlas(meshes[p], material, items, images[items[0][1].texture])
        entries.setdefault(p, []).extend(own + [entry])
        boxes.update(placed)
    for (p, material), items in tiled.items():
        UV = np.zeros((len(meshes[p].V), 2))
        for job, res in items:
            UV[job.vertices] = res.UV
        file = f"{safe_name(material)}_tiled.png"
        entries.setdefault(p, []).append(Retexture(np.concatenate([job.faces for job, _ in items]), UV, file[:-4],
                                                   file, images[items[0][0].texture]))
    return entries, boxes


def texture_metrics(results: dict, notes: dict, untouched: int, skipped: dict, boxes: dict) -> dict:
    """``surfaces`` (name -> metrics, with its ``atlas`` file and ``atlas_box`` [x, y, w, h] when
    packed) and the worst case of each :data:`WORST` metric."""
    surfaces = {}
    for name, (job, res, _) in results.items():
        m = dict(res.metrics)
        m["grid_nodes"] = m.pop("nodes", None)
        m.update(material=job.material, texture=job.texture.name, toroidal=job.toroidal)
        if name in boxes:
            m["atlas_box"], m["atlas"] = boxes[name]
        surfaces[name] = m
    out = {"surfaces": surfaces, "texture_surfaces": len(surfaces), "texture_notes": notes,
           "texture_untouched_surfaces": untouched, "texture_skipped": skipped}
    for key, pick in WORST.items():
        vals = [m[key] for m in surfaces.values() if m.get(key) is not None]
        top = key if key in ("rigid_scale_error", "stochastic_stretch", "detail_energy_ratio", "tiles",
                             "baseline_rigid_scale_error", "baseline_detail_energy_ratio") else f"texture_{key}"
        out[top] = pick(vals) if vals else None
    return out
