"""The tile candidates of mode ``tile`` and the figures they are chosen by.

Tiling (mode ``tile``): the tile is the centre of the input less ``margin`` of each side, at the
input's resolution (``tile.zoom: crop``; the paper zooms the centre to the input's size, which
upsamples by 1 / (1 - 2 margin) and blurs: ``zoom: upsample``); the deformation may pull the
margin in (only with ``tile.optimize: true``; by default the candidates below are compared
without it). After optimizing E_symm of the toroidal S_T, :func:`toroidal_blend` makes the image
periodic with period ``(H, W)``: the wrap-around step between opposite borders is targeted to an
interior-like step and the border corrections are spread into the interior by mean value
coordinates. The baseline (paper Fig. 7, top rows) is the same blend of the untouched input,
without symmetry optimization. The cut tiles are not optimized either: the input's opposite
borders overlapped by each of ``tile.cut_overlaps`` px and joined by minimum-error boundary cuts,
each step across the cuts then made interior-like (:mod:`synthkit.core.tiling`); their seams are
measured where their copies meet. :func:`choose_tile` returns one of them or the input (see
:func:`tile_result`).

What the seam ratio and E_symm showed on real photographs: docs/findings/symmetry-texture.md.
"""

from __future__ import annotations

import contextlib
import logging

import cv2
import numpy as np
import scipy.linalg

from synthkit.core import symmetry as sy
from synthkit.core.tiling import cut_tile, fix_seams, seam_masks
from synthkit.core.warp import mean_value_coordinates, mvc_interpolate
from synthkit.methods.symtex.options import TileOptions

log = logging.getLogger("synthkit")


def _untimed(name: str):
    return contextlib.nullcontext()


def _silent(iterable=None, *, total=None, desc=""):
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, disable=True)


def _border_polygon(H: int, W: int, spacing: int) -> np.ndarray:
    """Border pixels ``(n, 2)`` (x, y) every ``spacing`` px, in order around the rectangle (corners included)."""
    xs = np.arange(0, W - 1, spacing)
    ys = np.arange(0, H - 1, spacing)
    return np.concatenate(
        [
            np.stack([xs, np.zeros_like(xs)], 1),
            np.stack([np.full_like(ys, W - 1), ys], 1),
            np.stack([W - 1 - xs, np.full_like(xs, H - 1)], 1),
            np.stack([np.zeros_like(ys), H - 1 - ys], 1),
        ]
    ).astype(np.float64)


def _linear_matrix(pos: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Weights ``(len(pos), len(nodes))`` of 1-D linear interpolation at ``pos`` between ``nodes``."""
    j = np.clip(np.searchsorted(nodes, pos, side="right") - 1, 0, len(nodes) - 2)
    t = (pos - nodes[j]) / (nodes[j + 1] - nodes[j])
    M = np.zeros((len(pos), len(nodes)))
    M[np.arange(len(pos)), j] = 1.0 - t
    M[np.arange(len(pos)), j + 1] = t
    return M


def _spread(c: np.ndarray, shape, poly: np.ndarray, band: int, step: int) -> np.ndarray:
    """MVC interpolation ``(H, W, C)`` of the vertex values ``c (n, C)`` of ``poly`` over the image.

    Exact within ``band`` px of the border, where the interpolant carries the corrections' fine
    detail; farther in, where it is smooth, MVC is evaluated on a grid every ``step`` px and
    interpolated bilinearly (the adaptive evaluation of Farbman et al. 2009's MVC cloning).
    """
    H, W = shape
    out = np.zeros((H, W, c.shape[1]))
    if min(H, W) <= 2 * band + step:
        band = (min(H, W) + 1) // 2
    mask = np.zeros((H, W), dtype=bool)
    mask[:band], mask[H - band :], mask[:, :band], mask[:, W - band :] = True, True, True, True
    yy, xx = np.nonzero(mask)
    out[yy, xx] = mvc_interpolate(np.stack([xx, yy], 1).astype(np.float64), poly, c)
    if H - 2 * band > 0 and W - 2 * band > 0:
        ys = np.linspace(band - 1, H - band, int(np.ceil((H - 2 * band + 1) / step)) + 1)
        xs = np.linspace(band - 1, W - band, int(np.ceil((W - 2 * band + 1) / step)) + 1)
        gy, gx = np.meshgrid(ys, xs, indexing="ij")
        grid = mvc_interpolate(np.stack([gx.ravel(), gy.ravel()], 1), poly, c).reshape(len(ys), len(xs), -1)
        Ry = _linear_matrix(np.arange(band, H - band, dtype=np.float64), ys)
        Rx = _linear_matrix(np.arange(band, W - band, dtype=np.float64), xs)
        # Ry grid Rx^T per channel, as two matrix products (a three-operand einsum is a slow loop)
        rows = np.tensordot(Ry, grid, axes=(1, 0))  # (h, nx, C)
        out[band : H - band, band : W - band] = np.einsum("jx,ixc->ijc", Rx, rows, optimize=True)
    return out


def _min_norm_lstsq(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Least-squares solution of smallest norm of ``A x = r`` by Cholesky of the normal equations
    (``A^T (A A^T)^-1 r`` when ``A`` is wide). When they are singular (the corner constraints of a
    blend with a vertex every pixel are dependent: one zero eigenvalue, the next 2.0 of 10 on a
    640x480 photo), ``1e-10`` of their mean diagonal is added (Tikhonov): the solution moves by
    about 1e-10 of itself, where an SVD of ``A`` took seconds."""
    wide = A.shape[0] <= A.shape[1]
    G = A @ A.T if wide else A.T @ A
    try:
        fac = scipy.linalg.cho_factor(G)
    except np.linalg.LinAlgError:
        G[np.diag_indices_from(G)] += 1e-10 * float(np.trace(G)) / len(G)
        fac = scipy.linalg.cho_factor(G)
    return A.T @ scipy.linalg.cho_solve(fac, r) if wide else scipy.linalg.cho_solve(fac, A.T @ r)


def toroidal_blend(img: np.ndarray, *, spacing: int = 1, band: int = 8, step: int = 4) -> np.ndarray:
    """Make ``img (H, W[, C])`` periodic with period ``(H, W)`` by MVC interpolation of a border correction.

    In the tiling, column ``W-1`` is followed by column ``0`` (and row ``H-1`` by row ``0``), so the
    wrap-around step ``v[:, 0] - v[:, W-1]`` should look like an interior step: it is targeted to
    the local derivative estimated from the two neighbouring interior steps,
    ``(v[:, W-1] - v[:, W-2] + v[:, 1] - v[:, 0]) / 2``, and likewise for the rows. The correction
    is given at border vertices every ``spacing`` px around the rectangle and spread over the image
    by mean value coordinates (border pixels between vertices interpolate linearly), so every
    constraint, which reads the border and the first interior lines, is linear in the vertex
    corrections; they are the least-squares solution of smallest norm. With ``spacing`` 1 there are
    about twice as many unknowns as constraints and every constraint holds exactly: each mismatch
    is split evenly between both sides of the seam, and the four corners, which enter a row and a
    column constraint each, take one consistent correction. See :func:`_spread` for ``band`` and
    ``step``. The result is clipped to [0, 1].
    """
    arr = np.asarray(img, dtype=np.float64)
    H, W = arr.shape[:2]
    if min(H, W) < 4:
        raise ValueError(f"toroidal_blend needs an image of at least 4x4, got {H}x{W}")
    flat = arr.reshape(H, W, -1)
    poly = _border_polygon(H, W, max(1, int(spacing)))
    y, x = np.arange(H, dtype=np.float64), np.arange(W, dtype=np.float64)

    def col(j):
        return mean_value_coordinates(np.stack([np.full(H, float(j)), y], 1), poly)

    def row(i):
        return mean_value_coordinates(np.stack([x, np.full(W, float(i))], 1), poly)

    # 1.5 v[0] - 1.5 v[-1] + 0.5 v[-2] - 0.5 v[1] = 0 along each seam
    coef = (1.5, -1.5, 0.5, -0.5)
    A = np.vstack(
        [
            sum(k * col(j) for k, j in zip(coef, (0, W - 1, W - 2, 1), strict=True)),
            sum(k * row(i) for k, i in zip(coef, (0, H - 1, H - 2, 1), strict=True)),
        ]
    )
    r = -np.vstack(
        [
            sum(k * flat[:, j] for k, j in zip(coef, (0, W - 1, W - 2, 1), strict=True)),
            sum(k * flat[i] for k, i in zip(coef, (0, H - 1, H - 2, 1), strict=True)),
        ]
    )
    c = _min_norm_lstsq(A, r)
    out = flat + _spread(c, (H, W), poly, max(2, band), max(1, step))
    return np.clip(out.reshape(arr.shape), 0.0, 1.0).astype(np.float32)


def seam_energies(img: np.ndarray, *, width: int = 0, seams=None) -> tuple[float, float]:
    """Mean squared luminance step across the toroidal seams, and over the interior.

    The seam steps are the wrap-around ones (column ``W-1`` to ``0``, row ``H-1`` to ``0``), or,
    given ``seams = (mx, my)`` (``(H, W) bool``: the step from ``(y, x)`` to ``(y, x + 1)`` resp.
    ``(y + 1, x)``, wrapping, is a seam; :func:`synthkit.core.tiling.seam_masks`), those; with
    ``width`` > 0 also the ``width`` steps on either side of each seam step along its line (a band
    that shows a discontinuity merely moved off the seam); the interior steps are all the others.
    Each direction is averaged on its own and the two means averaged.
    """
    lum = sy.f_lum(np.asarray(img, dtype=np.float32)).astype(np.float64)
    dx = (np.roll(lum, -1, axis=1) - lum) ** 2  # dx[:, j]: j -> j+1, the last wraps
    dy = (np.roll(lum, -1, axis=0) - lum) ** 2
    if seams is None:
        mx, my = np.zeros(lum.shape, dtype=bool), np.zeros(lum.shape, dtype=bool)
        mx[:, -1], my[-1] = True, True
    else:
        mx, my = (np.asarray(m, dtype=bool) for m in seams)
    bx = np.any([np.roll(mx, k, axis=1) for k in range(-width, width + 1)], axis=0)
    by = np.any([np.roll(my, k, axis=0) for k in range(-width, width + 1)], axis=0)
    seam = 0.5 * (dx[bx].mean() + dy[by].mean())
    interior = 0.5 * (dx[~bx].mean() + dy[~by].mean())
    return float(seam), float(interior)


def seam_ratio(img: np.ndarray, *, width: int = 0, seams=None) -> float:
    """Seam over interior gradient energy of the toroidal tiling of ``img`` (see :func:`seam_energies`)."""
    seam, interior = seam_energies(img, width=width, seams=seams)
    return float(seam / max(interior, 1e-12))


def high_frequency_energy(img: np.ndarray, *, sigma: float = 1.0) -> float:
    """Mean squared high-pass luminance of ``img (H, W[, C])``: ``lum - gaussian(lum, sigma)``.

    The sharpness measure of mode ``tile``: a result's value over the input's is its
    ``sharpness`` (1 for the input itself; a bilinear half-pixel shift or a 1/0.6 upsampling
    takes it well below 0.9).
    """
    lum = sy.f_lum(np.asarray(img, dtype=np.float32)).astype(np.float64)
    low = cv2.GaussianBlur(lum, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    return float(np.mean((lum - low) ** 2))


def tile_crop(shape, margin: float) -> tuple[tuple[int, int], tuple[int, int]]:
    """Native-resolution tile inside an image of ``shape (H, W)``: its ``(h, w)`` and offset ``(oy, ox)``.

    The tile is the centre of the image less ``round(margin * H)`` rows and ``round(margin * W)``
    columns on each side (at least 4 px each way), read at the input's own pixel spacing: the
    warp may pull the margin in, and with no warp the tile is an exact crop.
    """
    H, W = shape[:2]
    oy, ox = int(round(margin * H)), int(round(margin * W))
    h, w = H - 2 * oy, W - 2 * ox
    if min(h, w) < 4:
        raise ValueError(f"tile.margin {margin} leaves a {h}x{w} tile of the {H}x{W} input")
    return (h, w), (oy, ox)


def _tile_candidate(image, objective, hf_reference, stretch, seams=None) -> dict:
    return {
        "seam_ratio": seam_ratio(image, seams=seams),
        "seam_band_ratio": seam_ratio(image, width=3, seams=seams),
        "objective": objective.value(image),
        "sharpness": high_frequency_energy(image) / max(hf_reference, 1e-20),
        "max_stretch": stretch,
        "size": list(image.shape[:2]),
    }


def tile_order(name: str) -> tuple[int, int]:
    """Sort key of a candidate of mode ``tile``: ``optimized``, the cut tiles ``cut<overlap>`` by
    overlap, ``baseline``, ``input``; a tie in seam ratio goes to the earlier one."""
    if name.startswith("cut"):
        return 1, int(name[3:])
    return {"optimized": 0, "baseline": 2, "input": 3}[name], 0


def choose_tile(candidates: dict, input_objective: float) -> str:
    """Name of the candidate returned by mode ``tile`` (see :func:`tile_order`).

    Issue 14's goals for the returned tile: a seam ratio at most the baseline's (the input
    blended) and the input's, E_symm not below the input's (``input_objective``, less
    ``E_SYMM_TOL``) and ``SHARPNESS_MIN`` of its high-frequency energy. Of the candidates that
    meet all of them, the one with the lowest seam ratio; when none does, the lowest seam ratio
    of the baseline, the input and those made candidates (``optimized``, the cut tiles) that keep
    E_symm and sharpness (the baseline is then returned when it tiles better than the input: the
    E_symm goal is missed and ``metrics.tile_choice`` says so). Ties go by :func:`tile_order`.
    """
    floor = input_objective * (1.0 - E_SYMM_TOL)
    bound = min(candidates["baseline"]["seam_ratio"], candidates["input"]["seam_ratio"])

    def keeps(c):
        return c["objective"] >= floor and c["sharpness"] >= SHARPNESS_MIN

    pool = [k for k, c in candidates.items() if keeps(c) and c["seam_ratio"] <= bound]
    if not pool:
        pool = [k for k, c in candidates.items() if k in ("baseline", "input") or keeps(c)]
    return min(pool, key=lambda k: (candidates[k]["seam_ratio"], tile_order(k)))


E_SYMM_TOL = 1e-3
"""E_symm within this share below the input's counts as not below it: the blend's smooth border
correction alone moves it by 5e-4 on lattice-p4, a grid that already tiles."""

SHARPNESS_MIN = 0.9
"""A tile keeps at least this share of the input's high-frequency energy (issue 14)."""


def tile_result(src: np.ndarray, image: np.ndarray | None, objective, tc: TileOptions, hf_view: float | None,
                metrics: dict, *, progress=None, stage=None):
    """Blend the warped tile (``image``; None without the optimization) and the input ``src``
    toroidally, cut the input's cut tiles, and return ``(result, tiles)``: the result chosen by
    :func:`choose_tile` and every candidate image by name; the figures of every candidate go to
    ``metrics`` (which holds the warp's figures: ``max_stretch``, ``objective_end``).
    ``stage(name)`` times a step (a context manager), ``progress(total=, desc=)`` a tqdm bar."""
    stage = stage or _untimed
    tiles, candidates = {}, {}
    hf_input = high_frequency_energy(src)
    if image is not None:
        with stage("blend"):
            tiles["optimized"] = toroidal_blend(image, spacing=tc.mvc_spacing)
        candidates["optimized"] = _tile_candidate(tiles["optimized"], objective, hf_view, metrics["max_stretch"])
    overlaps = cut_overlaps(tc.cut_overlaps, src.shape)
    bar = (progress or _silent)(total=1 + len(overlaps), desc="tile candidates")
    with stage("baseline"):
        tiles["baseline"] = toroidal_blend(src, spacing=tc.mvc_spacing)
    bar.update()
    tiles["input"] = src
    input_objective = objective.value(src)
    candidates["baseline"] = _tile_candidate(tiles["baseline"], objective, hf_input, 1.0)
    candidates["input"] = _tile_candidate(src, objective, hf_input, 1.0)
    for ov in overlaps:
        with stage("cut"):
            cut, source = cut_tile(src, ov)
            tiles[f"cut{ov}"] = fix_seams(cut, source, radius=ov // 2)
        candidates[f"cut{ov}"] = _tile_candidate(tiles[f"cut{ov}"], objective, hf_input, 1.0, seams=seam_masks(source))
        bar.update()
    bar.close()
    choice = choose_tile(candidates, input_objective)
    result = tiles[choice]
    chosen = candidates[choice]
    if image is not None:
        metrics.update(
            objective_warped=metrics["objective_end"],
            objective_optimized=candidates["optimized"]["objective"],
            optimized_seam_ratio=candidates["optimized"]["seam_ratio"],
        )
    metrics.update(
        objective_end=chosen["objective"],
        baseline_objective=candidates["baseline"]["objective"],
        input_objective=input_objective,
        seam_ratio=chosen["seam_ratio"],
        seam_band_ratio=chosen["seam_band_ratio"],
        seam_ratio_input=candidates["input"]["seam_ratio"],
        baseline_seam_ratio=candidates["baseline"]["seam_ratio"],
        sharpness=chosen["sharpness"],
        tile_choice=choice,
        tile_candidates=candidates,
        tile_size=list(result.shape[:2]),
    )
    return result, tiles


def cut_overlaps(overlaps, shape) -> list[int]:
    """The distinct ``overlaps`` below half of an input of ``shape``, ascending; a warning names the others."""
    fit = sorted({int(ov) for ov in overlaps if 2 * int(ov) < min(shape[:2])})
    if len(fit) < len(set(overlaps)):
        log.warning(
            "tile.cut_overlaps: %s px do not fit the %dx%d input (at most half its size); no cut tile for them",
            sorted(set(overlaps) - set(fit)),
            *shape[:2],
        )
    return fit

