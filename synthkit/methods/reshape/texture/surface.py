"""One textured surface through the texture reshape (Cabral et al. 2009, section 4).

:func:`analyse_texture` runs the per-texture stages once (an atlas shared by many surfaces is
analysed once): luminance equalization, directional autosimilarity (eq. 9), the rigid/stochastic
cut, the tile map (used by toroidal surfaces; other surfaces grow their tiles inside their own
polygon), the bilateral base/detail split. :func:`reshape_surface` runs the
per-surface stages: corner solve, toroidal repetitions, deformation grid, interior solve,
distortion map, stretch, bake, and the naive stretch for comparison, and measures both.

Texel coordinates as in :mod:`synthkit.methods.reshape.texture`. A toroidal surface (its UVs
leave [0, 1], the texture repeats) is reshaped tile-wise (4.4): the grid covers one tile, the
solved corners' bounding box sets an integer number of repetitions per axis, and the tile is
deformed by ``extent / repetitions`` with its opposite sides tied together.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from synthkit.methods.reshape.texture import autosim, bake, detail
from synthkit.methods.reshape.texture.grid import DeformationGrid, build_grid
from synthkit.methods.reshape.texture.solve import CornerSolver, InteriorSolver, edge_stiffness, toroidal_repetitions

__all__ = ["TextureParams", "TextureAnalysis", "SurfaceResult", "analyse_texture", "reshape_surface"]


@dataclass(frozen=True)
class TextureParams:
    """Parameters of section 4 (see the ``texture_reshape`` config section for each one's meaning)."""

    delta: int = 10
    neighbourhood: int = 5
    spacing: float = 1 / 32
    s_min: float = 0.01
    s_align: float = 1.0
    t_max: float | None = 0.4
    samples: int = 9
    corner_form: str = "contour"
    tau: float = 0.1
    smoothness: float = 20.0
    edge_sigma: float = 0.5
    tries: int = 8
    tile_search: str = "spiral"
    min_tile: int = 16
    regions: str = "connected"
    clusters: int = 3
    sigma_s: float = 3.0
    sigma_r: float = 0.2
    ramp: float = 0.25
    max_side: int = 4096
    backend: str = "auto"


@dataclass
class TextureAnalysis:
    """Per-texture stages: ``img (H, W, 3)``, equalized ``lum (H, W)``, ``T (2, H, W)`` (x, y),
    ``rigid (H, W) bool``, ``tile_ids (H, W) int32``, ``tiles (k + 1, 4)``, ``base`` and
    ``detail`` ``(H, W, 3)``, and the seconds each took (``timings``)."""

    img: np.ndarray
    wrap: bool
    lum: np.ndarray
    T: np.ndarray
    rigid: np.ndarray
    tile_ids: np.ndarray
    tiles: np.ndarray
    base: np.ndarray
    detail: np.ndarray
    timings: dict = field(default_factory=dict)


def analyse_texture(img, *, wrap: bool, params: TextureParams, rng) -> TextureAnalysis:
    """:class:`TextureAnalysis` of ``img (H, W, 3)`` in [0, 1]; ``rng`` seeds the tile growth."""
    t = {}
    start = time.perf_counter()
    lum = autosim.equalize_luminance(img)
    T = autosim.directional_autosimilarity(lum, delta=params.delta, size=params.neighbourhood, wrap=wrap)
    t["autosimilarity"] = time.perf_counter() - start
    start = time.perf_counter()
    rigid = detail.segment_rigid(T, lum, tau=params.tau, smoothness=params.smoothness, edge_sigma=params.edge_sigma)
    t["segmentation"] = time.perf_counter() - start
    start = time.perf_counter()
    ids, tiles = detail.tile_map(rigid, rng=rng, tries=params.tries, search=params.tile_search,
                                 min_side=params.min_tile)
    t["tiles"] = time.perf_counter() - start
    start = time.perf_counter()
    base, det = detail.base_detail(img, sigma_s=params.sigma_s, sigma_r=params.sigma_r)
    t["base_detail"] = time.perf_counter() - start
    return TextureAnalysis(np.asarray(img, np.float32), wrap, lum, T, rigid, ids, tiles, base, det, t)


@dataclass
class SurfaceResult:
    """A reshaped surface: new ``UV (c, 2)`` of its corners, the baked texture ``(Ho, Wo, 3)``, the
    naive stretch ``(Hn, Wn, 3)``, the grid (nodes in source texels) and its nodes ``Y (n, 2)`` in
    output texels, the metrics dict and the detail tiles ``(k + 1, 4)`` (source texels) it used."""

    UV: np.ndarray
    texture: np.ndarray
    naive: np.ndarray
    grid: DeformationGrid
    Y: np.ndarray
    metrics: dict
    tiles: np.ndarray


def _periodic_pairs(grid: DeformationGrid, size) -> np.ndarray:
    """``(p, 3)`` rows tying boundary nodes of opposite tile sides (left-right share y, top-bottom x)."""
    X, rows = grid.X, []
    for ax in range(2):
        lo = np.flatnonzero(np.abs(X[:, ax]) < 1e-6)
        hi = np.flatnonzero(np.abs(X[:, ax] - size[ax]) < 1e-6)
        other = 1 - ax
        for i in lo:
            j = hi[np.abs(X[hi, other] - X[i, other]) < 1e-6]
            if len(j) and 1e-6 < X[i, other] < size[other] - 1e-6:
                rows.append((i, int(j[0]), other))
    return np.asarray(rows, np.int64).reshape(-1, 3)


def _solve(C, F, segments, ratio, size, toroidal, tex: TextureAnalysis, p: TextureParams):
    """Corner solve, grid and interior solve: new corners ``Cn (c, 2)``, the grid, its nodes ``Y
    (n, 2)`` in output texels, the output shape ``(Ho, Wo)``, the per-tile scale ``(2,)`` (ones when
    not toroidal) and the solve figures."""
    cs = CornerSolver(C, F, segments, form=p.corner_form, backend=p.backend)
    Cn = cs.solve(ratio)
    reps, scale, per = None, np.ones(2), None
    if toroidal:
        reps, scale = toroidal_repetitions(C / size, Cn / size)
        W, H = size
        sq = np.array([[0, 0], [W, 0], [W, H], [0, H]], np.float64)
        grid = build_grid(sq, np.array([[0, 1], [1, 2], [2, 3], [3, 0]]), p.spacing * size)
        per, Cd = _periodic_pairs(grid, size), sq * scale
    else:
        order = np.unique(segments)  # the grid's corners are the contour's corners
        grid = build_grid(C[order], np.searchsorted(order, segments), p.spacing * size)
        Cd = Cn[order]
    stiff = edge_stiffness(tex.T, grid.X, grid.edges, s_min=p.s_min, s_align=p.s_align, samples=p.samples,
                           wrap=toroidal, t_max=p.t_max)
    isv = InteriorSolver(grid, stiff, periodic=per, backend=p.backend)
    Yd = isv.solve(Cd)
    if toroidal:
        shape = np.maximum(np.round(scale[::-1] * size[::-1]), 1).astype(int)
        Y = Yd * (shape[::-1] / (scale * size))
    else:
        off = _origin(Cn)
        shape = np.maximum(np.ceil(Cn.max(axis=0) - off - _SNAP), 1).astype(int)[::-1]
        Y = Yd - off
    info = dict(corner_equations=cs.equations, interior_equations=isv.equations, vars=isv.vars,
                corner_factor_ms=cs.factor_ms, interior_factor_ms=isv.factor_ms,
                corner_solve_ms=cs.solve_ms, interior_solve_ms=isv.solve_ms,
                repetitions=None if reps is None else reps.tolist())
    return Cn, grid, Y, tuple(int(v) for v in shape), scale, info


_SNAP = 1e-2
"""Solved corners this close (texels) to a texel boundary count as on it: the geometry's least
squares changes a kept edge by about 1e-6 of its length, which must not add a row of texels."""


def _origin(Cn) -> np.ndarray:
    """Texel origin ``(2,)`` of the baked texture of solved corners ``Cn (c, 2)``."""
    return np.floor(Cn.min(axis=0) + _SNAP)


def _new_uv(C, Cn, Y_shape, size, scale, toroidal) -> np.ndarray:
    """New UVs ``(c, 2)`` of the surface's corners on the baked texture."""
    if toroidal:
        Q = Cn / size / scale
        Q = Q - Q[0] + C[0] / size
        return np.column_stack([Q[:, 0], 1.0 - Q[:, 1]])
    Ho, Wo = Y_shape
    off = _origin(Cn)
    return np.column_stack([(Cn[:, 0] - off[0]) / Wo, 1.0 - (Cn[:, 1] - off[1]) / Ho])


def _texel_lookup(mask, uv, wrap):
    """``mask (H, W)`` read at the nearest texel of ``uv (Ho, Wo, 2)``."""
    return mask[_texel_index(uv.reshape(-1, 2), mask.shape, wrap)].reshape(uv.shape[:2])


def _measure(tex, tile_ids, dmap, J, out, energy_in, *, tau, stretched_at=1.25) -> dict:
    """Rigid scale error, stochastic stretch and detail energy ratio of one output whose triangles
    (``dmap.triangle`` per texel) have the Jacobians ``J (t, 2, 2)``.

    ``rigid_scale_error``: over the output texels whose source texel is rigid *in direction d*
    (``T_d > tau``: a plinth is rigid vertically, not along its length), the mean of ``|scale_d -
    1|``, ``scale_d`` the length of the image of a unit step along d. ``stochastic_stretch``: mean
    largest singular value over stochastic texels. ``detail_energy_ratio``: the Laplacian energy of
    the output's stochastic texels stretched at least ``stretched_at``, over the input's."""
    covered, tri = dmap.covered, dmap.triangle
    scale = np.linalg.norm(J, axis=1)  # (t, 2): |J e_d|
    errs = []
    for d in range(2):
        rigid_d = _texel_lookup(tex.rigid & (tex.T[d] > tau), dmap.uv, tex.wrap) & covered
        errs.append(np.abs(scale[:, d] - 1.0)[tri[rigid_d]])
    err = np.concatenate(errs)
    smax = np.linalg.svd(J, compute_uv=False)[:, 0][tri]
    stoch = (_texel_lookup(tile_ids, dmap.uv, tex.wrap) != 0) & covered
    region = stoch & (smax >= stretched_at)
    e_out = bake.laplacian_energy(out, region) if region.sum() > 16 else float("nan")
    return {"rigid_scale_error": float(err.mean()) if len(err) else 0.0,
            "stochastic_stretch": float(smax[stoch].mean()) if stoch.any() else None,
            "detail_energy_ratio": e_out / energy_in if np.isfinite(e_out) and energy_in > 0 else None}


def _naive(tex, C, Cn, F, size, toroidal):
    """The naive stretch (the texture follows the corners, as with unchanged UVs): its distortion
    map and singular values per texel; toroidal surfaces show one tile stretched by the full
    factor."""
    if toroidal:
        W, H = size
        full = (Cn.max(axis=0) - Cn.min(axis=0)) / np.maximum(C.max(axis=0) - C.min(axis=0), 1e-12)
        X = np.array([[0, 0], [W, 0], [W, H], [0, H]], np.float64)
        Xn, Fn = X * full, np.array([[0, 1, 2], [0, 2, 3]])
    else:
        X, Xn, Fn = C, Cn - _origin(Cn), F
    shape = tuple(int(v) for v in np.maximum(np.ceil(Xn.max(axis=0) - _SNAP), 1)[::-1])
    dm = bake.distortion_map(X, Xn, Fn, shape)
    return dm, bake.triangle_jacobians(X, Xn, Fn)


def _surface_tiles(tex: TextureAnalysis, grid: DeformationGrid, params: TextureParams, rng):
    """Tile map ``(H, W) int32`` and table ``(k + 1, 4)`` of the stochastic regions *inside this
    surface's texture-space polygon* (in an atlas, neighbouring patches' stochastic texels touch:
    docs/findings/reshape.md). The polygon is rasterized from the grid's triangles, and the regions
    are cut by its outline."""
    H, W = tex.rigid.shape
    lo = np.clip(np.floor(grid.X.min(axis=0)), 0, [W - 1, H - 1]).astype(int)
    hi = np.clip(np.ceil(grid.X.max(axis=0)), lo + 1, [W, H]).astype(int)
    X = grid.X - lo
    inside = bake.distortion_map(X, X, grid.triangles, (hi[1] - lo[1], hi[0] - lo[0])).covered
    stoch = inside & ~tex.rigid[lo[1]:hi[1], lo[0]:hi[0]]
    labels = None
    if params.regions == "split":
        labels = detail.split_regions(stoch, tex.lum[lo[1]:hi[1], lo[0]:hi[0]], clusters=params.clusters, rng=rng)
    ids_w, tiles = detail.tile_map(~stoch, rng=rng, tries=params.tries, search=params.tile_search,
                                   min_side=params.min_tile, labels=labels)
    ids = np.zeros((H, W), np.int32)
    ids[lo[1]:hi[1], lo[0]:hi[0]] = ids_w
    tiles[1:] += [lo[1], lo[0], lo[1], lo[0]]
    return ids, tiles


def reshape_surface(C, F, segments, ratio, tex: TextureAnalysis, *, toroidal: bool, params: TextureParams,
                    rng=None) -> SurfaceResult:
    """Reshape the texture of one surface with corners ``C (c, 2)`` (texels of ``tex.img``),
    triangles ``F (t, 3)`` and contour ``segments (S, 2)`` over them, for the world edge length
    ratios ``ratio`` (see :meth:`CornerSolver.solve`). ``rng`` seeds the surface's tile growth
    (:func:`_surface_tiles`; a toroidal surface uses the texture's own tile map). Raises
    ValueError when the output would exceed ``params.max_side`` texels or the grid is degenerate."""
    size = np.array(tex.img.shape[1::-1], np.float64)
    Cn, grid, Y, shape, scale, info = _solve(C, F, segments, ratio, size, toroidal, tex, params)
    if toroidal:
        tile_ids, tiles = tex.tile_ids, tex.tiles
    else:
        tile_ids, tiles = _surface_tiles(tex, grid, params, np.random.default_rng(rng))
    if max(shape) > params.max_side:
        raise ValueError(f"baked texture would be {shape[1]} x {shape[0]} texels (max_side {params.max_side})")
    start = time.perf_counter()
    dmap = bake.distortion_map(grid.X, Y, grid.triangles, shape)
    smax = bake.triangle_stretch(grid.X, Y, grid.triangles)[:, 0][dmap.triangle]
    amount = np.clip((smax - 1.0) / params.ramp, 0.0, 1.0)
    out = bake.bake(tex.base, tex.detail, tile_ids, tiles, dmap, amount, wrap=toroidal)
    bake_ms = 1e3 * (time.perf_counter() - start)
    reached = np.zeros(tex.rigid.shape, bool)
    reached[_texel_index(dmap.uv[dmap.covered], tex.rigid.shape, toroidal)] = True
    energy_in = bake.laplacian_energy(tex.img, reached & (tile_ids != 0))
    m = {**grid.counts, **info, "bake_ms": bake_ms, "texture_shape": list(shape),
         **_measure(tex, tile_ids, dmap, bake.triangle_jacobians(grid.X, Y, grid.triangles), out, energy_in,
                    tau=params.tau)}
    ndm, nJ = _naive(tex, C, Cn, F, size, toroidal)
    naive = np.clip(bake.remap(tex.img, ndm.uv, toroidal), 0, 1)
    base_m = _measure(tex, tile_ids, ndm, nJ, naive, energy_in, tau=params.tau)
    m.update(baseline_rigid_scale_error=base_m["rigid_scale_error"],
             baseline_detail_energy_ratio=base_m["detail_energy_ratio"],
             equations=info["corner_equations"] + info["interior_equations"],
             factor_ms=info["corner_factor_ms"] + info["interior_factor_ms"],
             solve_ms=info["corner_solve_ms"] + info["interior_solve_ms"],
             tiles=int(len(np.unique(tile_ids[reached & (tile_ids != 0)]))))
    return SurfaceResult(_new_uv(C, Cn, shape, size, scale, toroidal), out, naive, grid, Y, m, tiles)


def _texel_index(uv, shape, wrap):
    """Row and column ``(m,)`` arrays of the texels holding ``uv (m, 2)`` (wrapped or clamped)."""
    H, W = shape
    ix, iy = np.floor(uv[:, 0]).astype(np.int64), np.floor(uv[:, 1]).astype(np.int64)
    ix, iy = (ix % W, iy % H) if wrap else (np.clip(ix, 0, W - 1), np.clip(iy, 0, H - 1))
    return iy, ix
