"""ARAP image deformation guided by a symmetry objective (theta_deform, paper Sec. 4 Example 2).

Control points: up to ``N`` Harris corners of the luminance, spaced at least ``d = sqrt(H W / N) / 2``
apart, then filled up to ``N`` by dart throwing (uniform darts from the run's generator, rejected
when closer than ``d``); the four image corners and border points every ``2 d`` are added as mesh
vertices so the Delaunay mesh covers the image. The warp is a backward map (each rest vertex
samples the input at ``U_i``; see :class:`synthkit.core.warp.MeshSampler`), kept as rigid as
possible by :class:`synthkit.core.warp.ARAP2D` with the control points as handles.

Hierarchy: control points ordered by farthest-point sampling; level ``l`` of ``L`` uses the first
``N / 2^(L-1-l)`` of them (at least 4). At each level, starting at step ``s`` (5 px at the coarsest,
halved per finer level), every handle in turn estimates the gradient of the loss by central
differences of size ``step`` and moves ``step`` along it when that lowers the loss; cycles repeat
until none moves (or ``max_cycles``), then the step halves until it falls below ``min_step``.

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
:func:`run_deform`).

Where real photographs contradict the paper (issue 14, README tables):

- E_symm favours magnification and blur: a smoother image has a broader S_T, whose variance is
  larger. Unbounded, the warp zoomed into a brick wall (texture_bricks) and bent its courses,
  keeping 0.71 of its high-frequency energy. Hence the stretch bound (``tile.max_stretch`` 1.1,
  ``deform.max_stretch`` 1.25) and, for tiles, the refusal of moves whose render loses 10 % of
  the high frequencies; the result is rendered with Lanczos, as bilinear reads at sub-pixel
  shifts keep 0.34-0.5 of them.
- The blend lowers E_symm where the input's borders disagree in brightness: its correction is a
  smooth field over the whole tile (0.035 rms on texture_bricks, a quarter of the photo's
  contrast) and the blended input's E_symm is 16 % below the photo's (aerial rocks 27 %). A cut
  through an overlap of the borders leaves less to correct: on texture_bricks the 16 px cut tile
  keeps E_symm (+21 %) at a seam ratio of 0.27 (the blend's 0.41), on the aerial rocks the 8 px
  one (+8 %) at 0.235 (the blend's 0.240). The toroidal E_symm of a cut tile depends on how the
  pattern wraps at its size, hence several overlaps (``tile.cut_overlaps``).
- The seam ratio rewards smoothness: on diagonal stripes (lattice-p3-21) the baseline's 0.12
  comes from the blend smearing mismatched stripes into a grey band, while the optimized tile,
  whose stripes continue across the seams, scores 0.33 (a seam like the interior scores 1).
- The paper's S_T is that of a toroidal ``f`` (eq. 2). A photograph whose period does not divide
  its size is irregular across the wrap, so symmetrization by the toroidal E_symm of the whole
  image warps even an unwarped photograph of stripes (E_symm x2.9 for 2.2 px of mean
  displacement). Symmetrize therefore evaluates S_T of the input's centred crop to a whole number
  of periods (``symmetry.crop: auto``): the stripes then move 0.86 px, and 0.34 px when every
  move must buy 1 % of E_symm (``deform.min_gain``'s default for symmetrize, which also keeps
  the unwarped cars and skimage's brick within 0.65 and 0.68 px on seed 0, not on every
  seed). The ``overlap`` S_T
  (:func:`synthkit.core.symmetry.translational`) has no wrap but moves them 1.29 px. Neither
  removes half of a known warp on the cars or the brick walls, nor do a Hann-apodized signal,
  Lanczos probes or E_L2 to the input's sharpened S_T (the paper's Fig. 5a):
  each objective is higher somewhere other than at the unwarped photograph (README tables).
"""

from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import scipy.linalg

from synthkit.core import symmetry as sy
from synthkit.core.tiling import cut_tile, fix_seams, seam_masks
from synthkit.core.warp import (
    ARAP2D,
    MeshSampler,
    displacement_gradient,
    mean_value_coordinates,
    mvc_interpolate,
    triangle_stretch,
)
from synthkit.methods.symtex.common import build_objective, build_targets

log = logging.getLogger("synthkit")


def control_points(img: np.ndarray, n: int, rng) -> np.ndarray:
    """Control points ``(k, 2)`` as (x, y): Harris corners then dart throwing, up to ``n``.

    Dart throwing stops after ``30 n`` darts; when the image is too small for ``n`` points spaced
    ``d`` apart, fewer are returned and a warning is logged (the pipeline records the count in
    ``metrics.control_points``).
    """
    lum = sy.f_lum(np.asarray(img, dtype=np.float32))
    H, W = lum.shape
    d = max(2.0, np.sqrt(H * W / n) / 2.0)
    corners = cv2.goodFeaturesToTrack(
        lum, maxCorners=n, qualityLevel=0.01, minDistance=d, useHarrisDetector=True, k=0.04
    )
    pts = [] if corners is None else [tuple(p) for p in corners.reshape(-1, 2).astype(np.float64)]
    pts = [p for p in pts if d <= p[0] <= W - 1 - d and d <= p[1] <= H - 1 - d]
    arr = np.array(pts, dtype=np.float64).reshape(-1, 2)
    attempts = 0
    while len(arr) < n and attempts < 30 * n:
        attempts += 1
        p = np.array([rng.uniform(d, W - 1 - d), rng.uniform(d, H - 1 - d)])
        if len(arr) == 0 or np.min(np.hypot(*(arr - p).T)) >= d:
            arr = np.vstack([arr, p])
    if len(arr) < n:
        log.warning(
            "only %d of %d control points fit a %dx%d image at spacing %.1f px after %d darts (deform.points)",
            len(arr),
            n,
            H,
            W,
            d,
            attempts,
        )
    return arr


def border_points(shape, spacing: float) -> np.ndarray:
    """Image corners and border points ``(k, 2)`` (x, y) about ``spacing`` apart."""
    H, W = shape
    xs = np.linspace(0, W - 1, max(2, int(round((W - 1) / spacing)) + 1))
    ys = np.linspace(0, H - 1, max(2, int(round((H - 1) / spacing)) + 1))
    pts = [(x, 0.0) for x in xs] + [(x, H - 1.0) for x in xs]
    pts += [(0.0, y) for y in ys[1:-1]] + [(W - 1.0, y) for y in ys[1:-1]]
    return np.array(pts, dtype=np.float64)


def farthest_order(P: np.ndarray) -> np.ndarray:
    """Farthest-point ordering ``(k,)`` of points ``P (k, 2)``, starting at the one nearest their mean."""
    order = [int(np.argmin(np.hypot(*(P - P.mean(axis=0)).T)))]
    dist = np.hypot(*(P - P[order[0]]).T)
    for _ in range(len(P) - 1):
        nxt = int(np.argmax(dist))
        order.append(nxt)
        dist = np.minimum(dist, np.hypot(*(P - P[nxt]).T))
    return np.array(order, dtype=np.int64)


_PROBE_POOL: ThreadPoolExecutor | None = None


def _probe_pool() -> ThreadPoolExecutor:
    """Two threads shared by every optimizer's gradient probes (one on a one-core machine)."""
    global _PROBE_POOL
    if _PROBE_POOL is None:
        _PROBE_POOL = ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1))
    return _PROBE_POOL


class DeformOptimizer:
    """Coarse-to-fine per-handle descent of ``loss(warped image)`` over ARAP warps.

    ``loss`` maps an image ``(H, W[, C])`` to a float to minimize. ``U0 (n, 2)`` is the starting
    backward map (identity or the tile zoom) and the shape the warp is kept as rigid as possible
    against, so the zoom itself costs nothing: with the handles where ``U0`` puts them, the ARAP
    solve returns ``U0``. Each level starts from the ARAP solve of its own handles at their current
    positions (the state its probes perturb). Evaluations are counted in ``evaluations``.

    ``out_shape`` is the rendered image's ``(H, W)`` (default ``img``'s): a tile smaller than the
    input is read from inside it. A move is taken only when it lowers the loss by more than
    ``min_gain`` times its magnitude (a relative threshold: moves that buy a gain within the
    evaluation noise only add warp), and, with ``max_stretch``, only when no triangle of the warp
    is stretched by more than that against ``U0`` (:func:`synthkit.core.warp.triangle_stretch`);
    ``rejected_stretch`` counts the moves that bound refused. ``accept(U) -> bool``, when given, is
    a further condition on every move (mode ``tile``: the Lanczos render keeps
    ``SHARPNESS_MIN`` of the input's high-frequency energy); ``rejected_accept`` counts its
    refusals. With ``max_gradient``, a move is also refused when the displacement from ``U0`` has
    a larger gradient on some triangle (:func:`synthkit.core.warp.displacement_gradient`: pattern
    elements stay in their rows); ``rejected_gradient`` counts those refusals.
    """

    def __init__(
        self,
        img,
        loss,
        *,
        rest,
        U0,
        n_control,
        levels,
        step,
        min_step,
        max_cycles,
        max_evaluations,
        border="reflect",
        progress=None,
        out_shape=None,
        max_stretch=None,
        min_gain=0.0,
        accept=None,
        max_gradient=None,
    ):
        self.img = np.asarray(img, dtype=np.float32)
        self.loss = loss
        self.sampler = MeshSampler(rest, self.img.shape[:2] if out_shape is None else tuple(out_shape))
        self.F = self.sampler.F
        self.rest = rest
        self.U0 = np.asarray(U0, dtype=np.float64).copy()
        self.U = self.U0.copy()
        self.n_control = n_control
        self.levels, self.step, self.min_step = levels, step, min_step
        self.max_cycles, self.max_evaluations = max_cycles, max_evaluations
        self.border = border
        self.progress = progress
        self.max_stretch = max_stretch
        self.min_gain = float(min_gain)
        self.rejected_stretch = 0
        self.accept = accept
        self.rejected_accept = 0
        self.max_gradient = max_gradient
        self.rejected_gradient = 0
        self.evaluations = 0
        self.history: list[float] = []

    def _allowed(self, U) -> bool:
        if self.max_stretch is not None and self.stretch(U) > self.max_stretch:
            self.rejected_stretch += 1
            return False
        if self.max_gradient is not None and self.gradient(U) > self.max_gradient:
            self.rejected_gradient += 1
            return False
        if self.accept is not None and not self.accept(U):
            self.rejected_accept += 1
            return False
        return True

    def gradient(self, U=None) -> float:
        """Largest displacement gradient of ``U`` (default the current warp) from ``U0``."""
        return float(displacement_gradient(self.rest, self.U0, self.U if U is None else U, self.F).max())

    def stretch(self, U=None) -> float:
        """Largest triangle stretch of ``U`` (default the current warp) against ``U0``."""
        return float(triangle_stretch(self.U0, self.U if U is None else U, self.F).max())

    def render(self, U=None) -> np.ndarray:
        return self.sampler.warp(self.img, self.U if U is None else U, border=self.border)

    def _eval(self, solver, H):
        self.evaluations += 1
        U = solver.solve(H)
        return self.loss(self.render(U)), U

    def _gradient(self, solver, Hpos: np.ndarray, h: int, step: float) -> np.ndarray:
        """Central-difference gradient ``(2,)`` of the loss in handle ``h``'s position: its four
        probes (``+-step`` along x and y) are independent and run on two threads (the FFTs, the
        resampling and the compiled loops release the GIL); the values do not depend on it."""
        trials = []
        for axis in range(2):
            for sgn in (1.0, -1.0):
                trial = Hpos.copy()
                trial[h, axis] += sgn * step
                trials.append(trial)
        vals = list(_probe_pool().map(lambda t: self.loss(self.render(solver.solve(t))), trials))
        self.evaluations += len(trials)
        return np.array([vals[0] - vals[1], vals[2] - vals[3]]) / (2 * step)

    def run(self) -> np.ndarray:
        order = farthest_order(self.rest[: self.n_control])
        current = self.loss(self.render())
        self.history.append(current)
        budget_left = lambda: self.evaluations < self.max_evaluations  # noqa: E731
        for level in range(self.levels):
            k = max(4, self.n_control // 2 ** (self.levels - 1 - level))
            handles = order[: min(k, self.n_control)]
            solver = ARAP2D(self.U0, self.F, handles)
            Hpos = self.U[handles].copy()
            if level > 0:
                # the finer level's parametrization: its handles where the coarser level left them
                val, U = self._eval(solver, Hpos)
                if self._allowed(U):
                    current, self.U = val, U
                # else keep the coarser warp: the finer solve of the same handles breaks a bound
                self.history.append(current)
            step = self.step / 2**level
            while step >= self.min_step and budget_left():
                for _ in range(self.max_cycles):
                    moved = 0
                    it = range(len(handles))
                    if self.progress is not None:
                        it = self.progress(it, total=len(handles), desc=f"ARAP level {level} step {step:g}")
                    for h in it:
                        if not budget_left():
                            break
                        grad = self._gradient(solver, Hpos, h, step)
                        g = np.hypot(*grad)
                        if g <= 0:
                            continue
                        trial = Hpos.copy()
                        trial[h] -= step * grad / g
                        val, U = self._eval(solver, trial)
                        if val < current - self.min_gain * abs(current):
                            if not self._allowed(U):
                                continue
                            current, Hpos, self.U = val, trial, U
                            moved += 1
                    self.history.append(current)
                    if moved == 0 or not budget_left():
                        break
                step /= 2.0
        return self.render()


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


def run_deform(cfg, ctx, src, tgt):
    """Run ``perturbation: deform`` for transfer / filter / symmetrize / tile.

    ``tile``: with ``tile.optimize`` (default off: :func:`_run_tile_unoptimized`), the optimized
    tile (``tile.zoom: crop``, the default, a native-resolution crop of
    the centre that the warp may pull the margin into; ``upsample``, the paper's zoom to the
    input's size) is blended toroidally, and so is the untouched input (the baseline); a cut tile
    per ``tile.cut_overlaps`` entry is cut from the input (``cut<overlap>``). The returned
    ``result.png`` is, of these and the input itself, the one :func:`choose_tile` picks: the
    lowest seam ratio among those meeting every goal of issue 14 (``metrics.tile_choice`` names
    it, ``metrics.tile_candidates`` holds the figures of all).

    Returns ``(image, sample_map, tiles, objective, targets)``: the result, the backward map
    ``(H, W, 2) float32`` (None for a tile without the optimization), the tiles by name (mode
    tile; else empty), the objective and the E_L2 targets (or None). Figures go to ``ctx.metrics``.
    """
    if cfg.mode == "tile" and not cfg.tile.optimize:
        return _run_tile_unoptimized(cfg, ctx, src)
    dc = cfg.deform
    H, W = src.shape[:2]
    out_shape = (H, W)
    offset = np.zeros(2)
    crop = cfg.mode == "tile" and cfg.tile.zoom == "crop"
    if crop:
        out_shape, (oy, ox) = tile_crop(src.shape, cfg.tile.margin)
        offset = np.array([ox, oy], dtype=np.float64)
    h, w = out_shape
    with ctx.stage("target"):
        targets = build_targets(cfg, src, tgt, out_shape)
        objective = build_objective(cfg, out_shape, targets, source=src)
    with ctx.stage("mesh"):
        view = src[int(offset[1]) : int(offset[1]) + h, int(offset[0]) : int(offset[0]) + w]
        ctrl = control_points(view, dc.points, ctx.rng)
        spacing = max(4.0, np.sqrt(h * w / dc.points))
        rest = np.vstack([ctrl, border_points(out_shape, spacing)])
        U0 = rest + offset
        if cfg.mode == "tile" and not crop:
            m = cfg.tile.margin
            c = np.array([(W - 1) / 2.0, (H - 1) / 2.0])
            U0 = c + (rest - c) * (1.0 - 2.0 * m)
    # f_lum and f_1-lum are linear in the colour channels and bilinear sampling commutes with
    # them, so the optimizer may warp the one-channel luminance instead of the colour image
    pointwise = set(cfg.symmetry.signals) <= {"lum", "1-lum"}
    opt = DeformOptimizer(
        sy.f_lum(src) if pointwise else src,
        objective.loss,
        rest=rest,
        U0=U0,
        n_control=len(ctrl),
        levels=dc.levels,
        step=dc.step,
        min_step=dc.min_step,
        max_cycles=dc.max_cycles,
        max_evaluations=dc.max_evaluations,
        progress=ctx.progress,
        out_shape=out_shape,
        max_stretch=cfg.tile.max_stretch if cfg.mode == "tile" else dc.max_stretch,
        min_gain=cfg.resolved_min_gain(),
        max_gradient=dc.max_gradient if cfg.mode == "symmetrize" else None,
    )
    interp = dc.interpolation
    # sharpness reference of the optimized tile: the part of the input it is cut from (the whole
    # input when upsampled); a photo's high frequencies vary across it (texture_bricks' 154 px
    # centre has 0.83 of its 256 px crop's), so the whole input would be an unfair reference
    hf_view = high_frequency_energy(view if crop else src)
    start_img = opt.sampler.warp(src, U0, interpolation=interp)
    if cfg.mode == "tile":
        # upsample: the zoom itself keeps ~0.3 of the high frequencies; moves may not lose more
        # than 10 % of what the zoomed start has (such a tile is never returned: see choose_tile)
        lum = sy.f_lum(src)
        floor = SHARPNESS_MIN * (hf_view if crop else high_frequency_energy(start_img))
        opt.accept = lambda U: high_frequency_energy(opt.sampler.warp(lum, U, interpolation=interp)) >= floor
    with ctx.stage("optimize"):
        opt.run()
        image = opt.sampler.warp(src, opt.U, interpolation=interp)
    start = objective.value(start_img)
    end = objective.value(image)
    mx, my = opt.sampler.coords(opt.U)
    mx0, my0 = opt.sampler.coords(U0)
    moved = np.hypot(mx - mx0, my - my0)
    metrics = {
        "objective": "E_L2" if objective.kind == "l2" else "E_symm",
        "objective_start": start,
        "objective_end": end,
        "baseline_objective": objective.value(src),
        "iterations": opt.evaluations,
        "control_points": len(ctrl),
        "control_points_requested": dc.points,
        "objective_history": [abs(v) for v in opt.history],
        "mean_displacement": float(moved.mean()),
        "max_displacement": float(moved.max()),
        "max_stretch": opt.stretch(),
        "max_stretch_bound": opt.max_stretch,
        "moves_rejected_by_stretch": opt.rejected_stretch,
        "moves_rejected_by_sharpness": opt.rejected_accept,
        "moves_rejected_by_gradient": opt.rejected_gradient,
        "max_displacement_gradient": opt.gradient(),
        "symmetry_crop": None if objective.crop is None else list(objective.crop),
        "min_gain": opt.min_gain,
    }
    tiles = None
    if cfg.mode == "tile":
        image, tiles = _tile_result(cfg, ctx, src, image, objective, hf_view, metrics)
    if cfg.mode == "symmetrize":
        reason = symmetrize_refusal(metrics, dc.max_gradient)
        metrics["status"] = "input returned" if reason else "symmetrized"
        metrics["status_reason"] = reason
        if reason:
            log.warning("symmetrize: %s: returned the input unchanged (%s)", cfg.source, reason)
            image, mx, my = src, mx0, my0
            for key in ("objective_end", "mean_displacement", "max_displacement", "max_displacement_gradient"):
                metrics[f"refused_{key}"] = metrics[key]
            metrics.update(
                objective_end=metrics["baseline_objective"],
                mean_displacement=0.0,
                max_displacement=0.0,
                max_displacement_gradient=0.0,
            )
    ctx.metrics.update(metrics)
    return image, np.stack([mx, my], axis=2).astype(np.float32), tiles or {}, objective, targets


def symmetrize_refusal(metrics: dict, max_gradient: float | None) -> str | None:
    """Why mode ``symmetrize`` returns the input instead of the deformed image, or None (issue 24).

    The deformed image is kept only when its E_symm (``metrics.objective_end``, the rendered
    colour result) is above the input's (``baseline_objective``) by more than ``min_gain`` of it
    (the share each move must buy) and, with ``max_gradient``, its displacement's gradient
    (``max_displacement_gradient``) is within it. The optimizer refuses moves that break either,
    but its probes are bilinear renders of the luminance, while the result is a Lanczos render of
    the colour image: E_symm of the two differ by about a percent (the unwarped grid lattice-p4:
    the probes +3%, the result -1.2%).
    """
    end, start = metrics["objective_end"], metrics["baseline_objective"]
    floor = start * (1.0 + metrics["min_gain"])
    if not end > floor:
        gain = (end / start - 1.0) * 100.0 if start > 0 else 0.0
        return (
            f"E_symm {end:.4g} of the deformed image is {gain:+.2f}% of the input's {start:.4g}, "
            f"not above it by deform.min_gain {metrics['min_gain']:g}"
        )
    grad = metrics["max_displacement_gradient"]
    if max_gradient is not None and grad > max_gradient:
        return f"the displacement's gradient {grad:.3g} exceeds deform.max_gradient {max_gradient:g}"
    return None


def _run_tile_unoptimized(cfg, ctx, src):
    """Mode ``tile`` without the paper's optimization (``tile.optimize: false``, the default): the
    blended input and the cut tiles are compared with the input as :func:`choose_tile` does, in
    seconds (issue 24: the optimized tile was returned on none of 4 photographs and took minutes).
    E_symm is that of the same objective as with the optimization (window of the tile crop)."""
    out_shape, _ = tile_crop(src.shape, cfg.tile.margin)
    with ctx.stage("target"):
        objective = build_objective(cfg, out_shape, None, source=src)
    start = objective.value(src)
    metrics = {
        "objective": "E_symm",
        "objective_start": start,
        "objective_end": start,
        "iterations": 0,
        "tile_optimized": False,
    }
    image, tiles = _tile_result(cfg, ctx, src, None, objective, None, metrics)
    ctx.metrics.update(metrics)
    return image, None, tiles, objective, None


def _tile_result(cfg, ctx, src, image, objective, hf_view: float | None, metrics: dict):
    """Blend the warped tile (``image``; None without the optimization) and the input toroidally,
    cut the input's cut tiles, and return ``(result, tiles)``: the result chosen by
    :func:`choose_tile` and every candidate image by name; the figures of every candidate go to
    ``metrics``."""
    tc = cfg.tile
    tiles, candidates = {}, {}
    hf_input = high_frequency_energy(src)
    if image is not None:
        with ctx.stage("blend"):
            tiles["optimized"] = toroidal_blend(image, spacing=tc.mvc_spacing)
        candidates["optimized"] = _tile_candidate(tiles["optimized"], objective, hf_view, metrics["max_stretch"])
    overlaps = _cut_overlaps(tc.cut_overlaps, src.shape)
    bar = ctx.progress(total=1 + len(overlaps), desc="tile candidates")
    with ctx.stage("baseline"):
        tiles["baseline"] = toroidal_blend(src, spacing=tc.mvc_spacing)
    bar.update()
    tiles["input"] = src
    input_objective = objective.value(src)
    candidates["baseline"] = _tile_candidate(tiles["baseline"], objective, hf_input, 1.0)
    candidates["input"] = _tile_candidate(src, objective, hf_input, 1.0)
    for ov in overlaps:
        with ctx.stage("cut"):
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


def _cut_overlaps(overlaps, shape) -> list[int]:
    """The distinct ``overlaps`` below half of an input of ``shape``, ascending; a warning names the others."""
    fit = sorted({int(ov) for ov in overlaps if 2 * int(ov) < min(shape[:2])})
    if len(fit) < len(set(overlaps)):
        log.warning(
            "tile.cut_overlaps: %s px do not fit the %dx%d input (at most half its size); no cut tile for them",
            sorted(set(overlaps) - set(fit)),
            *shape[:2],
        )
    return fit

