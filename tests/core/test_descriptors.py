"""SHOT (world frame) and FPFH descriptors: exact bins on tiny clouds, invariants, errors."""

import numpy as np
import pytest

from synthkit.core.descriptors import FPFH_SIZE, SHOT_SIZE, descriptor_distances, fpfh, shot


def _bin(az, el, rad, cos):
    return ((az * 2 + el) * 2 + rad) * 11 + cos


def test_shot_single_neighbour_exact_bin():
    # neighbour at the centre of azimuth sector 0 (22.5 deg), elevation 45 deg, radius 3R/4 (outer
    # shell centre), normal equal to the keypoint's (cos = 1 -> last cos bin, clamped)
    R = 0.2
    az, el = np.radians(22.5), np.radians(45.0)
    d = 0.75 * R * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    n = np.array([[0.0, 0.0, 1.0]])
    D = shot(np.zeros((1, 3)), n, d[None, :], n, radius=R)
    assert D.shape == (1, SHOT_SIZE) and D.dtype == np.float32
    expected = np.zeros(SHOT_SIZE)
    expected[_bin(0, 1, 1, 10)] = 1.0
    np.testing.assert_allclose(D[0], expected, atol=1e-6)


def test_shot_interpolates_between_azimuth_sectors():
    # exactly on the border of sectors 0 and 1 (45 deg) in the plane: half to each sector; the
    # elevation is 0, halfway between the two halves' centres: half to each half
    R = 0.2
    d = 0.75 * R * np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0])
    n = np.array([[0.0, 0.0, 1.0]])
    raw = shot(np.zeros((1, 3)), n, d[None, :], n, radius=R)[0]
    vals = {_bin(a, e, 1, 10): 0.5 for a in (0, 1) for e in (0, 1)}
    expected = np.zeros(SHOT_SIZE)
    for k in vals:
        expected[k] = 1.0
    expected /= np.linalg.norm(expected)
    np.testing.assert_allclose(raw, expected, atol=1e-6)


def test_shot_translation_invariant_and_unit_length():
    rng = np.random.default_rng(0)
    P = rng.random((300, 3))
    N = rng.normal(size=(300, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    keys = P[:20]
    D1 = shot(keys, N[:20], P, N, radius=0.3)
    D2 = shot(keys + 5.0, N[:20], P + 5.0, N, radius=0.3)
    np.testing.assert_allclose(D1, D2, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(D1, axis=1), 1.0, atol=1e-5)


def test_shot_frame_is_world_aligned_not_rotation_invariant():
    rng = np.random.default_rng(1)
    P = rng.random((200, 3)) - 0.5
    N = np.tile([0.0, 0.0, 1.0], (200, 1))
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    D1 = shot(np.zeros((1, 3)), N[:1], P, N, radius=0.5)
    D2 = shot(np.zeros((1, 3)), N[:1], P @ R.T, N, radius=0.5)
    assert np.linalg.norm(D1 - D2) > 0.05


def test_shot_empty_support_gives_zero_and_chunking_is_irrelevant():
    n = np.array([[0.0, 0.0, 1.0]])
    D = shot(np.zeros((1, 3)), n, np.array([[5.0, 0, 0]]), n, radius=0.2)
    assert not D.any()
    rng = np.random.default_rng(2)
    P = rng.random((100, 3))
    N = np.tile([0.0, 1.0, 0.0], (100, 1))
    np.testing.assert_allclose(shot(P, N, P, N, radius=0.4, chunk=7), shot(P, N, P, N, radius=0.4), atol=1e-6)


def test_shot_errors():
    n = np.zeros((1, 3))
    with pytest.raises(ValueError, match="radius"):
        shot(n, n, n, n, radius=0)
    with pytest.raises(ValueError, match="normals must have shape"):
        shot(n, np.zeros((2, 3)), n, n)
    with pytest.raises(ValueError, match="NaN"):
        shot(np.full((1, 3), np.nan), n, n, n)


def test_fpfh_shape_norm_and_rigid_invariance():
    rng = np.random.default_rng(3)
    P = rng.random((150, 3))
    N = rng.normal(size=(150, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    D = fpfh(P[:10], N[:10], P, N, radius=0.3)
    assert D.shape == (10, FPFH_SIZE)
    np.testing.assert_allclose(np.linalg.norm(D, axis=1), 1.0, atol=1e-5)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    D2 = fpfh(P[:10] @ R.T + 1.0, N[:10] @ R.T, P @ R.T + 1.0, N @ R.T, radius=0.3)
    np.testing.assert_allclose(D, D2, atol=1e-4)


def test_descriptor_distances_matches_brute_force():
    rng = np.random.default_rng(4)
    A, B = rng.random((5, 7)), rng.random((4, 7))
    ref = np.linalg.norm(A[:, None] - B[None], axis=2)
    np.testing.assert_allclose(descriptor_distances(A, B), ref, atol=1e-12)
