"""ARAP warping, backward mesh sampling and mean value coordinates."""

import numpy as np
import pytest
from scipy.spatial import Delaunay

from synthkit.core import warp


@pytest.fixture
def mesh():
    rng = np.random.default_rng(0)
    V = np.concatenate([[[0, 0], [10, 0], [0, 10], [10, 10]], rng.random((20, 2)) * 8 + 1])
    return V, Delaunay(V).simplices.astype(np.int64)


def test_rigid_handles_give_rigid_motion(mesh):
    V, F = mesh
    solver = warp.ARAP2D(V, F, [0, 3, 7])
    t = 0.4
    R = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    shift = np.array([3.0, -2.0])
    U = solver.solve(V[[0, 3, 7]] @ R.T + shift)
    np.testing.assert_allclose(U, V @ R.T + shift, atol=1e-9)
    np.testing.assert_allclose(solver.solve(V[[0, 3, 7]]), V, atol=1e-9)


def test_handles_are_followed_and_shape_kept(mesh):
    V, F = mesh
    target = V[[0, 3]] + np.array([[0.0, 0.0], [2.0, 0.0]])
    U = warp.arap_deform(V, F, [0, 3], target)
    np.testing.assert_allclose(U[[0, 3]], target, atol=0.05)
    # edge lengths change far less than a uniform stretch of the same handle motion would
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    rest = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    new = np.linalg.norm(U[e[:, 0]] - U[e[:, 1]], axis=1)
    assert np.median(np.abs(new / rest - 1)) < 0.2


def test_arap_errors(mesh):
    V, F = mesh
    with pytest.raises(ValueError, match="two distinct handles"):
        warp.ARAP2D(V, F, [1])
    with pytest.raises(ValueError, match="outside"):
        warp.ARAP2D(V, F + 100, [0, 1])
    with pytest.raises(ValueError, match="handle_positions"):
        warp.ARAP2D(V, F, [0, 1]).solve(np.zeros((3, 2)))


def test_mesh_sampler_identity_and_shift():
    rng = np.random.default_rng(1)
    img = rng.random((20, 24)).astype(np.float32)
    V = np.concatenate([[[0, 0], [23, 0], [0, 19], [23, 19]], rng.random((10, 2)) * [20, 16] + 2])
    s = warp.MeshSampler(V, img.shape)
    np.testing.assert_allclose(s.warp(img, V), img, atol=1e-5)
    shifted = s.warp(img, V + [2.0, 1.0], border="wrap")
    np.testing.assert_allclose(shifted, np.roll(img, (-1, -2), axis=(0, 1)), atol=1e-5)
    with pytest.raises(ValueError, match="cover"):
        warp.MeshSampler(V[4:], img.shape)


def test_mean_value_coordinates_properties():
    square = np.array([[0, 0], [2, 0], [2, 1], [0, 1.0]])
    pts = np.array([[1.0, 0.5], [0.3, 0.2], [0.0, 0.0], [1.0, 0.0]])
    w = warp.mean_value_coordinates(pts, square)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    np.testing.assert_allclose(w @ square, pts, atol=1e-12)  # linear precision
    np.testing.assert_allclose(w[2], [1, 0, 0, 0])
    np.testing.assert_allclose(w[3], [0.5, 0.5, 0, 0])
    assert np.all(w[:2] > 0)


def test_triangle_stretch_exact_values():
    """Two triangles of a unit square: rigid 1, x stretched by 1.2 -> 1.2, squeezed to 0.8 ->
    1.25, a flipped triangle inf; shapes and dtype."""
    V = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    c, s = np.cos(0.3), np.sin(0.3)
    rigid = V @ np.array([[c, s], [-s, c]]) + [5.0, -2.0]
    np.testing.assert_allclose(warp.triangle_stretch(V, rigid, F), [1.0, 1.0])
    np.testing.assert_allclose(warp.triangle_stretch(V, V * [1.2, 1.0], F), [1.2, 1.2])
    np.testing.assert_allclose(warp.triangle_stretch(V, V * [0.8, 1.0], F), [1.25, 1.25])
    flipped = V.copy()
    flipped[2] = [0.2, -0.5]  # vertex 2 crosses edge 0-1: triangle 0 flips
    out = warp.triangle_stretch(V, flipped, F)
    assert out.shape == (2,) and out.dtype == np.float64 and np.isinf(out[0])
    with pytest.raises(ValueError, match="degenerate"):
        warp.triangle_stretch(np.zeros((4, 2)), V, F)


def test_mesh_sampler_lanczos_keeps_identity_and_range():
    rng = np.random.default_rng(2)
    img = rng.random((20, 24)).astype(np.float32)
    V = np.array([[0, 0], [23, 0], [0, 19], [23, 19.0]])
    s = warp.MeshSampler(V, (10, 12))  # a 10x12 tile read from inside the 20x24 image
    np.testing.assert_allclose(s.warp(img, V / 2 + [4.0, 3.0], interpolation="lanczos")[0, 0], img[3, 4], atol=1e-5)
    half = s.warp(img, V / 2 + 4.5, interpolation="lanczos")
    assert half.min() >= img.min() and half.max() <= img.max()
    with pytest.raises(ValueError, match="interpolation"):
        s.warp(img, V, interpolation="nearest")


def test_arap_solve_equals_the_numpy_rotation_fit():
    """The compiled rotation fit of ARAP2D.solve gives the bytes of the former numpy code."""
    rng = np.random.default_rng(5)
    V = np.concatenate([[[0, 0], [64, 0], [0, 64], [64, 64]], rng.random((80, 2)) * 62 + 1])
    F = Delaunay(V).simplices.astype(np.int64)
    handles = rng.choice(len(V), 20, replace=False)
    solver = warp.ARAP2D(V, F, handles)
    P = V[handles] + rng.standard_normal((20, 2)) * 2
    U1 = solver._step1.solve(np.concatenate([np.zeros(solver._n_shape1), P.ravel()])).reshape(-1, 2)
    rest, cur = V[F], U1[F]
    rc = rest - rest.mean(axis=1, keepdims=True)
    cc = cur - cur.mean(axis=1, keepdims=True)
    a = (rc * cc).sum(axis=(1, 2))
    b = (rc[..., 0] * cc[..., 1] - rc[..., 1] * cc[..., 0]).sum(axis=1)
    norm = np.hypot(a, b)
    norm = np.where(norm > 0, norm, 1.0)
    cos, sin = a / norm, b / norm
    fitted = np.stack([cos[:, None] * rc[..., 0] - sin[:, None] * rc[..., 1],
                       sin[:, None] * rc[..., 0] + cos[:, None] * rc[..., 1]], axis=2)
    d = np.concatenate([fitted[:, 1] - fitted[:, 0], fitted[:, 2] - fitted[:, 1], fitted[:, 0] - fitted[:, 2]])
    expected = solver._step2.solve(np.concatenate([d.ravel(), P.ravel()])).reshape(-1, 2)
    np.testing.assert_array_equal(solver.solve(P), expected)
