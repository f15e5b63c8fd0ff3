"""Symmetry representations, objectives and filters against brute-force references."""

import numpy as np
import pytest

from synthkit.core import symmetry as sy


def brute_toroidal(f, wy, wx):
    out = np.zeros((2 * wy + 1, 2 * wx + 1))
    for dy in range(-wy, wy + 1):
        for dx in range(-wx, wx + 1):
            out[wy + dy, wx + dx] = (f * np.roll(f, (-dy, -dx), (0, 1))).sum()
    return out / (f * f).sum()


def brute_zero(f, wy, wx):
    H, W = f.shape
    out = np.zeros((2 * wy + 1, 2 * wx + 1))
    for dy in range(-wy, wy + 1):
        for dx in range(-wx, wx + 1):
            a = f[max(0, -dy) : H - max(0, dy), max(0, -dx) : W - max(0, dx)]
            b = f[max(0, dy) : H - max(0, -dy), max(0, dx) : W - max(0, -dx)]
            out[wy + dy, wx + dx] = (a * b).sum()
    return out / (f * f).sum()


def lattice(H, W, P, *, r=2.0, phase=(0, 0)):
    yy, xx = np.mgrid[0:H, 0:W]
    dy = (yy - phase[0]) % P
    dx = (xx - phase[1]) % P
    d = np.hypot(np.minimum(dy, P - dy), np.minimum(dx, P - dx))
    return (d <= r).astype(np.float64)


@pytest.fixture
def rng():
    return np.random.default_rng(1)


def test_translational_toroidal_matches_brute_force(rng):
    f = rng.random((9, 12))
    S = sy.translational(f, standardize=False)
    assert S.shape == (9, 11)
    np.testing.assert_allclose(S, brute_toroidal(f, 4, 5), atol=1e-12)
    assert S[4, 5] == pytest.approx(1.0)


def test_translational_zero_padded_matches_brute_force(rng):
    f = rng.random((7, 6))
    S = sy.translational(f, mode="zero", standardize=False)
    assert S.shape == (13, 11)
    np.testing.assert_allclose(S, brute_zero(f, 6, 5), atol=1e-12)
    Sw = sy.translational(f, mode="zero", window=(2, 3), standardize=False)
    np.testing.assert_allclose(Sw, brute_zero(f, 2, 3), atol=1e-12)


def test_standardized_has_mean0_var1_and_window(rng):
    f = rng.random((20, 16))
    S = sy.translational(f, window=(3, 5))
    assert S.shape == (7, 11)
    assert S.mean() == pytest.approx(0.0, abs=1e-12)
    assert S.var() == pytest.approx(1.0)
    np.testing.assert_allclose(S, sy.standardize(brute_toroidal(f, 3, 5)), atol=1e-10)


def test_toroidal_transform_ignores_signal_mean(rng):
    f = rng.random((16, 16))
    np.testing.assert_allclose(sy.translational(f), sy.translational(f + 3.0), atol=1e-9)
    np.testing.assert_allclose(sy.translational(f), sy.translational(1.0 - f), atol=1e-9)


def test_window_beyond_image_extends_periodically(rng):
    g = rng.random((8, 10))
    big = sy.translational(g, window=(11, 13), standardize=False)
    tiled = np.tile(g, (4, 3))
    np.testing.assert_allclose(big, sy.translational(tiled, window=(11, 13), standardize=False), atol=1e-12)


def test_float32_stays_float32(rng):
    f = rng.random((32, 32)).astype(np.float32)
    S = sy.translational(f)
    assert S.dtype == np.float32
    np.testing.assert_allclose(S, sy.translational(f.astype(np.float64)), atol=1e-4)


def test_lattice_peak_at_period():
    f = lattice(64, 64, 8)
    S = sy.translational(f, window=(12, 12))
    dy, dx = sy.strongest_peak(S)
    assert (abs(dy), abs(dx)) in {(8, 0), (0, 8)}


@pytest.mark.parametrize("fn", [sy.translational, sy.rotational, sy.reflective])
def test_constant_signal_rejected(fn):
    with pytest.raises(ValueError, match="constant"):
        fn(np.full((16, 16), 0.5))


def test_bad_window_and_mode(rng):
    f = rng.random((8, 8))
    with pytest.raises(ValueError, match="mode"):
        sy.translational(f, mode="wrap")
    with pytest.raises(ValueError, match="exceeds"):
        sy.translational(f, mode="zero", window=(8, 1))


def _rotated_pattern(n, fold):
    yy, xx = np.mgrid[0:n, 0:n] - (n - 1) / 2.0
    phi = np.arctan2(yy, xx)
    r = np.hypot(yy, xx)
    return (1.0 + np.cos(fold * phi)) * np.exp(-((r - n / 4) ** 2) / 20.0)


def test_rotational_matches_direct_polar_sum(rng):
    f = rng.random((31, 31))
    S = sy.rotational(f, n_angles=36, standardize=False)
    P, r = sy.polar_resample(f, n_angles=36)
    ref = np.array([(r[:, None] * P * np.roll(P, -k, axis=1)).sum() for k in range(36)])
    np.testing.assert_allclose(S, ref / (r[:, None] * P**2).sum(), atol=1e-12)


def test_rotational_finds_fold():
    S = sy.rotational(_rotated_pattern(65, 5), n_angles=360, standardize=False)
    assert S[72] == pytest.approx(1.0, abs=1e-4)
    assert S[36] < 0.9
    assert np.all(S[[144, 216, 288]] > 0.999)
    assert S[[36, 108, 180]].max() < 0.9


def test_reflective_matches_direct_sum_and_finds_axis(rng):
    f = rng.random((31, 31))
    S = sy.reflective(f, n_angles=24, standardize=False)
    P, r = sy.polar_resample(f, n_angles=24)
    idx = np.arange(24)
    ref = np.array([(r[:, None] * P * P[:, (j - idx) % 24]).sum() for j in range(24)])
    np.testing.assert_allclose(S, ref / (r[:, None] * P**2).sum(), atol=1e-12)
    # mirror image about the horizontal line through the centre: theta = 0
    g = rng.random((31, 31))
    g = g + g[::-1]
    Sg = sy.reflective(g, n_angles=180, standardize=False)
    assert int(np.argmax(Sg)) == 0
    assert Sg[0] == pytest.approx(1.0, abs=1e-9)
    # and about the vertical line: theta = 90 degrees
    Sv = sy.reflective(g.T, n_angles=180, standardize=False)
    assert int(np.argmax(Sv)) == 90


def test_polar_bad_centre():
    with pytest.raises(ValueError, match="outside"):
        sy.polar_resample(np.ones((8, 8)), center=(20, 3))


def test_objectives_exact():
    S = np.array([[1.0, 2.0], [3.0, 4.0]])
    T = np.array([[1.0, 0.0], [3.0, 2.0]])
    assert sy.e_l2(S, T) == pytest.approx((4 + 4) / 4)
    assert sy.e_symm(S) == pytest.approx(1.25)
    with pytest.raises(ValueError, match="shape"):
        sy.e_l2(S, T[:1])


def test_e_symm_higher_for_lattice_than_noise(rng):
    lat = lattice(64, 64, 8)
    noise = rng.random((64, 64))
    assert sy.e_symm(sy.translational(lat, standardize=False)) > 10 * sy.e_symm(
        sy.translational(noise, standardize=False)
    )


def test_filters_identities(rng):
    S = sy.translational(rng.random((16, 16)))
    np.testing.assert_allclose(sy.blur(S, 0.0), S, atol=1e-12)
    np.testing.assert_allclose(sy.sharpen(S, 1.0), S, atol=1e-12)
    np.testing.assert_allclose(sy.contrast(S, 1.0), S, atol=1e-9)
    np.testing.assert_allclose(sy.scale(S, 1.0), S, atol=1e-12)
    np.testing.assert_allclose(sy.rotate(S, 0.0), S, atol=1e-12)


def test_filter_effects():
    S = sy.translational(lattice(64, 64, 8, r=1.5), window=(20, 20))
    assert sy.blur(S, 2.0).max() < S.max()
    assert sy.sharpen(S, 4.0).max() > S.max()
    up = sy.contrast(S, 3.0)
    down = sy.contrast(S, 0.3)
    assert up.max() != pytest.approx(down.max())
    dy, dx = sy.strongest_peak(sy.scale(S, 2.0))
    assert (abs(dy), abs(dx)) in {(16, 0), (0, 16)}
    stripes = np.tile((np.arange(32) % 8 < 3).astype(float)[:, None], (1, 32))
    Ss = sy.translational(stripes + 0.01 * np.random.default_rng(0).random((32, 32)), window=(12, 12))
    # horizontal stripes repeat along y; rotated by 90 degrees they repeat along x
    rot = sy.rotate(Ss, 90.0)
    assert Ss[12, 12 + 4] > 1.0 and Ss[12 + 4, 12] < 0.0
    assert rot[12 + 4, 12] > 1.0 and rot[12, 12 + 4] < 0.0


def test_filter_errors():
    S = np.zeros(8)
    with pytest.raises(ValueError, match="2-D"):
        sy.scale(np.arange(8.0), 2.0)
    with pytest.raises(ValueError, match="sigma"):
        sy.blur(S, -1.0)
    with pytest.raises(ValueError, match="constant"):
        sy.contrast(S, 2.0)


def test_signals():
    img = np.zeros((8, 8, 3), dtype=np.float32)
    img[..., 0] = 1.0
    lum = sy.f_lum(img)
    assert lum.dtype == np.float32
    assert lum[0, 0] == pytest.approx(0.299)
    assert sy.f_inv_lum(img)[0, 0] == pytest.approx(0.701)
    step = np.zeros((8, 8))
    step[:, 4:] = 1.0
    edge = sy.f_edge(step)
    assert edge.max() == pytest.approx(1.0)
    assert edge[:, 0].max() == 0.0 and edge[:, 3:5].min() > 0.5
    with pytest.raises(ValueError, match="unknown signal"):
        sy.signal(img, "hue")


def test_translational_overlap_is_a_correlation_coefficient(rng):
    """mode "overlap": exact brute-force value on a small signal; 1 at zero displacement; a
    period that does not divide the size still gives ~1 (the toroidal S_T does not); the same
    for f and 1 - f."""
    f = rng.random((7, 9))
    S = sy.translational(f, mode="overlap", window=(2, 3), standardize=False)
    g = f - f.mean()
    var = (g * g).mean()
    dy, dx = 1, -2
    a = g[max(0, -dy) : 7 - max(0, dy), max(0, -dx) : 9 - max(0, dx)]
    b = g[max(0, dy) : 7 + min(0, dy), max(0, dx) : 9 + min(0, dx)]
    assert S[2 + dy, 3 + dx] == pytest.approx((a * b).mean() / var)
    assert S[2, 3] == pytest.approx(1.0)
    np.testing.assert_allclose(sy.translational(1 - f, mode="overlap", window=(2, 3), standardize=False), S)
    x = np.arange(50)
    stripes = np.tile(np.sin(2 * np.pi * x / 7.0), (50, 1))  # period 7 does not divide 50
    St = sy.translational(stripes, mode="overlap", window=(3, 10), standardize=False)
    assert St[3, 10 + 7] > 0.99
    Storus = sy.translational(stripes, mode="toroidal", window=(3, 10), standardize=False)
    assert Storus[3, 10 + 7] < St[3, 10 + 7] - 0.03  # the wrap-around columns are out of phase


def test_whole_period_crop_of_stripes_and_a_lattice():
    """Stripes of period 10 along x on a 57 x 64 image: 60 columns (6 periods); down the rows
    nothing varies, the autocorrelation is flat and its first displacement (4 px) wins: 56 rows.
    A dot lattice of period (12, 9) on 50 x 50: 48 rows, 45 columns. Short axes keep their size."""
    x = np.arange(64)
    stripes = np.tile(np.sin(2 * np.pi * x / 10.0), (57, 1))
    h, w = sy.whole_period_crop(stripes)
    assert (h, w) == (56, 60)
    yy, xx = np.mgrid[0:50, 0:50]
    dots = ((yy % 12 < 3) & (xx % 9 < 3)).astype(np.float64)
    assert sy.whole_period_crop(dots) == (48, 45)
    assert sy.whole_period_crop(dots[:8, :]) == (8, 45)


@pytest.mark.parametrize("shape", [(16, 16), (15, 16), (16, 17), (13, 11)])
def test_e_symm_toroidal_matches_the_transform(shape):
    """E_symm from the power spectrum (no inverse transform) equals that of the raw S_T window,
    for even sizes (the half-period lines left out) and odd ones; other windows take the plain way."""
    f = np.random.default_rng(sum(shape)).random(shape)
    ref = sy.e_symm(sy.translational(f, standardize=False))
    assert sy.e_symm_toroidal(f) == pytest.approx(ref, rel=1e-12)
    small = sy.e_symm(sy.translational(f, window=(3, 2), standardize=False))
    assert sy.e_symm_toroidal(f, window=(3, 2)) == pytest.approx(small, rel=1e-12)
