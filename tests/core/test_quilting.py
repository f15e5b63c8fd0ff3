"""Image quilting building blocks against brute force on tiny inputs."""

import itertools

import numpy as np
import pytest

from synthkit.core import quilting as q


@pytest.fixture
def rng():
    return np.random.default_rng(3)


@pytest.mark.parametrize("size", [32, 33, 50, 64, 100, 512])
def test_tile_grid_covers_torus_with_overlap(size):
    ys = q.tile_grid(size, 32, 12)
    assert ys[0] == 0
    steps = np.diff(np.append(ys, ys[0] + size))
    assert steps.max() <= 20 and steps.min() >= 1
    assert (32 - steps).min() >= 12


def test_tile_grid_errors():
    with pytest.raises(ValueError, match="smaller than one patch"):
        q.tile_grid(20, 32, 12)
    with pytest.raises(ValueError, match="overlap"):
        q.tile_grid(64, 8, 8)


def test_overlap_costs_match_brute_force(rng):
    src = rng.random((9, 11, 3)).astype(np.float32)
    tgt = rng.random((4, 4, 3)).astype(np.float32)
    w = np.zeros((4, 4), dtype=np.float32)
    w[:, :2] = 1
    w[0, :] = 1
    cost = q.overlap_costs(src, tgt, w)
    assert cost.shape == (6, 8)
    for v, u in itertools.product(range(6), range(8)):
        ref = (w[..., None] * (src[v : v + 4, u : u + 4] - tgt) ** 2).sum()
        assert cost[v, u] == pytest.approx(ref, rel=1e-4, abs=1e-4)


def test_candidates_rules():
    cost = np.array([[4.0, 1.0, 1.05], [3.0, 1.2, 1.0]])
    np.testing.assert_array_equal(q.candidates(cost, tol=0.1), [[0, 1], [1, 2], [0, 2]])
    np.testing.assert_array_equal(q.candidates(cost, tol=None, k=2), [[0, 1], [1, 2]])
    zero = np.array([[0.0, 5.0], [0.0, 7.0]])
    np.testing.assert_array_equal(q.candidates(zero, tol=0.1), [[0, 0], [1, 0]])


def test_left_cut_is_minimum_over_all_paths(rng):
    err = rng.random((3, 5, 3))
    path = q.min_vertical_cuts(err)
    for k in range(3):
        best = np.inf
        for cols in itertools.product(range(3), repeat=5):
            if all(abs(a - b) <= 1 for a, b in itertools.pairwise(cols)):
                best = min(best, sum(err[k, y, c] for y, c in enumerate(cols)))
        assert sum(err[k, y, c] for y, c in enumerate(path[k])) == pytest.approx(best)
        assert np.all(np.abs(np.diff(path[k])) <= 1)


def test_boundary_masks_follow_the_seam():
    B = 8
    canvas = np.zeros((B, B), dtype=np.float32)
    patch = np.ones((1, B, B), dtype=np.float32)
    # the patch agrees with the canvas in column 2 only: the cut must run there
    patch[0, :, 2] = 0.0
    filled = np.zeros((B, B), dtype=bool)
    filled[:, :4] = True
    keep = q.boundary_masks(patch, canvas, filled, overlaps=(0, 4, 0, 0))[0]
    assert keep[:, 3:].all() and not keep[:, :2].any()
    assert keep[:, 2].all()
    # unfilled pixels always take the new patch, even without a cut side
    keep2 = q.boundary_masks(patch, canvas, np.zeros((B, B), bool), overlaps=(4, 4, 4, 4))[0]
    assert keep2.all()


def test_boundary_masks_all_sides_keep_centre(rng):
    B = 12
    canvas = rng.random((B, B, 3)).astype(np.float32)
    patches = rng.random((4, B, B, 3)).astype(np.float32)
    keep = q.boundary_masks(patches, canvas, np.ones((B, B), bool), overlaps=(4, 4, 4, 4))
    assert keep.shape == (4, B, B)
    assert keep[:, 4:8, 4:8].all()
    assert not keep[:, 0, 0].any()


def test_quilt_copies_source_pixels_and_is_deterministic(rng):
    src = rng.random((40, 40, 3)).astype(np.float32)
    a = q.quilt(src, (50, 70), patch=16, overlap=6, rng=5)
    b = q.quilt(src, (50, 70), patch=16, overlap=6, rng=5)
    assert a.image.shape == (50, 70, 3)
    np.testing.assert_array_equal(a.image, b.image)
    values = {tuple(v) for v in src.reshape(-1, 3)}
    assert all(tuple(v) in values for v in a.image.reshape(-1, 3)[::7])
    assert a.origins.shape == (len(a.ys), len(a.xs), 2)
    assert a.origins.max() <= 40 - 16


def test_quilt_of_periodic_source_stays_seamless():
    # a source that is periodic with the tile step: perfect overlaps exist everywhere
    y, x = np.mgrid[0:64, 0:64]
    src = (0.5 + 0.5 * np.sin(2 * np.pi * x / 16) * np.cos(2 * np.pi * y / 16)).astype(np.float32)
    out = q.quilt(src, (64, 64), patch=24, overlap=8, tol=0.0, rng=1).image
    assert np.abs(out - np.roll(out, 16, axis=1)).max() < 1e-5
    assert np.abs(out - np.roll(out, 16, axis=0)).max() < 1e-5


def test_quilt_errors(rng):
    src = rng.random((20, 20)).astype(np.float32)
    with pytest.raises(ValueError, match="larger than the 20x20 source"):
        q.quilt(src, (64, 64), patch=32, overlap=12)
    with pytest.raises(ValueError, match="smaller than one patch"):
        q.quilt(src, (10, 64), patch=16, overlap=4)


def test_graphcut_masks_follow_the_seam():
    B = 8
    canvas = np.zeros((B, B), dtype=np.float32)
    patch = np.ones((1, B, B), dtype=np.float32)
    patch[0, :, 2] = 0.0  # agrees with the canvas in column 2 only
    filled = np.zeros((B, B), dtype=bool)
    filled[:, :4] = True
    keep = q.graphcut_masks(patch, canvas, filled, overlaps=(0, 4, 0, 0))[0]
    assert not keep[:, 0].any() and keep[:, 3:].all()
    # the cut passes through the agreeing column: no kept pixel left of it, none lost right of it
    assert not keep[:, :2].any()
    keep_free = q.graphcut_masks(patch, canvas, np.zeros((B, B), bool), overlaps=(4, 4, 4, 4))[0]
    assert keep_free.all()


def test_quilt_with_graphcut_seams(rng):
    src = rng.random((40, 40, 3)).astype(np.float32)
    a = q.quilt(src, (48, 48), patch=16, overlap=6, seams="graphcut", rng=2)
    values = {tuple(v) for v in src.reshape(-1, 3)}
    assert all(tuple(v) in values for v in a.image.reshape(-1, 3)[::5])
    with pytest.raises(ValueError, match="seam method"):
        q.seam_masks(src[None, :16, :16], src[:16, :16], np.ones((16, 16), bool), overlaps=(6, 6, 6, 6), method="x")


def test_quilt_sources_name_the_source_pixel_of_every_output_pixel(rng):
    src = rng.random((40, 44, 3)).astype(np.float32)
    res = q.quilt(src, (50, 47), patch=12, overlap=4, rng=0)
    np.testing.assert_array_equal(res.image, src[res.sources[..., 0], res.sources[..., 1]])
    assert res.sources.shape == (50, 47, 2)


def test_patch_matcher_reuses_the_weight_term_and_checks_shapes(rng):
    src = rng.random((20, 18, 3)).astype(np.float32)
    m = q.PatchMatcher(src, 5)
    w = np.zeros((5, 5), dtype=bool)
    w[:2] = True
    tgt = rng.random((5, 5, 3)).astype(np.float32)
    np.testing.assert_allclose(m.costs(tgt, w), q.overlap_costs(src, tgt, w.astype(np.float32)), rtol=1e-5, atol=1e-5)
    assert len(m._weight_terms) == 1
    m.costs(tgt * 0.5, w)
    assert len(m._weight_terms) == 1
    with pytest.raises(ValueError, match=r"target and weight must be \(5, 5"):
        m.costs(tgt[:4], w)
    with pytest.raises(ValueError, match="larger than the 20x18 source"):
        q.PatchMatcher(src, 19)


def _numpy_vertical_cuts(err):
    """The former numpy dynamic program (reference for the compiled one)."""
    K, B, w = err.shape
    acc = err[:, 0, :].astype(np.float64)
    back = np.zeros((K, B, w), dtype=np.int8)
    left = np.full((K, w), np.inf)
    right = np.full((K, w), np.inf)
    for y in range(1, B):
        left[:, 1:] = acc[:, :-1]
        right[:, :-1] = acc[:, 1:]
        best = np.minimum(np.minimum(left, acc), right)
        back[:, y, :] = np.where(left == best, -1, np.where(acc == best, 0, 1))
        acc = best + err[:, y, :]
    path = np.zeros((K, B), dtype=np.int64)
    path[:, B - 1] = np.argmin(acc, axis=1)
    for y in range(B - 1, 0, -1):
        path[:, y - 1] = path[:, y] + back[np.arange(K), y, path[:, y]]
    return path


def test_compiled_cuts_equal_the_numpy_program_with_ties_and_padding(rng):
    """Ties (rounded errors, zero columns) and inf padding take the same paths as the numpy loop."""
    for trial in range(60):
        K, B, w = int(rng.integers(1, 30)), int(rng.integers(2, 34)), int(rng.integers(1, 14))
        err = rng.random((K, B, w))
        if trial % 3 == 0:
            err = np.round(err * 3)
        if trial % 2 == 0:
            err[:, :, int(rng.integers(1, w + 1)) :] = np.inf
        np.testing.assert_array_equal(q.min_vertical_cuts(err), _numpy_vertical_cuts(err))
