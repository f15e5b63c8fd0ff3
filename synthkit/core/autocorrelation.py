"""Windowed toroidal autocorrelation of an image kept up to date when one block of it changes.

:class:`IncrementalAutocorrelation` holds ``AC(d) = sum_p g(p) g(p + d)`` of a signal ``f (H, W)``
(``g = f - offset``, indices mod ``(H, W)``) over a window of displacements and evaluates many
candidate replacements of one block at a time, without a full-image transform per candidate:
the guided walk of symmetry-guided quilting (:mod:`synthkit.methods.symtex.synth`) scores every
candidate patch of a tile by E_L2 of the standardized window (:func:`synthkit.core.symmetry.e_l2`)
this way.
"""

from __future__ import annotations

import threading

import numpy as np
import scipy.fft as sfft

from synthkit.core.symmetry import check_signal
from synthkit.core.threads import one_blas_thread, thread_pool

__all__ = ["IncrementalAutocorrelation"]

_CHUNK = 4  # candidates per batched transform in IncrementalAutocorrelation.l2_of_changes


def _run_chunks(chunk, jobs: list[tuple[int, int]], threads: int) -> None:
    """``chunk(lo, hi)`` for every ``(lo, hi)`` of ``jobs``, shared by ``threads`` threads (in
    order in this thread when ``threads`` is 1)."""
    if threads > 1:
        list(thread_pool("symmetry", threads).map(lambda job: chunk(*job), jobs))
    else:
        for job in jobs:
            chunk(*job)


class IncrementalAutocorrelation:
    """Windowed toroidal autocorrelation of ``f (H, W)`` kept up to date under block changes.

    ``ac (2 wy + 1, 2 wx + 1)`` holds ``AC(d) = sum_p g(p) g(p + d)`` of ``g = f - offset``
    (indices mod ``(H, W)``) for ``|dy| <= wy, |dx| <= wx``, centred like :func:`translational`.
    A constant ``offset`` changes the toroidal AC by a constant only, so the standardized ``S_T``
    is the same for every offset; subtracting the mean keeps the sums small (better rounding).
    Replacing ``f`` by ``f + delta`` with ``delta`` supported on an ``h x w`` block ``B`` at
    ``(y0, x0)`` changes it by

        dAC(d) = c(d) + c(-d) + a(d),  c(d) = sum_{p in B} delta(p) g(p + d),  a = autocorr(delta),

    which only involves ``g`` on ``B`` grown by the window: one FFT of size about
    ``(h + 2 wy) x (w + 2 wx)`` per candidate instead of one of ``H x W`` (and the whole spectrum of
    ``dAC`` is real, ``2 Re(conj(D) G) + |D|^2``, so one forward and one inverse transform suffice).
    :meth:`delta` evaluates candidates at the same block in one batched FFT. :meth:`l2_of_changes`
    (the guided walk's evaluation) needs less: E_L2 of the standardized window follows from four
    sums of ``dAC`` over the window (its sum, its inner products with the target and with ``ac``,
    its squared sum), and ``dAC`` is even, so only the rows ``dy >= 0`` are transformed back (a
    real-input FFT along the rows, then ``wy + 1`` row transforms); with a window holding the whole
    torus, the sums come from per-tile fields and a small FFT per candidate (:meth:`_spectral_l2`).

    Requirements: ``wy <= (H - 1) // 2``, ``wx <= (W - 1) // 2`` (distinct displacements) and blocks
    at most half the image in each axis (so a block never meets its own toroidal copy).
    ``fft_dtype`` float32 runs the per-candidate transforms in single precision (about twice as
    fast; sums and ``ac`` stay float64, the mean-subtracting ``offset`` keeps the relative error
    near 1e-6). :meth:`refresh` recomputes ``ac`` from scratch to drop rounding drift.
    """

    def __init__(self, f: np.ndarray, *, window: tuple[int, int], offset: float = 0.0, fft_dtype=np.float64):
        f = check_signal(f).astype(np.float64)
        H, W = f.shape
        wy, wx = int(window[0]), int(window[1])
        if not (0 <= wy <= (H - 1) // 2 and 0 <= wx <= (W - 1) // 2):
            raise ValueError(f"window {window} must lie within ((H-1)//2, (W-1)//2) = {((H - 1) // 2, (W - 1) // 2)}")
        self.f = f.copy()
        self.offset = float(offset)
        self.fft_dtype = np.dtype(fft_dtype)
        if self.fft_dtype not in (np.float32, np.float64):
            raise ValueError(f"fft_dtype must be float32 or float64, got {fft_dtype}")
        self.window = (wy, wx)
        self._plans: dict[tuple, tuple] = {}
        self._weight_cache: dict[tuple[int, int], dict] = {}
        self._ac_version = 0
        self._grown_cache: tuple | None = None
        self._sums_cache: tuple | None = None
        self._torus_cache: dict = {}
        self._ac: np.ndarray | None = None
        self._prepared: tuple | None = None
        self._lock = threading.Lock()
        self.refresh()

    @property
    def ac(self) -> np.ndarray:
        """The window ``(2 wy + 1, 2 wx + 1)`` of the autocorrelation of ``f - offset``.

        After :meth:`apply` of a change whose window was not given with the whole torus as window
        (the spectral evaluation never needs it), it is recomputed from ``f`` when next read."""
        if self._ac is None:
            self._ac = self._full_ac()
        return self._ac

    @ac.setter
    def ac(self, value: np.ndarray) -> None:
        self._ac = value

    def _full_ac(self) -> np.ndarray:
        spec = sfft.rfft2(self.f - self.offset)
        ac = sfft.irfft2(spec.real**2 + spec.imag**2, s=self.f.shape)
        wy, wx = self.window
        H, W = self.f.shape
        return ac[np.ix_(np.arange(-wy, wy + 1) % H, np.arange(-wx, wx + 1) % W)]

    def refresh(self) -> None:
        """Recompute ``ac`` from ``f`` with one full-image FFT."""
        self._ac = self._full_ac()
        self._ac_version += 1

    def _plan(self, h: int, w: int):
        key = (h, w)
        if key not in self._plans:
            wy, wx = self.window
            shape = (sfft.next_fast_len(h + 2 * wy, real=True), sfft.next_fast_len(w + 2 * wx, real=True))
            rows = np.arange(-wy, wy + 1) % shape[0]
            cols = np.arange(-wx, wx + 1) % shape[1]
            self._plans[key] = (shape, rows, cols)
        return self._plans[key]

    def _blocks(self, deltas: np.ndarray, dtype=None) -> np.ndarray:
        """``deltas`` as ``(K, h, w)`` (one ``(h, w)`` block becomes ``K = 1``); ValueError when a
        block exceeds half the image (the incremental update assumes it wraps onto itself nowhere)."""
        deltas = np.asarray(deltas, dtype=dtype)
        if deltas.ndim == 2:
            deltas = deltas[None]
        h, w = deltas.shape[1:]
        H, W = self.f.shape
        if h > H // 2 or w > W // 2:
            raise ValueError(f"block {h}x{w} exceeds half the {H}x{W} image")
        return deltas

    def delta_grid(self, y0: int, x0: int, deltas: np.ndarray) -> np.ndarray:
        """``dAC`` on the padded FFT grid, ``(K, M0, M1)``: displacement ``d`` sits at ``d mod M``.

        Only displacements inside the window are meaningful; :meth:`window_of` extracts them.
        """
        deltas = self._blocks(deltas, np.float64)
        K, h, w = deltas.shape
        H, W = self.f.shape
        wy, wx = self.window
        shape, _, _ = self._plan(h, w)
        ry = (y0 - wy + np.arange(h + 2 * wy)) % H
        rx = (x0 - wx + np.arange(w + 2 * wx)) % W
        grown = np.zeros(shape, dtype=self.fft_dtype)
        grown[: h + 2 * wy, : w + 2 * wx] = self.f[np.ix_(ry, rx)] - self.offset
        Fg = sfft.rfft2(grown)
        placed = np.zeros((K, *shape), dtype=self.fft_dtype)
        placed[:, wy : wy + h, wx : wx + w] = deltas
        D = sfft.rfft2(placed, axes=(1, 2), overwrite_x=True)
        spec = D.real * (2.0 * Fg.real + D.real)
        spec += D.imag * (2.0 * Fg.imag + D.imag)
        return sfft.irfft2(spec, s=shape, axes=(1, 2), overwrite_x=True).astype(np.float64, copy=False)

    def window_of(self, grid: np.ndarray, block: tuple[int, int]) -> np.ndarray:
        """Window ``(..., 2 wy + 1, 2 wx + 1)`` of a :meth:`delta_grid` result for ``block`` (h, w)."""
        _, rows, cols = self._plan(*block)
        return grid[..., rows, :][..., cols]

    def delta(self, y0: int, x0: int, deltas: np.ndarray) -> np.ndarray:
        """``dAC (K, 2 wy + 1, 2 wx + 1)`` for each block change ``deltas (K, h, w)`` at ``(y0, x0)``.

        ``(y0, x0)`` may be any integers: indices wrap toroidally.
        """
        deltas = np.asarray(deltas, dtype=np.float64)
        if deltas.ndim == 2:
            deltas = deltas[None]
        return self.window_of(self.delta_grid(y0, x0, deltas), deltas.shape[1:])

    def _half_plan(self, h: int, w: int):
        """Grid ``(M0, M1)`` for a block ``h x w`` and the half-window layout ``(wy + 1, M1)``.

        The block sits at grid rows ``0..h-1``, columns ``0..w-1``; the grown image occupies rows
        ``-wy .. h + wy - 1`` (mod ``M0``), columns likewise, so the circular correlation on the grid
        is exact for every displacement of the window. An axis where that grid would not be smaller
        than the image (large windows, e.g. all displacements) uses the image's own period instead:
        the toroidal correlation of the whole image, exact as well. ``keep (M1,)`` marks the
        columns ``dx`` of the window (``|dx| <= wx`` mod ``M1``), ``rows (wy + 1,)`` weighs row
        ``dy = 0`` once and rows ``dy > 0`` twice (each stands for ``dy`` and ``-dy``: the change
        of AC is even).
        """
        key = ("half", h, w)
        if key not in self._plans:
            wy, wx = self.window
            shape = tuple(
                n if sfft.next_fast_len(b + 2 * r, real=True) >= n else sfft.next_fast_len(b + 2 * r, real=True)
                for n, b, r in zip(self.f.shape, (h, w), (wy, wx), strict=True)
            )
            keep = np.zeros(shape[1], dtype=bool)
            keep[np.arange(-wx, wx + 1) % shape[1]] = True
            rows = np.full(wy + 1, 2.0)
            rows[0] = 1.0
            self._plans[key] = (shape, keep, rows)
        return self._plans[key]

    def _half_layout(self, X: np.ndarray, shape, keep, rows) -> np.ndarray:
        """Even part of a window array ``X (2 wy + 1, 2 wx + 1)`` on the half layout ``(wy + 1, M1)``,
        times the row weights, zero outside the window: ``sum_W s X = sum(half(s) * this)`` for even ``s``."""
        wy, wx = self.window
        even = 0.5 * (X + X[::-1, ::-1])
        out = np.zeros((wy + 1, shape[1]))
        out[:, np.arange(-wx, wx + 1) % shape[1]] = even[wy:] * rows[:, None]
        return out

    def _weights(self, h: int, w: int, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Half-layout weights ``(3, (wy + 1) M1)`` of the window indicator, ``T`` and ``ac``, and of
        the squared sum, in ``fft_dtype``. Kept between calls: the target's rows are rebuilt when
        another target comes, the ``ac`` row whenever ``ac`` changed (:meth:`apply`, :meth:`refresh`)."""
        shape, keep, rows = self._half_plan(h, w)
        cache = self._weight_cache.get((h, w))
        if cache is None:
            ones = self._half_layout(np.ones(T.shape), shape, keep, rows).ravel()
            sq = (rows[:, None] * keep[None, :]).ravel().astype(self.fft_dtype)
            cache = {"weights": np.zeros((3, ones.size), dtype=self.fft_dtype), "sq": sq, "T": None, "ac": -1}
            cache["weights"][0] = ones
            self._weight_cache[(h, w)] = cache
        if cache["T"] is None or cache["T"].shape != T.shape or not np.array_equal(cache["T"], T):
            cache["T"] = T.copy()
            cache["weights"][1] = self._half_layout(T, shape, keep, rows).ravel()
        if cache["ac"] != self._ac_version:  # a new array: threads scoring other blocks may hold the old one
            version, weights = self._ac_version, cache["weights"].copy()
            weights[2] = self._half_layout(self.ac, shape, keep, rows).ravel()
            cache["weights"], cache["ac"] = weights, version
        return cache["weights"], cache["sq"]

    def _spectral(self, h: int, w: int) -> bool:
        """True when the grid is the image's period and the window holds every displacement but the
        half-period lines (``dy = H / 2`` or ``dx = W / 2`` of even sizes): the paper's unwindowed S_T."""
        H, W = self.f.shape
        shape, _, _ = self._half_plan(h, w)
        return shape == (H, W) and self.window == ((H - 1) // 2, (W - 1) // 2)

    def _spectral_weights(self, h: int, w: int, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Parseval weights on the half spectrum ``(M0, M1 // 2 + 1)`` flattened: ``(3, n)`` for the
        window indicator and ``T`` (``mult(kx) Re(FFT(X on the grid)) / N``; the third row, for the
        autocorrelation, is filled per block by :meth:`l2_of_changes`), ``(n,)`` for the squared sum
        (``mult(kx) / N``) and ``(M1 // 2 + 1,)`` ``mult(kx) (-1)^kx`` for the ``dx = W / 2`` line;
        ``mult`` counts the conjugate column a half spectrum stands for (1 or 2)."""
        M0, M1 = self.f.shape
        wy, wx = self.window
        key = ("spectral", h, w)
        cache = self._weight_cache.get(key)
        mult = self._mult_row(M1)
        N = M0 * M1

        def parseval(X):  # in fft_dtype, the precision the weights are used in
            grid = np.zeros((M0, M1), dtype=self.fft_dtype)
            grid[np.ix_(np.arange(-wy, wy + 1) % M0, np.arange(-wx, wx + 1) % M1)] = X
            return (sfft.rfft2(grid).real * (mult / N)).ravel()

        if cache is None:
            sq = np.broadcast_to(mult / N, (M0, mult.size)).ravel().astype(self.fft_dtype)
            col = (mult * (-1.0) ** np.arange(mult.size)).astype(self.fft_dtype)
            cache = {"weights": np.zeros((3, sq.size), dtype=self.fft_dtype), "sq": sq, "col": col, "T": None}
            cache["weights"][0] = parseval(np.ones((2 * self.window[0] + 1, 2 * self.window[1] + 1)))
            self._weight_cache[key] = cache
        if T is cache.get("T_given"):  # the walk passes the same array every tile
            pass
        elif cache["T"] is None or cache["T"].shape != T.shape or not np.array_equal(cache["T"], T):
            cache["T"] = T.copy()
            cache["weights"][1] = parseval(T)
        cache["T_given"] = T
        return cache["weights"], cache["sq"], cache["col"]

    def _base_sums(self, T: np.ndarray) -> tuple[float, float, float, float, float]:
        """``sum ac``, ``<ac, T>``, ``sum ac^2``, ``mean T``, ``mean T^2`` (kept until ``ac`` or ``T`` change)."""
        c = self._sums_cache
        if c is None or c[0] != self._ac_version or c[1].shape != T.shape or not np.array_equal(c[1], T):
            ac = self.ac
            sums = (
                float(ac.sum()),
                float((ac * T).sum()),
                float((ac * ac).sum()),
                float(T.mean()),
                float((T * T).mean()),
            )
            self._sums_cache = c = (self._ac_version, T.copy(), sums)
        return c[2]

    def _grown_spectrum(self, y0: int, x0: int, h: int, w: int) -> np.ndarray:
        """``2 G``: twice the half spectrum of ``g`` around the block on the grid (block at the origin).

        The last one is kept until ``f`` changes, so :meth:`apply` after :meth:`l2_of_changes` at the
        same block reuses it."""
        H, W = self.f.shape
        key = (y0 % H, x0 % W, h, w, self._ac_version)
        if self._grown_cache is not None and self._grown_cache[0] == key:
            return self._grown_cache[1]
        wy, wx = self.window
        shape, _, _ = self._half_plan(h, w)
        M0, M1 = shape
        if shape == (H, W):  # the whole torus, rolled so that the block sits at the origin
            grown = np.roll(self.f, (-(y0 % H), -(x0 % W)), axis=(0, 1)).astype(self.fft_dtype)
            grown -= self.fft_dtype.type(self.offset)
        else:  # the grown image on the grid: g_grid[u mod M] = g(y0 + u)
            uy = np.arange(H) if M0 == H else np.arange(-wy, h + wy)
            ux = np.arange(W) if M1 == W else np.arange(-wx, w + wx)
            grown = np.zeros(shape, dtype=self.fft_dtype)
            grown[np.ix_(uy % M0, ux % M1)] = self.f[np.ix_((y0 + uy) % H, (x0 + ux) % W)] - self.offset
        G2 = 2.0 * sfft.rfft2(grown)
        self._grown_cache = (key, G2)
        return G2

    def _change_spectra(self, G2: np.ndarray, deltas: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """Real spectra ``(k, M0, M1 // 2 + 1)`` of ``dAC`` on the grid ``shape`` for blocks
        ``deltas (k, h, w)``: ``Re(D conj(2 G + D))``; the forward transform skips the block's zero rows."""
        M0, M1 = shape
        D = sfft.rfft(deltas, n=M1, axis=2)
        D = sfft.fft(D, n=M0, axis=1, overwrite_x=True)
        # on the interleaved (re, im) float view: contiguous, no complex temporaries
        prod = G2.view(self.fft_dtype) + D.view(self.fft_dtype)
        prod *= D.view(self.fft_dtype)
        del D
        return prod[..., 0::2] + prod[..., 1::2]

    def _halves(self, spec: np.ndarray, M1: int) -> np.ndarray:
        """Half windows ``(k, wy + 1, M1)`` of ``dAC`` from its real spectra (rows ``dy >= 0`` only)."""
        wy = self.window[0]
        return sfft.irfft(sfft.ihfft(spec, axis=1)[:, : wy + 1], n=M1, axis=2, overwrite_x=True)

    def _torus_state(self) -> dict:
        """What the spectral evaluation needs of the current ``g = f - offset`` (kept until ``f``
        changes): its half spectrum ``G`` and power ``P = |G|^2`` (float64), the half-period lines of
        ``AC = autocorr(g)`` and the window sums of ``AC``."""
        st = self._torus_cache.get("state")
        if st is not None and st["version"] == self._ac_version:
            return st
        H, W = self.f.shape
        g = self.f - self.offset
        G = sfft.rfft2(g)  # one thread: the walk's other threads keep the second core
        P = G.real**2 + G.imag**2
        st = {"version": self._ac_version, "g": g, "G": G, "P": P, "gsum": float(g.sum())}
        # the lines dy = H / 2 and dx = W / 2 of AC (outside the window), as in the Parseval sums
        mult = self._mult_row(W)
        st["ac_row"] = sfft.irfft((-1.0) ** np.arange(H) @ P, n=W) / H if H % 2 == 0 else None
        st["ac_col"] = sfft.fft(P @ (mult * (-1.0) ** np.arange(mult.size))).real / (H * W) if W % 2 == 0 else None
        self._torus_cache["state"] = st
        return st

    def prepare_image(self, target: np.ndarray, block: tuple[int, int]) -> None:
        """The spectral evaluation's work on the whole current image for blocks ``(h, w)``: its
        spectrum, window sums and fields (:meth:`_image_fields`), which :meth:`prepare` of every
        block then cuts from (nothing when the window is not the whole torus). The guided walk
        calls it while its other threads build the candidates of a batch."""
        if not self._spectral(*block):
            return
        T = np.asarray(target, dtype=np.float64)
        with self._lock:
            st = self._torus_state()
            tau = self._image_sums(st, *block, T)[1]
            self._image_fields(st, tau, tau[0])

    def prepare(self, y0: int, x0: int, h: int, w: int, target: np.ndarray):
        """The spectral evaluation's work at block ``h x w`` at ``(y0, x0)`` that does not depend on
        the candidates (:meth:`_spectral_l2`): the block's fields, the small-grid weights and the
        current image's window sums, kept until ``f``, the block or the target change. The fields
        are cut from whole-image fields (:meth:`_image_fields`) computed once per image, so blocks
        evaluated against the same image (the guided walk's batches; from several threads) share them.
        Returns ``(block, small, sums)``, or None when the window is not the whole torus (nothing to prepare)."""
        H, W = self.f.shape
        if not self._spectral(h, w):
            return None
        T = np.asarray(target, dtype=np.float64)
        with self._lock:  # what the whole image gives, computed once by the first thread that needs it
            st = self._torus_state()
            sums, tau = self._image_sums(st, h, w, T)
            t_key = tau[0]
            key = (y0 % H, x0 % W, h, w, self._ac_version, id(t_key))
            prepared = self._prepared
            if prepared is not None and prepared[0] == key:
                return prepared[1]
            fields = self._image_fields(st, tau, t_key)
        block = self._block_fields(st, fields, y0, x0, h, w)
        kernels = self._near_zero_kernels(fields, y0, x0, h, w)
        small = self._small_grid_weights(st, y0, x0, h, w, T, t_key, kernels)
        result = (block, small, sums)
        self._prepared = (key, result)
        return result

    def _spectral_l2(self, y0: int, x0: int, deltas: np.ndarray, T: np.ndarray, workers: int | None):
        """``(lin (K, 3), quad (K,), base sums)`` of the spectral case without a full-image transform
        per candidate (:meth:`l2_of_changes`).

        ``dAC(d) = c(d) + c(-d) + a(d)`` with ``c(d) = sum_p delta(p) g(p + d)`` over the torus and
        ``a = autocorr(delta)`` (support ``|dy| < h``, ``|dx| < w``). Over the window ``Wn`` (every
        displacement but the half-period lines):

        - ``sum dAC = <delta, U_1> + (sum delta)^2``, ``<dAC, X> = <delta, U_X> + sum a X`` for
          ``X = T`` and ``X = AC``, where ``U_X(p) = sum_{d in Wn} (X(d) + X(-d)) g(p + d)`` is a
          fixed field on the block (cut from the inverse transform of ``X^ G``, computed once per
          image, the lines subtracted by row/column correlations);
        - ``sum dAC^2 = 2 sum a AC + 2 sum (delta * delta)(s) Conv(s) + 4 sum a c + sum a^2`` less
          ``2 sum (c(d)^2 + c(d) c(-d))`` over the lines: ``sum_d c(d)^2 = sum a AC``,
          ``sum_d c(d) c(-d) = sum_s (delta * delta)(s) Conv(2 p0 + s)`` with ``Conv = g * g``
          (cut on ``(2h - 1) x (2w - 1)`` pixels from the inverse transform of ``G^2``), and ``sum a c``
          involves ``c`` for ``|d| < (h, w)`` only: every per-candidate term lives on a small grid
          of about ``3h x 3w`` (one small FFT per candidate), and ``c`` on the lines is a product
          of the block with fixed row/column strips of ``g``.

        Exact algebra (the same sums as Parseval on the full spectrum of each candidate), so the
        values agree with a full recompute up to rounding. The parts: :meth:`_window_sums` (the
        current image's sums), :meth:`_block_fields` (``U_1``, ``U_T``, ``U_ac`` and the line
        strips), :meth:`_small_grid_weights` and, per candidate, :meth:`_candidate_terms`."""
        K, h, w = deltas.shape
        block, small, sums = self.prepare(y0, x0, h, w, T)
        deltas = deltas.astype(self.fft_dtype, copy=False)
        lin = np.empty((K, 3))
        quad = np.empty(K)

        def chunk(lo: int, hi: int) -> None:
            lin[lo:hi], quad[lo:hi] = self._candidate_terms(deltas[lo:hi], block, small)

        # one chunk per thread (the per-candidate work is small); the chunks' sizes follow the
        # number of threads, and BLAS rounds products of other sizes differently (an ulp): the
        # same bytes for a given number of threads
        threads = max(1, min(int(workers or 1), K))
        bounds = [round(i * K / threads) for i in range(threads + 1)]
        _run_chunks(chunk, list(zip(bounds[:-1], bounds[1:], strict=True)), threads)
        return lin, quad, sums

    def _window_sums(self, st: dict, weights: np.ndarray, sq: np.ndarray) -> tuple[float, float, float]:
        """``sum AC``, ``<AC, T>`` and ``sum AC^2`` over the window (float64, Parseval less the lines)."""
        W = self.f.shape[1]
        Pf = st["P"].ravel()
        ac_sum = float(weights[0].astype(np.float64) @ Pf)
        ac_t = float(weights[1].astype(np.float64) @ Pf)
        ac_sq = float((Pf * Pf) @ sq.astype(np.float64))
        ac_row, ac_col = st["ac_row"], st["ac_col"]
        if ac_row is not None:
            ac_sq -= float(ac_row @ ac_row)
        if ac_col is not None:
            ac_sq -= float(ac_col @ ac_col)
        if ac_row is not None and ac_col is not None:
            ac_sq += float(ac_row[W // 2] ** 2)
        return ac_sum, ac_t, ac_sq

    @staticmethod
    def _near_zero_kernels(fields: dict, y0: int, x0: int, h: int, w: int):
        """``AC`` for ``|d| < (h, w)`` and ``Conv = g * g`` at ``2 p0 + s`` (cut from :meth:`_image_fields`)."""
        H, W = fields["AC"].shape
        ac_small = fields["AC"][np.ix_(np.arange(-(h - 1), h) % H, np.arange(-(w - 1), w) % W)]
        rows, cols = (2 * y0 + np.arange(2 * h - 1)) % H, (2 * x0 + np.arange(2 * w - 1)) % W
        return ac_small, fields["Conv"][np.ix_(rows, cols)]

    def _tau(self, weights: np.ndarray, t_key, T: np.ndarray, shape: tuple[int, int]) -> tuple:
        """``(t_key, the spectral weight of T (shape) float64, mean(T), mean(T^2))``, kept while the
        target stays."""
        tau = self._torus_cache.get("tau")
        if tau is None or tau[0] is not t_key:
            N = self.f.size
            tau = 2.0 * weights[1].astype(np.float64).reshape(shape) * (N / self._mult_row(self.f.shape[1]))
            tau = (t_key, tau, float(T.mean()), float((T * T).mean()))
            self._torus_cache["tau"] = tau
        return tau

    def _image_sums(self, st: dict, h: int, w: int, T: np.ndarray) -> tuple[tuple, tuple]:
        """The window sums of the current image and the target's means, ``(sum AC, <AC, T>, sum AC^2,
        mean T, mean T^2)`` (kept with the torus state while the target stays), and :meth:`_tau`."""
        weights, sq, _ = self._spectral_weights(h, w, T)
        t_key = self._weight_cache[("spectral", h, w)]["T"]  # a new object whenever the target changes
        tau = self._tau(weights, t_key, T, st["P"].shape)
        if st.get("sums", (None,))[0] is not t_key:
            st["sums"] = (t_key, (*self._window_sums(st, weights, sq), tau[2], tau[3]))
        return st["sums"][1], tau

    def _image_fields(self, st: dict, tau: tuple, t_key) -> dict:
        """Whole-image fields of the current ``g`` (transforms in ``fft_dtype``, kept with the torus
        state until ``f`` or the target change): ``U_1``, ``U_T``, ``U_ac`` ``(H, W)`` with
        ``U_X(p) = sum_{d in Wn} (X(d) + X(-d)) g(p + d)`` over the window ``Wn`` (the inverse
        transform of ``X^ G``, ``X`` without its half-period lines), ``AC = autocorr(g)`` and
        ``Conv = g * g`` ``(H, W)``: four full-size inverse transforms per image instead of pruned
        transforms per block."""
        cached = st.get("fields")
        if cached is not None and cached[0] is t_key:
            return cached[1]
        H, W = self.f.shape
        ctype = np.complex64 if self.fft_dtype == np.float32 else np.complex128
        g, G, P = st["g"], st["G"].astype(ctype), st["P"]
        ac_row, ac_col = st["ac_row"], st["ac_col"]
        # AC without the half-period lines, on the half spectrum: P less the lines' transforms
        # ((-1)^ky rfft(ac_row)(kx), fft(ac_col)(ky) (-1)^kx) plus the corner they share
        K = P.copy()
        sign_y, sign_x = (-1.0) ** np.arange(H)[:, None], (-1.0) ** np.arange(W // 2 + 1)[None, :]
        if ac_row is not None:
            K -= sign_y * sfft.rfft(ac_row)[None, :].real
        if ac_col is not None:
            K -= sfft.fft(ac_col).real[:, None] * sign_x
        if ac_row is not None and ac_col is not None:
            K += ac_row[W // 2] * sign_y * sign_x
        U_T = sfft.irfft2(G * tau[1].astype(self.fft_dtype), s=(H, W))
        U_ac = sfft.irfft2(G * (2.0 * K).astype(self.fft_dtype), s=(H, W))
        U_1 = np.full((H, W), 2.0 * st["gsum"])
        if ac_row is not None:  # the line dy = H / 2 left out: 2 sum_j g(y + H / 2, j)
            U_1 -= 2.0 * np.roll(g.sum(axis=1), -(H // 2))[:, None]
        if ac_col is not None:
            U_1 -= 2.0 * np.roll(g.sum(axis=0), -(W // 2))[None, :]
        if ac_row is not None and ac_col is not None:
            U_1 += 2.0 * np.roll(g, (-(H // 2), -(W // 2)), axis=(0, 1))
        fields = {"U": np.stack([U_1, U_T, U_ac], axis=2), "AC": sfft.irfft2(P.astype(self.fft_dtype), s=(H, W)),
                  "Conv": sfft.irfft2(G * G, s=(H, W))}
        st["fields"] = (t_key, fields)
        return fields

    def _block_fields(self, st: dict, fields: dict, y0: int, x0: int, h: int, w: int) -> dict:
        """The fixed fields on the block: ``fields (h w, 3)`` = ``U_1, U_T, U_ac`` (cut from
        :meth:`_image_fields`) and the line strips ``M_r (h w, W)``, ``M_c (h w, H)`` (None for odd sizes)."""
        H, W = self.f.shape
        dt = self.fft_dtype
        g = st["g"]
        ry, rx = (y0 + np.arange(h)) % H, (x0 + np.arange(w)) % W
        M_r = M_c = None
        if st["ac_row"] is not None:  # row strip: M_r[(py, px), j] = g(y0 + H / 2 + py, x0 + px + j)
            strip = np.roll(g[(ry + H // 2) % H], -(x0 % W), axis=1)
            strip = np.concatenate([strip, strip[:, :w]], axis=1).astype(dt)
            M_r = np.lib.stride_tricks.sliding_window_view(strip, W, axis=1)[:, :w].reshape(h * w, W)
        if st["ac_col"] is not None:  # column strip: M_c[(py, px), j] = g(y0 + py + j, x0 + W / 2 + px)
            strip = np.roll(g[:, (rx + W // 2) % W], -(y0 % H), axis=0)
            strip = np.concatenate([strip, strip[:h]], axis=0).astype(dt)
            M_c = np.lib.stride_tricks.sliding_window_view(strip, H, axis=0)[:h].reshape(h * w, H)
        return {"fields": fields["U"][np.ix_(ry, rx)].reshape(h * w, 3), "M_r": M_r, "M_c": M_c}

    def _small_grid_weights(self, st: dict, y0: int, x0: int, h: int, w: int, T: np.ndarray, t_key,
                            kernels) -> dict:
        """Weights on the small grid ``(My, Mx)`` of about ``3h x 3w`` for the terms of the block's
        own autocorrelation ``a``: ``wa (n, 2)`` (``sum a T``, ``sum a AC``), ``w_conv`` (``Conv``),
        ``w_grown`` (``c`` near zero) and ``wsq`` (``sum a^2``)."""
        H, W = self.f.shape
        g = st["g"]
        My = sfft.next_fast_len(3 * h - 2)
        Mx = sfft.next_fast_len(3 * w - 2, real=True)
        msq = np.broadcast_to(self._mult_row(Mx) / (My * Mx), (My, Mx // 2 + 1))
        sy_ = np.arange(-(h - 1), h) % My
        sx_ = np.arange(-(w - 1), w) % Mx

        def small_spec(X, rows, cols):  # half spectrum on the small grid of X placed at rows x cols
            grid = np.zeros((My, Mx))
            grid[np.ix_(rows, cols)] = X
            return sfft.rfft2(grid)

        ac_small, conv = kernels
        cache_t = self._torus_cache.get("t_small")
        if cache_t is None or cache_t[0] is not t_key or cache_t[1] != (h, w):
            wy, wx = self.window
            Ts = T[np.ix_(wy + np.arange(-(h - 1), h), wx + np.arange(-(w - 1), w))]
            cache_t = (t_key, (h, w), small_spec(Ts, sy_, sx_).real * msq)
            self._torus_cache["t_small"] = cache_t
        wa = st.get("wa")  # AC near zero is the same for every block of one image
        if wa is None or wa[0] is not t_key or wa[1] != (h, w):
            wa = (t_key, (h, w), np.stack([cache_t[2].ravel(), (small_spec(ac_small, sy_, sx_).real * msq).ravel()],
                                          axis=1))
            st["wa"] = wa
        wa = wa[2]
        w_conv = (small_spec(conv, np.arange(2 * h - 1), np.arange(2 * w - 1)) * msq).ravel()
        grown = g[np.ix_((y0 + np.arange(-(h - 1), 2 * h - 1)) % H, (x0 + np.arange(-(w - 1), 2 * w - 1)) % W)]
        w_grown = (small_spec(grown, np.arange(-(h - 1), 2 * h - 1) % My, np.arange(-(w - 1), 2 * w - 1) % Mx) * msq)
        return {"shape": (My, Mx), "wa": wa, "w_conv": w_conv, "w_grown": w_grown.ravel(), "wsq": msq.ravel()}

    def _candidate_terms(self, d: np.ndarray, block: dict, small: dict) -> tuple[np.ndarray, np.ndarray]:
        """``lin (k, 3)`` and ``quad (k,)`` of the block changes ``d (k, h, w)``."""
        H, W = self.f.shape
        k, h, w = d.shape
        M_r, M_c = block["M_r"], block["M_c"]
        flat = d.reshape(k, h * w)
        # rfft2(d, s=shape) without transforming the zero rows (the same bytes, a third of the time)
        My, Mx = small["shape"]
        D = sfft.fft(sfft.rfft(d, n=Mx, axis=2), n=My, axis=1, overwrite_x=True).reshape(k, -1).astype(np.complex128)
        A = D.real**2 + D.imag**2
        a_lin = A @ small["wa"]  # sum a T, sum a AC
        a_sq = (A * A) @ small["wsq"]
        # sum Re(z conj(v)) as float inner products of the interleaved (re, im) views
        cv = (D * D).view(np.float64) @ small["w_conv"].view(np.float64)
        cub = (A * D).view(np.float64) @ small["w_grown"].view(np.float64)
        f64 = flat.astype(np.float64)
        sd = f64.sum(axis=1)
        lin = f64 @ block["fields"]
        lin[:, 0] += sd * sd
        lin[:, 1] += a_lin[:, 0]
        lin[:, 2] += a_lin[:, 1]
        q = 2.0 * a_lin[:, 1] + 2.0 * cv + 4.0 * cub + a_sq
        if M_r is not None:
            cr = (flat @ M_r).astype(np.float64)
            q -= 2.0 * (cr * (cr + cr[:, (-np.arange(W)) % W])).sum(axis=1)
        if M_c is not None:
            cc = (flat @ M_c).astype(np.float64)
            q -= 2.0 * (cc * (cc + cc[:, (-np.arange(H)) % H])).sum(axis=1)
        if M_r is not None and M_c is not None:  # the corner (H / 2, W / 2) is on both lines, its own reflection
            q += 4.0 * cr[:, W // 2] ** 2
        return lin, q

    @staticmethod
    def _mult_row(M1: int) -> np.ndarray:
        """``mult(kx) (M1 // 2 + 1,)``: how many columns of a full spectrum a half-spectrum column stands for."""
        mult = np.full(M1 // 2 + 1, 2.0)
        mult[0] = 1.0
        if M1 % 2 == 0:
            mult[-1] = 1.0
        return mult

    def _windowed_sums(self, y0: int, x0: int, deltas: np.ndarray, T: np.ndarray, workers: int | None):
        """``(lin (K, 3), quad (K,), halves)`` of a window smaller than the torus (:meth:`l2_of_changes`):
        per candidate, the change spectrum on the grown grid and the half window ``dy >= 0``."""
        K, h, w = deltas.shape
        wy = self.window[0]
        (M0, M1), _, _ = self._half_plan(h, w)
        G2 = self._grown_spectrum(y0, x0, h, w)
        weights, sq = self._weights(h, w, T)
        half = np.empty((K, wy + 1, M1), dtype=self.fft_dtype)
        deltas = deltas.astype(self.fft_dtype, copy=False)
        lin = np.empty((K, 3))
        quad = np.empty(K)

        def chunk(lo: int, hi: int) -> None:
            spec = self._change_spectra(G2, deltas[lo:hi], (M0, M1))
            part = self._halves(spec, M1)
            half[lo:hi] = part
            flat = part.reshape(hi - lo, -1)
            quad[lo:hi] = np.einsum("kj,kj,j->k", flat, flat, sq)
            # (3, n) @ (n, k): OpenBLAS is slow on the thin (k, n) @ (n, 3) shapes
            lin[lo:hi] = (weights @ flat.T).T

        bounds = list(range(0, K, _CHUNK)) + [K]
        jobs = list(zip(bounds[:-1], bounds[1:], strict=True))
        _run_chunks(chunk, jobs, max(1, min(int(workers or 1), len(jobs))))
        return lin, quad, half

    def l2_of_changes(self, y0: int, x0: int, deltas: np.ndarray, target: np.ndarray, *, workers: int | None = None):
        """E_L2 ``(K,)`` of the standardized windows after each change, and the changes' half windows.

        ``deltas (K, h, w)`` are block changes at ``(y0, x0)`` (wrapping). With ``n`` window
        entries, ``mean(z^2) = 1`` and ``mean(z) = 0`` give
        ``E = 1 + mean(T^2) - 2 (<A, T> / n - mean(A) mean(T)) / std(A)`` for ``A = ac + dAC``, so
        each candidate needs ``sum dAC``, ``<dAC, T>``, ``<dAC, ac>`` and ``sum dAC^2`` over the window.

        ``dAC`` is even (``dAC(-d) = dAC(d)``) and its spectrum ``2 Re(conj(D) G) + |D|^2`` real, so
        one half of the window carries everything: the inverse transform runs as a real-input FFT
        along the rows (``ihfft``, half the work of a complex one) followed by inverse transforms of
        only the ``wy + 1`` rows ``dy >= 0``. The forward transform of each block skips its zero
        rows (one transform per block row, then the column transforms). The four sums are inner
        products of the half windows with fixed weights. When the window holds every displacement
        of the torus (the paper's unwindowed S_T; :meth:`_spectral`), no full-size transform runs
        per candidate (:meth:`_spectral_l2`): the sums split into fixed fields of the current image
        on the block (cut from whole-image fields computed once per image), terms of the block's own autocorrelation
        on a small grid (one small FFT per candidate) and the half-period lines outside the window
        (two matrix products per tile's candidates).

        Candidates go through in chunks of ``_CHUNK`` (small arrays stay in cache); ``workers``
        threads (default 1) share the chunks. In the windowed case the chunks are the same for any
        number of threads, so the values are the same bytes for any ``workers``; the spectral case
        cuts one chunk per thread, and its values differ across ``workers`` by an ulp.
        Exact: the same values as recomputing S_T of the whole image, up to floating rounding
        (float32 transforms: about 1e-7 relative).

        The target's spectral weights are kept while the same array object comes again (modify a
        target in place only as a new array).

        Returns ``values (K,)`` and ``halves (K, wy + 1, M1)``: ``halves[k, dy, dx mod M1]`` is
        ``dAC_k(dy, dx)`` for ``0 <= dy <= wy``, ``|dx| <= wx`` (:meth:`window_from_half`); ``halves``
        is None in the spectral case (:meth:`apply` then computes the accepted change's window).
        """
        deltas = self._blocks(deltas)
        K, h, w = deltas.shape
        T = np.asarray(target, dtype=np.float64)
        wshape = (2 * self.window[0] + 1, 2 * self.window[1] + 1)
        if T.shape != wshape:
            raise ValueError(f"target shape {T.shape} differs from the window {wshape}")
        spectral = self._spectral(h, w)
        if spectral:
            with one_blas_thread():
                lin, quad, sums = self._spectral_l2(y0, x0, deltas, T, workers)
            half = None
        else:
            lin, quad, half = self._windowed_sums(y0, x0, deltas, T, workers)
            sums = self._base_sums(T)
        return self._l2(sums, lin, quad, T.size), half

    @staticmethod
    def _l2(sums: tuple, lin: np.ndarray, quad: np.ndarray, n: int) -> np.ndarray:
        """E_L2 ``(K,)`` from the window's sums ``(sum ac, <ac, T>, sum ac^2, mean T, mean T^2)`` and
        the changes' ``lin (K, 3)`` and ``quad (K,)`` over ``n`` window entries."""
        ac_sum, ac_t, ac_sq, t_mean, t_sq = sums
        s1 = ac_sum + lin[:, 0]
        p = ac_t + lin[:, 1]
        s2 = ac_sq + 2.0 * lin[:, 2] + quad
        mean = s1 / n
        var = np.maximum(s2 / n - mean * mean, 0.0)
        sd = np.where(var > 0, np.sqrt(var), np.inf)
        corr = (p / n - mean * t_mean) / sd
        return 1.0 + t_sq - 2.0 * corr

    def value(self, target: np.ndarray, block: tuple[int, int]) -> float:
        """E_L2 of the standardized window of the current ``f`` against ``target`` (what
        :meth:`l2_of_changes` gives a zero change at a block ``(h, w)``): with the whole torus as
        window, from the image's spectrum (:meth:`_window_sums`; :meth:`prepare` then reuses that
        spectrum until ``f`` changes), otherwise from ``ac``."""
        T = np.asarray(target, dtype=np.float64)
        if self._spectral(*block):
            with self._lock:
                sums = self._image_sums(self._torus_state(), *block, T)[0]
        else:
            sums = self._base_sums(T)
        return float(self._l2(sums, np.zeros((1, 3)), np.zeros(1), T.size)[0])

    def assign(self, y0: int, x0: int, block: np.ndarray) -> None:
        """Set ``f`` to ``block (h, w)`` at ``(y0, x0)`` (wrapping); :attr:`ac` is recomputed from
        ``f`` when next read (one full-image transform for any number of blocks assigned)."""
        block = np.asarray(block, dtype=np.float64)
        H, W = self.f.shape
        ry = (y0 + np.arange(block.shape[0])) % H
        rx = (x0 + np.arange(block.shape[1])) % W
        self.f[np.ix_(ry, rx)] = block
        self._ac = None
        self._ac_version += 1

    def change_window(self, y0: int, x0: int, delta: np.ndarray) -> np.ndarray:
        """``dAC (2 wy + 1, 2 wx + 1)`` float64 of one block change ``delta (h, w)`` at ``(y0, x0)``
        (the half-window transforms of :meth:`l2_of_changes` for a single block)."""
        delta = np.asarray(delta, dtype=self.fft_dtype)
        h, w = delta.shape
        shape = self._half_plan(h, w)[0]
        spec = self._change_spectra(self._grown_spectrum(y0, x0, h, w), delta[None], shape)
        return self.window_from_half(self._halves(spec, shape[1])[0])

    def window_from_half(self, half: np.ndarray) -> np.ndarray:
        """Full window ``(2 wy + 1, 2 wx + 1)`` float64 of one half window from :meth:`l2_of_changes`."""
        wy, wx = self.window
        bottom = half[:, np.arange(-wx, wx + 1) % half.shape[-1]].astype(np.float64)
        return np.concatenate([bottom[:0:-1, ::-1], bottom], axis=0)

    def apply(self, y0: int, x0: int, delta: np.ndarray, *, dac: np.ndarray | None = None) -> None:
        """Add ``delta (h, w)`` to ``f`` at ``(y0, x0)`` (wrapping) and update ``ac``.

        ``dac`` is the matching window when already computed (:meth:`window_from_half`), otherwise
        :meth:`change_window` computes it; with the whole torus as window (the spectral evaluation)
        nothing is computed and :attr:`ac` is recomputed from ``f`` when next read.
        """
        delta = np.asarray(delta, dtype=np.float64)
        H, W = self.f.shape
        lazy = dac is None and self._spectral(*delta.shape)
        if dac is None and not lazy:
            dac = self.change_window(y0, x0, delta)
        ry = (y0 + np.arange(delta.shape[0])) % H
        rx = (x0 + np.arange(delta.shape[1])) % W
        self.f[np.ix_(ry, rx)] += delta
        # the spectral evaluation reads f only: ac is recomputed from f when next read
        self._ac = None if lazy or self._ac is None else self._ac + dac
        self._ac_version += 1
