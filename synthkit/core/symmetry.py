"""Symmetry representations of 2-D signals, their objectives and symmetry-space filters.

Kim, Lipman and Funkhouser 2012 ("Symmetry-guided texture synthesis and manipulation") describe an
image ``f (H, W) float`` by how similar it is to itself under every transformation of a group:

- :func:`translational` ``S_T`` (eq. 2): normalized autocorrelation over translations, by FFT,
  toroidal (circular) or zero-padded (linear), optionally limited to a window of displacements.
  The result is centred: ``S[wy + dy, wx + dx]`` is the value at displacement ``(dy, dx)``.
- :func:`rotational` ``S_R`` (eq. 3): correlation of ``f(r, phi)`` with ``f(r, phi + gamma)``
  about a centre, weighted by ``r``, from a polar resampling, one value per rotation ``gamma``.
- :func:`reflective`: correlation of ``f(r, phi)`` with ``f(r, 2 theta - phi)`` (the reflection
  across the line through the centre at angle ``theta``) for every ``theta`` in ``[0, pi)``.

Objectives :func:`e_l2` (eq. 1) and :func:`e_symm` (eq. 4); filters :func:`blur`,
:func:`sharpen`, :func:`contrast`, :func:`scale`, :func:`rotate`; input signals :func:`f_lum`,
:func:`f_inv_lum` (``f_1-lum``), :func:`f_edge`. The windowed toroidal autocorrelation kept up to
date under block changes is :class:`synthkit.core.autocorrelation.IncrementalAutocorrelation`.

Normalization. Every representation is first divided by ``||f||^2`` (eq. 2, "raw", ``S(0) = 1``
for ``S_T``); ``standardize=True`` then shifts and scales it to mean 0 and variance 1 over its
domain (the paper's normalization for comparing representations of different images). E_symm is
the variance, so it is measured on the raw representation (a standardized one has variance 1 by
construction). The signal's mean is not subtracted, as in eq. 2; for the toroidal transform this
changes the raw values by a constant only, so the standardized ``S_T`` does not depend on it.

Constant signals have no symmetry representation (the standardized values are 0/0): every
transform raises ``ValueError`` for them.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy import ndimage

from synthkit.core.tol import tol

__all__ = [
    "f_lum",
    "f_inv_lum",
    "f_edge",
    "signal",
    "translational",
    "rotational",
    "reflective",
    "polar_resample",
    "standardize",
    "e_l2",
    "e_symm",
    "blur",
    "sharpen",
    "contrast",
    "scale",
    "rotate",
    "strongest_peak",
    "check_signal",
]

LUMA = np.array([0.299, 0.587, 0.114])
"""Rec. 601 luma weights used by :func:`f_lum`."""



# ---------------------------------------------------------------------------------------------
# input signals


def f_lum(img: np.ndarray) -> np.ndarray:
    """Luminance ``(H, W)`` of ``img (H, W)`` or ``(H, W, 3|4)`` in [0, 1] (Rec. 601 weights).

    Keeps float32 input float32; everything else becomes float64.
    """
    img = np.asarray(img)
    dtype = np.float32 if img.dtype == np.float32 else np.float64
    if img.ndim == 2:
        return img.astype(dtype, copy=False)
    if img.ndim == 3 and img.shape[2] in (1, 3, 4):
        if img.shape[2] == 1:
            return img[..., 0].astype(dtype, copy=False)
        return (img[..., :3] @ LUMA.astype(dtype)).astype(dtype, copy=False)
    raise ValueError(f"image must be (H, W) or (H, W, 1|3|4), got shape {img.shape}")


def f_inv_lum(img: np.ndarray) -> np.ndarray:
    """Inverted luminance ``1 - f_lum(img)``, ``(H, W)`` (the paper's ``f_1-lum``)."""
    return 1.0 - f_lum(img)


def f_edge(img: np.ndarray) -> np.ndarray:
    """Edge signal ``(H, W)``: Sobel gradient magnitude of the luminance, scaled to max 1.

    The paper's "output of the edge detector" is unspecified; a Sobel magnitude keeps the signal
    continuous (a binary Canny map would make the objective piecewise constant under warping).
    """
    lum = f_lum(img)
    gy = ndimage.sobel(lum, axis=0, mode="reflect")
    gx = ndimage.sobel(lum, axis=1, mode="reflect")
    mag = np.hypot(gx, gy)
    peak = mag.max()
    return mag / peak if peak > 0 else mag


_SIGNALS = {"lum": f_lum, "1-lum": f_inv_lum, "edge": f_edge}


def signal(img: np.ndarray, kind: str) -> np.ndarray:
    """Input signal ``(H, W)`` named ``kind``: ``"lum"``, ``"1-lum"`` or ``"edge"``."""
    if kind not in _SIGNALS:
        raise ValueError(f"unknown signal {kind!r} (one of {', '.join(_SIGNALS)})")
    return _SIGNALS[kind](img)


# ---------------------------------------------------------------------------------------------
# translational symmetry transform


def check_signal(f: np.ndarray) -> np.ndarray:
    f = np.asarray(f)
    if f.ndim != 2 or f.shape[0] < 2 or f.shape[1] < 2:
        raise ValueError(f"signal must be a 2-D array of at least 2x2, got shape {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("signal holds NaN or infinite values")
    if float(np.ptp(f)) <= tol.constant:
        raise ValueError("signal is constant: its symmetry representation is undefined")
    return f


def standardize(S: np.ndarray) -> np.ndarray:
    """``(S - mean) / std`` over all entries; ValueError when ``S`` is constant."""
    S = np.asarray(S)
    mu = S.mean()
    sd = S.std()
    if not sd > tol.constant * max(1.0, abs(float(mu))):
        raise ValueError("symmetry representation is constant: cannot standardize")
    return (S - mu) / sd


_standardized = standardize  # reachable where a parameter named ``standardize`` shadows it


def _window_of(shape: tuple[int, int], window, mode: str) -> tuple[int, int]:
    H, W = shape
    full = ((H - 1) // 2, (W - 1) // 2) if mode == "toroidal" else (H - 1, W - 1)
    if window is None:
        return full
    if np.isscalar(window):
        window = (window, window)
    wy, wx = (int(v) for v in window)
    if wy < 0 or wx < 0:
        raise ValueError(f"window must be non-negative, got {window}")
    if mode == "zero" and (wy > full[0] or wx > full[1]):
        raise ValueError(f"zero-padded window {window} exceeds the largest displacement {full}")
    return wy, wx


def translational(
    f: np.ndarray,
    *,
    mode: str = "toroidal",
    window: int | tuple[int, int] | None = None,
    standardize: bool = True,
    workers: int | None = None,
) -> np.ndarray:
    """Translational symmetry transform ``S_T(f)`` (paper eq. 2), centred on zero displacement.

    Parameters
    ----------
    f : (H, W) float signal (float32 stays float32: the FFT then runs in single precision).
    mode : ``"toroidal"`` (circular autocorrelation, ``f`` seen as a torus) or ``"zero"``
        (linear autocorrelation of ``f`` padded with zeros).
    window : ``(wy, wx)`` or an int: keep displacements ``|dy| <= wy``, ``|dx| <= wx``. Default: all
        distinct displacements, ``((H-1)//2, (W-1)//2)`` toroidal, ``(H-1, W-1)`` zero-padded. A
        toroidal window larger than that extends the autocorrelation periodically (the transform
        of ``f`` tiled over the plane), which lets a small sketch define a target of any size.
    standardize : scale to mean 0, variance 1 over the window; otherwise return ``AC / ||f||^2``.

    Returns
    -------
    S : (2 wy + 1, 2 wx + 1) array; ``S[wy + dy, wx + dx]`` is the value at displacement ``(dy, dx)``,
        i.e. the normalized sum of ``f(y, x) f(y + dy, x + dx)``.
    """
    f = check_signal(f)
    if mode not in ("toroidal", "zero", "overlap"):
        raise ValueError(f"mode must be 'toroidal', 'zero' or 'overlap', got {mode!r}")
    dtype = np.float32 if f.dtype == np.float32 else np.float64
    f = f.astype(dtype, copy=False)
    H, W = f.shape
    if mode == "overlap":
        return _overlap_translational(f, window, standardize, workers).astype(dtype, copy=False)
    wy, wx = _window_of((H, W), window, mode)
    if mode == "toroidal":
        shape = (H, W)
    else:
        shape = (sfft.next_fast_len(2 * H - 1, real=True), sfft.next_fast_len(2 * W - 1, real=True))
    spec = sfft.rfft2(f, s=shape, workers=workers)
    spec = spec.real**2 + spec.imag**2
    ac = sfft.irfft2(spec, s=shape, workers=workers)
    rows = np.arange(-wy, wy + 1) % shape[0]
    cols = np.arange(-wx, wx + 1) % shape[1]
    S = ac[np.ix_(rows, cols)]
    S = S / ac[0, 0]
    if standardize:
        S = _standardized(S)
    return S.astype(dtype, copy=False)


def whole_period_crop(f: np.ndarray, *, min_period: int = 4) -> tuple[int, int]:
    """Size ``(h, w)`` of a whole number of periods of ``f (H, W)`` along each axis.

    Per axis, the period ``P`` is the displacement in ``[min_period, n // 2)`` with the largest
    circular autocorrelation of the mean-free ``f`` along that axis (averaged over the other
    axis), and the size is ``(n // P) P``: a crop of that size wraps the pattern onto itself,
    which the toroidal S_T (eq. 2) assumes. Along an axis without a repeat the autocorrelation
    falls from 0 on and ``P`` is ``min_period``: less than ``min_period`` px are cut (the stone
    wall texture_bricks, 128 px: no peak on either axis, the whole crop). An axis shorter than
    ``2 min_period + 1`` keeps its size.
    """
    g = check_signal(f).astype(np.float64)
    g = g - g.mean()
    out = []
    for axis in (0, 1):
        n = g.shape[axis]
        if n < 2 * min_period + 1:
            out.append(n)
            continue
        spec = np.abs(np.fft.rfft(g, axis=axis)) ** 2
        ac = np.fft.irfft(spec, n=n, axis=axis).mean(axis=1 - axis)
        period = min_period + int(np.argmax(ac[min_period : n // 2]))
        out.append((n // period) * period)
    return out[0], out[1]


def _overlap_translational(f, window, standardize, workers):
    """S_T of a photograph, not a torus: the mean-free signal's linear autocorrelation over the
    overlap of ``f`` and its shift, per overlapping pixel, over its zero-displacement value.

    ``S(t) = (sum g(x) g(x + t) / n(t)) / (sum g^2 / (H W))`` with ``g = f - mean(f)`` and
    ``n(t) = (H - |ty|) (W - |tx|)`` the pixels both cover: a correlation coefficient, 1 at
    ``t = 0`` and near 1 at every period of a regular pattern whatever the image size. The
    toroidal S_T counts the wrap-around too, so a photograph whose period does not divide its
    size is irregular on the torus and maximizing that E_symm warps it (issue 14). Default window:
    displacements up to half the size (overlaps of at least a quarter of the image).
    """
    H, W = f.shape
    wy, wx = _window_of((H, W), window, "toroidal" if window is None else "zero")
    g = f - f.mean()
    shape = (sfft.next_fast_len(2 * H - 1, real=True), sfft.next_fast_len(2 * W - 1, real=True))
    spec = sfft.rfft2(g, s=shape, workers=workers)
    ac = sfft.irfft2(spec.real**2 + spec.imag**2, s=shape, workers=workers)
    dy, dx = np.arange(-wy, wy + 1), np.arange(-wx, wx + 1)
    S = ac[np.ix_(dy % shape[0], dx % shape[1])]
    n = np.outer(H - np.abs(dy), W - np.abs(dx)).astype(S.dtype)
    S = (S / n) / (ac[0, 0] / (H * W))
    return _standardized(S) if standardize else S


# ---------------------------------------------------------------------------------------------
# rotational and reflective descriptors


def polar_resample(
    f: np.ndarray,
    *,
    center: tuple[float, float] | None = None,
    n_angles: int = 360,
    n_radii: int | None = None,
    max_radius: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear resampling of ``f (H, W)`` on a polar grid about ``center`` ``(y, x)``.

    Radii ``r_i = (i + 0.5) max_radius / n_radii``; angles ``phi_j = 2 pi j / n_angles``, measured
    from the +x axis towards +y. ``max_radius`` defaults to the distance from the centre to the
    nearest image border (the largest full circle inside the image), ``n_radii`` to
    ``ceil(max_radius)`` (one sample per pixel). ``center`` defaults to the image centre.

    Returns ``P (n_radii, n_angles)`` and the radii ``r (n_radii,)``.
    """
    f = np.asarray(f, dtype=np.float64)
    H, W = f.shape
    cy, cx = ((H - 1) / 2.0, (W - 1) / 2.0) if center is None else (float(center[0]), float(center[1]))
    if not (0 <= cy <= H - 1 and 0 <= cx <= W - 1):
        raise ValueError(f"center {center} lies outside the {H}x{W} image")
    if max_radius is None:
        max_radius = min(cy, cx, H - 1 - cy, W - 1 - cx)
    if max_radius <= 0:
        raise ValueError(f"center {center} lies on the image border: no circle fits around it")
    if n_radii is None:
        n_radii = max(1, int(np.ceil(max_radius)))
    if n_angles < 2:
        raise ValueError(f"n_angles must be at least 2, got {n_angles}")
    r = (np.arange(n_radii) + 0.5) * (max_radius / n_radii)
    phi = 2.0 * np.pi * np.arange(n_angles) / n_angles
    ys = cy + r[:, None] * np.sin(phi)[None, :]
    xs = cx + r[:, None] * np.cos(phi)[None, :]
    P = ndimage.map_coordinates(f, [ys, xs], order=1, mode="nearest")
    return P, r


def _polar_descriptor(f, kind, *, center, n_angles, n_radii, standardize):
    f = check_signal(f)
    P, r = polar_resample(f, center=center, n_angles=n_angles, n_radii=n_radii)
    spec = sfft.rfft(P, axis=1)
    if kind == "rot":
        prod = spec.real**2 + spec.imag**2
    else:
        prod = spec * spec
    per_radius = sfft.irfft(prod, n=n_angles, axis=1)
    norm = float((r[:, None] * P**2).sum())
    if norm <= tol.constant:
        raise ValueError("signal is zero on the polar grid: its symmetry descriptor is undefined")
    S = (r[:, None] * per_radius).sum(axis=0) / norm
    if standardize:
        S = _standardized(S)
    return S


def rotational(
    f: np.ndarray,
    *,
    center: tuple[float, float] | None = None,
    n_angles: int = 360,
    n_radii: int | None = None,
    standardize: bool = True,
) -> np.ndarray:
    """Rotational symmetry descriptor ``S_R(f)`` (paper eq. 3), shape ``(n_angles,)``.

    ``S[k]`` is ``sum_r r sum_phi f(r, phi) f(r, phi + gamma_k) / sum_r r sum_phi f(r, phi)^2`` with
    ``gamma_k = 2 pi k / n_angles``, from :func:`polar_resample` about ``center`` ``(y, x)``; one
    FFT per radius (Kazhdan et al. 2004). Raw ``S[0] = 1``; see the module notes on ``standardize``.
    """
    return _polar_descriptor(f, "rot", center=center, n_angles=n_angles, n_radii=n_radii, standardize=standardize)


def reflective(
    f: np.ndarray,
    *,
    center: tuple[float, float] | None = None,
    n_angles: int = 360,
    n_radii: int | None = None,
    standardize: bool = True,
) -> np.ndarray:
    """Reflective symmetry descriptor over all lines through ``center`` (Kazhdan et al. 2002).

    Shape ``(n_angles,)``: ``S[j]`` is the ``r``-weighted correlation of ``f(r, phi)`` with
    ``f(r, 2 theta_j - phi)`` for the line at angle ``theta_j = pi j / n_angles`` (from +x towards
    +y), normalized by ``sum r f^2``; a self-convolution along ``phi`` by FFT per radius. A signal
    mirror-symmetric about the line at ``theta`` has raw value 1 there.
    """
    return _polar_descriptor(f, "ref", center=center, n_angles=n_angles, n_radii=n_radii, standardize=standardize)


# ---------------------------------------------------------------------------------------------
# objectives


def e_l2(S: np.ndarray, target: np.ndarray) -> float:
    """``E_L2`` (paper eq. 1): mean squared difference of ``S`` and ``target`` (same shape).

    The integral of eq. 1 is taken over a domain of unit measure (mean, not sum), so values are
    comparable across window sizes.
    """
    S = np.asarray(S)
    target = np.asarray(target)
    if S.shape != target.shape:
        raise ValueError(f"representation shape {S.shape} differs from the target's {target.shape}")
    diff = S.astype(np.float64) - target.astype(np.float64)
    return float(np.mean(diff * diff))


def e_symm(S: np.ndarray) -> float:
    """``E_symm`` (paper eq. 4): variance of ``S`` over its domain (use a raw representation)."""
    S = np.asarray(S, dtype=np.float64)
    return float(np.mean((S - S.mean()) ** 2))


def e_symm_toroidal(f: np.ndarray, *, window: tuple[int, int] | None = None) -> float:
    """``e_symm(translational(f, window=window, standardize=False))`` of a toroidal ``f (H, W)``.

    With the full window ``((H - 1) // 2, (W - 1) // 2)`` (every displacement but the half-period
    lines ``dy = H / 2``, ``dx = W / 2`` of even sizes), from the power spectrum ``P = |F|^2``
    alone (float64), without the inverse transform: ``sum AC = P(0)`` and ``sum AC^2 = sum P^2 /
    N`` (Parseval), less the half-period lines (1-D transforms of the spectrum's alternating
    sums), and ``AC(0) = sum f^2``; the same value up to rounding (about 1e-12 relative), at about
    half the cost. Other windows take the plain way.
    """
    f = check_signal(f).astype(np.float64, copy=False)
    H, W = f.shape
    if window is not None and tuple(window) != ((H - 1) // 2, (W - 1) // 2):
        return e_symm(translational(f, window=window, standardize=False))
    F = sfft.rfft2(f)
    P = F.real**2 + F.imag**2
    mult = np.full(W // 2 + 1, 2.0)
    mult[0] = 1.0
    if W % 2 == 0:
        mult[-1] = 1.0
    N = H * W
    ac0 = float(np.sum(f * f))
    total = float(P[0, 0])
    total_sq = float((P * P).sum(axis=0) @ mult) / N
    n = ((H - 1) // 2 * 2 + 1) * ((W - 1) // 2 * 2 + 1)
    row = sfft.irfft((-1.0) ** np.arange(H) @ P, n=W) / H if H % 2 == 0 else None  # AC(H / 2, dx)
    col = sfft.fft(P @ (mult * (-1.0) ** np.arange(mult.size))).real / N if W % 2 == 0 else None  # AC(dy, W / 2)
    for line in (row, col):
        if line is not None:
            total -= float(line.sum())
            total_sq -= float(line @ line)
    if row is not None and col is not None:  # AC(H / 2, W / 2) left out twice
        total += float(row[W // 2])
        total_sq += float(row[W // 2] ** 2)
    mean = total / n / ac0
    return max(total_sq / n / ac0**2 - mean * mean, 0.0)


# ---------------------------------------------------------------------------------------------
# symmetry-space filters (each returns a standardized array of the input's shape)


def blur(S: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur of ``S`` with standard deviation ``sigma`` (in samples), re-standardized.

    A 1-D descriptor over angles (``S_R``) is blurred circularly, a 2-D ``S_T`` with reflected edges.
    """
    if sigma < 0:
        raise ValueError(f"sigma must be non-negative, got {sigma}")
    S = np.asarray(S, dtype=np.float64)
    mode = "wrap" if S.ndim == 1 else "reflect"
    return standardize(ndimage.gaussian_filter(S, sigma, mode=mode))


def sharpen(S: np.ndarray, power: float) -> np.ndarray:
    """Sharpen peaks: ``sign(S) |S|^power`` of the standardized ``S``, re-standardized.

    The paper raises ``S_T`` to the 4th power and normalizes the L1 mass; for standardized
    representations re-standardizing fixes the scale the same way (both have unit variance).
    """
    if power <= 0:
        raise ValueError(f"power must be positive, got {power}")
    Z = standardize(S)
    return standardize(np.sign(Z) * np.abs(Z) ** power)


def contrast(S: np.ndarray, amount: float) -> np.ndarray:
    """Contrast curve on ``S`` rescaled to [0, 1]: ``x^a / (x^a + (1 - x)^a)``, re-standardized.

    A linear gain would vanish under standardization, so contrast is this S-shaped curve: ``amount``
    1 is the identity, above 1 pushes values towards the extremes (stronger symmetries stand out),
    below 1 pulls them towards the middle.
    """
    if amount <= 0:
        raise ValueError(f"amount must be positive, got {amount}")
    S = np.asarray(S, dtype=np.float64)
    lo, hi = S.min(), S.max()
    if hi - lo <= tol.constant:
        raise ValueError("symmetry representation is constant: contrast is undefined")
    x = (S - lo) / (hi - lo)
    a = x**amount
    b = (1.0 - x) ** amount
    return standardize(a / (a + b))


def _affine_about_centre(S: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Resample 2-D ``S`` at ``matrix @ (p - c) + c`` (c the zero-displacement centre)."""
    S = np.asarray(S, dtype=np.float64)
    if S.ndim != 2:
        raise ValueError(f"scale and rotate need a 2-D representation, got shape {S.shape}")
    c = (np.array(S.shape, dtype=np.float64) - 1.0) / 2.0
    offset = c - matrix @ c
    out = ndimage.affine_transform(S, matrix, offset=offset, order=1, mode="constant", cval=float(S.mean()))
    return standardize(out)


def scale(S: np.ndarray, factor: float) -> np.ndarray:
    """Scale a 2-D ``S_T`` about zero displacement: ``out(d) = S(d / factor)``, re-standardized.

    ``factor`` 2 doubles every period of the pattern. Displacements that come from outside ``S``
    take its mean value.
    """
    if factor <= 0:
        raise ValueError(f"factor must be positive, got {factor}")
    return _affine_about_centre(S, np.eye(2) / factor)


def rotate(S: np.ndarray, degrees: float) -> np.ndarray:
    """Rotate a 2-D ``S_T`` about zero displacement by ``degrees`` (counter-clockwise on screen).

    ``out(d) = S(R^-1 d)`` with ``d = (dy, dx)``, rows pointing down; values from outside ``S`` take
    its mean.
    """
    t = np.deg2rad(degrees)
    c, s = np.cos(t), np.sin(t)
    # R maps (dx, dy) by a counter-clockwise screen rotation: in (row=dy, col=dx) order with rows
    # pointing down, a counter-clockwise turn is dy' = c dy - s dx, dx' = s dy + c dx.
    R = np.array([[c, -s], [s, c]])
    return _affine_about_centre(S, R.T)


def strongest_peak(S: np.ndarray, *, min_distance: float = 1.0) -> tuple[int, int]:
    """Displacement ``(dy, dx)`` of the strongest non-zero peak of centred 2-D ``S``.

    A peak is a local maximum over its 3x3 neighbourhood (window borders excluded, toroidal
    neighbours are not assumed) at least ``min_distance`` from zero displacement, so the central
    lobe around ``(0, 0)`` never counts. Values within ``1e-9`` (relative to the range of ``S``) of
    the best tie; the shortest displacement wins (then row-major order), so a perfect lattice
    reports a basis vector rather than a diagonal. ValueError when there is no peak.
    """
    S = np.asarray(S, dtype=np.float64)
    wy, wx = (S.shape[0] - 1) // 2, (S.shape[1] - 1) // 2
    dy, dx = np.mgrid[-wy : S.shape[0] - wy, -wx : S.shape[1] - wx]
    dist = np.hypot(dy, dx)
    local = S >= ndimage.maximum_filter(S, size=3, mode="constant", cval=-np.inf)
    local[[0, -1], :] = False
    local[:, [0, -1]] = False
    masked = np.where(local & (dist >= min_distance), S, -np.inf)
    best = masked.max()
    if not np.isfinite(best):
        raise ValueError(f"no peak at least {min_distance} from zero displacement in a {S.shape} array")
    tol = 1e-9 * max(float(np.ptp(S)), 1.0)
    ties = np.flatnonzero(masked.ravel() >= best - tol)
    k = int(ties[np.argmin(dist.ravel()[ties])])
    return int(dy.flat[k]), int(dx.flat[k])

