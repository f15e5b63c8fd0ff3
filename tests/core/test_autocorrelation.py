"""IncrementalAutocorrelation against full recomputes of the windowed autocorrelation."""

import numpy as np
import pytest

from synthkit.core import symmetry as sy
from synthkit.core.autocorrelation import IncrementalAutocorrelation


@pytest.fixture
def rng():
    return np.random.default_rng(1)


def test_incremental_matches_full_recompute(rng):
    f = rng.random((40, 36))
    inc = IncrementalAutocorrelation(f, window=(6, 9))
    deltas = rng.standard_normal((4, 10, 12))
    dac = inc.delta(35, 30, deltas)  # wraps in both axes
    ry, rx = (35 + np.arange(10)) % 40, (30 + np.arange(12)) % 36
    for k in range(4):
        g = f.copy()
        g[np.ix_(ry, rx)] += deltas[k]
        ref = sy.translational(g, window=(6, 9), standardize=False) * (g * g).sum()
        np.testing.assert_allclose(inc.ac + dac[k], ref, atol=1e-9)
    inc.apply(35, 30, deltas[2])
    g = f.copy()
    g[np.ix_(ry, rx)] += deltas[2]
    np.testing.assert_allclose(inc.f, g)
    np.testing.assert_allclose(inc.ac, sy.translational(g, window=(6, 9), standardize=False) * (g * g).sum())


def test_incremental_rejects_large_blocks_and_windows(rng):
    with pytest.raises(ValueError, match="window"):
        IncrementalAutocorrelation(rng.random((10, 10)), window=(5, 1))
    inc = IncrementalAutocorrelation(rng.random((10, 10)), window=(2, 2))
    with pytest.raises(ValueError, match="half"):
        inc.delta(0, 0, np.ones((6, 2)))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_l2_of_changes_matches_full_objective(rng, dtype):
    f = rng.random((48, 40))
    T = sy.translational(rng.random((48, 40)), window=(7, 6))
    inc = IncrementalAutocorrelation(f, window=(7, 6), offset=f.mean(), fft_dtype=dtype)
    deltas = 0.3 * rng.standard_normal((5, 9, 8))
    values, halves = inc.l2_of_changes(44, 3, deltas, T)
    ry, rx = (44 + np.arange(9)) % 48, (3 + np.arange(8)) % 40
    for k in range(5):
        g = f.copy()
        g[np.ix_(ry, rx)] += deltas[k]
        ref = sy.e_l2(sy.translational(g, window=(7, 6)), T)
        assert values[k] == pytest.approx(ref, abs=1e-9 if dtype == np.float64 else 1e-5)
    # the half windows hold the windowed change (even: the other half is its point reflection)
    dac = np.stack([inc.window_from_half(hv) for hv in halves])
    np.testing.assert_allclose(dac, inc.delta(44, 3, deltas), atol=1e-9 if dtype == np.float64 else 1e-3)
    with pytest.raises(ValueError, match="target shape"):
        inc.l2_of_changes(0, 0, deltas, T[:-1])
    with pytest.raises(ValueError, match="half"):
        inc.l2_of_changes(0, 0, np.ones((25, 2)), T)


def test_l2_of_changes_large_window_after_updates_and_threads(rng):
    """Rows: window at the largest distinct displacement (the grid is the image's period); columns:
    a grown grid larger than block + 2 window; a batch not a multiple of the chunk, two targets in
    turn and accepted changes in between: every value equals E_L2 of the recomputed S_T; one or two
    threads give the same bytes."""
    H, W, win = 50, 64, (24, 10)
    f = rng.random((H, W))
    targets = [sy.translational(rng.random((H, W)), window=win), sy.translational(rng.random((H, W)), window=win)]
    inc = IncrementalAutocorrelation(f, window=win, offset=f.mean())
    g = f.copy()
    for step, (y0, x0) in enumerate([(10, 40), (47, 1), (20, 20)]):
        deltas = 0.5 * rng.standard_normal((7, 7, 11))
        T = targets[step % 2]
        values, halves = inc.l2_of_changes(y0, x0, deltas, T, workers=1)
        values2, halves2 = inc.l2_of_changes(y0, x0, deltas, T, workers=2)
        assert values.tobytes() == values2.tobytes() and halves.tobytes() == halves2.tobytes()
        ry, rx = (y0 + np.arange(7)) % H, (x0 + np.arange(11)) % W
        for k in range(7):
            trial = g.copy()
            trial[np.ix_(ry, rx)] += deltas[k]
            assert values[k] == pytest.approx(sy.e_l2(sy.translational(trial, window=win), T), abs=1e-10)
        best = int(np.argmin(values))
        inc.apply(y0, x0, deltas[best], dac=inc.window_from_half(halves[best]))
        g[np.ix_(ry, rx)] += deltas[best]
        c = g - f.mean()
        ref = sy.translational(c, window=win, standardize=False) * (c * c).sum()
        np.testing.assert_allclose(inc.ac, ref, atol=1e-9)


@pytest.mark.parametrize("shape", [(48, 40), (49, 40), (48, 41), (47, 45)])
def test_l2_of_changes_unwindowed_is_spectral_and_exact(rng, shape):
    """All displacements (the paper's S_T): Parseval sums without inverse transforms, the half-period
    lines of even sizes left out as in the window; values equal E_L2 of the recomputed S_T, and
    apply without a window (change_window) keeps ac exact."""
    H, W = shape
    win = ((H - 1) // 2, (W - 1) // 2)
    f = rng.random(shape)
    T = sy.translational(rng.random(shape), window=win)
    inc = IncrementalAutocorrelation(f, window=win, offset=f.mean())
    deltas = 0.4 * rng.standard_normal((6, 7, 11))
    values, halves = inc.l2_of_changes(H - 3, 5, deltas, T, workers=2)
    assert halves is None
    ry, rx = (H - 3 + np.arange(7)) % H, (5 + np.arange(11)) % W
    for k in range(6):
        g = f.copy()
        g[np.ix_(ry, rx)] += deltas[k]
        assert values[k] == pytest.approx(sy.e_l2(sy.translational(g, window=win), T), abs=1e-10)
    np.testing.assert_allclose(inc.change_window(H - 3, 5, deltas[4]), inc.delta(H - 3, 5, deltas[4])[0], atol=1e-9)
    inc.apply(H - 3, 5, deltas[4])
    g = f.copy()
    g[np.ix_(ry, rx)] += deltas[4]
    c = g - f.mean()
    np.testing.assert_allclose(inc.ac, sy.translational(c, window=win, standardize=False) * (c * c).sum(), atol=1e-9)
    # the cached ac weights follow the update
    values2, _ = inc.l2_of_changes(0, 0, deltas[:2], T)
    for k in range(2):
        g2 = g.copy()
        g2[:7, :11] += deltas[k]
        assert values2[k] == pytest.approx(sy.e_l2(sy.translational(g2, window=win), T), abs=1e-10)


def test_spectral_float32_and_lazy_ac_after_apply(rng):
    """The spectral evaluation in single precision (the guided walk's) stays within 1e-6 of the full
    recompute, and after apply without a window ac is recomputed from f when read."""
    H, W = 64, 60
    win = ((H - 1) // 2, (W - 1) // 2)
    f = rng.random((H, W))
    T = sy.translational(rng.random((H, W)), window=win)
    inc = IncrementalAutocorrelation(f, window=win, offset=f.mean(), fft_dtype=np.float32)
    deltas = 0.3 * rng.standard_normal((5, 16, 16))
    g = f.copy()
    for y0, x0 in ((60, 55), (10, 20)):
        values, _ = inc.l2_of_changes(y0, x0, deltas, T, workers=2)
        ry, rx = (y0 + np.arange(16)) % H, (x0 + np.arange(16)) % W
        for k in range(5):
            trial = g.copy()
            trial[np.ix_(ry, rx)] += deltas[k].astype(np.float32)
            assert values[k] == pytest.approx(sy.e_l2(sy.translational(trial, window=win), T), rel=1e-6)
        inc.apply(y0, x0, deltas[2])
        g[np.ix_(ry, rx)] += deltas[2]
    c = g - f.mean()
    np.testing.assert_allclose(inc.ac, sy.translational(c, window=win, standardize=False) * (c * c).sum(), atol=1e-9)


def test_blocks_scored_in_threads_against_one_image_give_the_same_values(rng):
    """The guided walk scores the tiles of a batch against the same image from two threads, with
    the whole-image fields computed once: the values are the bytes of one thread, one block after
    the other; after assign, value() is E_L2 of the new image and the prepared work is redone."""
    from concurrent.futures import ThreadPoolExecutor

    shape = (48, 40)
    win = ((shape[0] - 1) // 2, (shape[1] - 1) // 2)
    f = rng.random(shape)
    T = sy.translational(rng.random(shape), window=win)
    deltas = 0.3 * rng.standard_normal((5, 8, 8))
    corners = [(9, 30), (40, 3), (20, 20)]
    a = IncrementalAutocorrelation(f, window=win, offset=f.mean(), fft_dtype=np.float32)
    b = IncrementalAutocorrelation(f, window=win, offset=f.mean(), fft_dtype=np.float32)
    plain = [a.l2_of_changes(y0, x0, deltas, T)[0] for y0, x0 in corners]
    with ThreadPoolExecutor(2) as pool:
        threaded = list(pool.map(lambda c: b.l2_of_changes(*c, deltas, T)[0], corners))
    for p, t in zip(plain, threaded, strict=True):
        np.testing.assert_array_equal(t, p)
    assert a.value(T, (8, 8)) == pytest.approx(sy.e_l2(sy.translational(f, window=win), T), rel=1e-6)
    g = f.copy()
    g[9:17, 30:38] += deltas[1]
    a.assign(9, 30, g[9:17, 30:38])
    assert a.value(T, (8, 8)) == pytest.approx(plain[0][1], rel=1e-6)
    assert a.value(T, (8, 8)) == pytest.approx(sy.e_l2(sy.translational(g, window=win), T), rel=1e-6)
    values = a.l2_of_changes(40, 3, deltas, T)[0]
    for k in range(5):
        trial = g.copy()
        trial[np.ix_((40 + np.arange(8)) % 48, 3 + np.arange(8))] += deltas[k]
        assert values[k] == pytest.approx(sy.e_l2(sy.translational(trial, window=win), T), rel=1e-6)
    windowed = IncrementalAutocorrelation(f, window=(5, 5))
    assert windowed.prepare(0, 0, 8, 8, T[:11, :11]) is None
    assert windowed.value(T[18:29, 15:26], (8, 8)) == pytest.approx(sy.e_l2(sy.translational(f, window=(5, 5)),
                                                                              T[18:29, 15:26]), rel=1e-9)
