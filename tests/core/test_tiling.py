"""Toroidal cut tiles: minimum-error boundary cuts across the wraps, their seams and the seam fix."""

import numpy as np
import pytest

from synthkit.core.tiling import cut_tile, fix_seams, seam_masks


def test_cut_tile_of_a_periodic_image_is_one_period():
    """An image of period 12 and size 12 + overlap: the overlapped copies agree, the tile is one period."""
    rng = np.random.default_rng(0)
    period = rng.random((12, 12, 3)).astype(np.float32)
    img = np.tile(period, (2, 2, 1))[:16, :16]
    tile, source = cut_tile(img, 4)
    assert tile.shape == (12, 12, 3) and source.shape == (12, 12, 2)
    np.testing.assert_array_equal(tile, period)
    np.testing.assert_array_equal(img[source[..., 0], source[..., 1]], tile)
    with pytest.raises(ValueError, match="overlap"):
        cut_tile(img, 8)


def test_seam_masks_of_the_identity_are_the_wrap_steps():
    source = np.stack(np.mgrid[0:5, 0:7], axis=2)
    mx, my = seam_masks(source)
    assert mx.sum() == 5 and mx[:, -1].all()
    assert my.sum() == 7 and my[-1].all()


def test_cut_tile_seams_follow_the_cut():
    """On noise the cut leaves the wrap: every row has a seam step in the column overlap band (or
    on the wrap, where the cut runs along it), and outside the row overlap band there are no others
    (inside it the row cut's steps from row to row cross columns too); the source map is what the
    tile shows."""
    rng = np.random.default_rng(1)
    img = rng.random((40, 48)).astype(np.float32)
    tile, source = cut_tile(img, 6)
    assert tile.shape == (34, 42)
    np.testing.assert_array_equal(img[source[..., 0], source[..., 1]], tile)
    mx, _ = seam_masks(source)
    band = np.zeros(42, dtype=bool)
    band[:6] = True
    band[-1] = True
    assert not mx[6:-1, ~band].any()
    assert (mx[:, band].sum(axis=1) >= 1).all()


def test_fix_seams_makes_seam_steps_the_mean_of_their_neighbours():
    rng = np.random.default_rng(2)
    img = np.clip(0.5 + 0.2 * rng.standard_normal((48, 48, 3)), 0, 1).astype(np.float32)
    img[:, 40:] += 0.2  # a brightness jump the cut cannot avoid
    img = np.clip(img, 0, 1)
    tile, source = cut_tile(img, 8)
    fixed = fix_seams(tile, source, radius=4).astype(np.float64)
    mx, my = seam_masks(source)
    for v, m in ((fixed, mx), (fixed.transpose(1, 0, 2), my.T)):
        raw = np.roll(v, -1, axis=1) - v  # raw[:, x]: the step x -> x + 1
        miss = raw - 0.5 * (np.roll(raw, 1, axis=1) + np.roll(raw, -1, axis=1))
        assert np.abs(miss[m]).mean() < 0.05 * np.abs(raw[m]).mean()
    # farther than the radius from every seam step's pixels (on the torus) nothing changes
    h, w = tile.shape[:2]
    far = np.ones((h, w), dtype=bool)
    ys, xs = np.nonzero(mx | my)
    for dy in range(-6, 7):
        for dx in range(-6, 7):
            far[(ys + dy) % h, (xs + dx) % w] = False
    np.testing.assert_allclose(fixed[far], tile[far], atol=1e-6)
