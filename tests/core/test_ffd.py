"""Trilinear and Bernstein free-form deformation."""

import numpy as np
import pytest

from synthkit.core.ffd import bernstein_ffd, box_coordinates, trilinear_ffd, trilinear_weights

UNIT = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], dtype=float)


def test_corner_order_and_identity():
    np.testing.assert_array_equal(UNIT[1], [1, 0, 0])
    np.testing.assert_array_equal(UNIT[2], [0, 1, 0])
    np.testing.assert_array_equal(UNIT[4], [0, 0, 1])
    P = np.random.default_rng(0).random((50, 3))
    np.testing.assert_allclose(trilinear_ffd(P, UNIT), P, atol=1e-15)
    # corners map to corners
    C = UNIT * [2, 3, 4] + [1, 1, 1]
    np.testing.assert_allclose(trilinear_ffd(UNIT, C), C)


def test_exact_values():
    C = UNIT.copy()
    C[7] = [2, 2, 2]  # pull corner (1,1,1)
    out = trilinear_ffd(np.array([[0.5, 0.5, 0.5], [1, 1, 0.5]]), C)
    # centre: the mean of the corners, (4 + 1) / 8 per coordinate
    np.testing.assert_allclose(out[0], [0.625, 0.625, 0.625])
    np.testing.assert_allclose(out[1], [1.5, 1.5, 1.0])
    w = trilinear_weights(np.array([[0.25, 0.5, 1.0]]))
    np.testing.assert_allclose(w.sum(), 1.0)
    np.testing.assert_allclose(w[0, [4, 5, 6, 7]], [0.375, 0.125, 0.375, 0.125])


def test_affine_corners_give_affine_map():
    rng = np.random.default_rng(2)
    A, t = rng.normal(size=(3, 3)), rng.normal(size=3)
    P = rng.random((20, 3))
    np.testing.assert_allclose(trilinear_ffd(P, UNIT @ A.T + t), P @ A.T + t, atol=1e-12)


def test_bernstein_degree1_equals_trilinear_and_degree2_affine():
    rng = np.random.default_rng(3)
    C = rng.normal(size=(8, 3))
    lattice = C.reshape(2, 2, 2, 3).transpose(2, 1, 0, 3)  # [i, j, k] = corner i + 2j + 4k
    P = rng.random((30, 3))
    np.testing.assert_allclose(bernstein_ffd(P, lattice), trilinear_ffd(P, C), atol=1e-12)
    g = np.linspace(0, 1, 3)
    grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1)  # undeformed degree-2 lattice
    np.testing.assert_allclose(bernstein_ffd(P, grid), P, atol=1e-12)


def test_box_coordinates_and_errors():
    np.testing.assert_allclose(box_coordinates([[1, 2, 3]], [0, 0, 0], [2, 4, 6]), [[0.5, 0.5, 0.5]])
    with pytest.raises(ValueError, match="positive extent"):
        box_coordinates([[0, 0, 0]], [0, 0, 0], [1, 0, 1])
    with pytest.raises(ValueError, match=r"\(8, 3\)"):
        trilinear_ffd([[0, 0, 0]], np.zeros((4, 3)))
    with pytest.raises(ValueError, match="points"):
        trilinear_ffd(np.zeros(3), UNIT)
