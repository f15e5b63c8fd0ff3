"""Sparse least squares: exact solutions, agreement with dense lstsq, many right-hand sides."""

import numpy as np
import pytest
import scipy.sparse as sp

from synthkit.core.lsq import LeastSquares, solve_least_squares


def test_exact_overdetermined_line_fit():
    # fit y = a + b x through (0,1), (1,3), (2,5): exact a=1, b=2
    A = sp.csr_matrix(np.array([[1, 0], [1, 1], [1, 2]], dtype=float))
    x = LeastSquares(A).solve(np.array([1.0, 3.0, 5.0]))
    np.testing.assert_allclose(x, [1.0, 2.0], atol=1e-12)


def test_mean_of_observations():
    # one unknown observed three times: the least-squares value is the (weighted) mean
    A = sp.csr_matrix(np.ones((3, 1)))
    np.testing.assert_allclose(LeastSquares(A).solve([1.0, 2.0, 6.0]), [3.0])
    np.testing.assert_allclose(LeastSquares(A, weights=[1, 1, 2]).solve([1.0, 2.0, 6.0]), [15 / 4])


def test_matches_dense_lstsq_many_rhs():
    rng = np.random.default_rng(0)
    A = sp.random(300, 80, density=0.05, random_state=1, format="csr") + sp.eye(300, 80)
    w = rng.random(300) + 0.1
    B = rng.normal(size=(300, 5))
    solver = LeastSquares(A, weights=w)
    X = solver.solve(B)
    sw = np.sqrt(w)[:, None]
    ref = np.linalg.lstsq(A.toarray() * sw, B * sw, rcond=None)[0]
    np.testing.assert_allclose(X, ref, rtol=1e-8, atol=1e-10)
    # column by column gives the same as the block solve
    np.testing.assert_allclose(solver.solve(B[:, 2]), X[:, 2], rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(solve_least_squares(A, B[:, 0], weights=w), X[:, 0], rtol=1e-10)


def test_errors():
    with pytest.raises(ValueError, match="singular"):
        LeastSquares(sp.csr_matrix(np.array([[1.0, 1.0], [2.0, 2.0]])))
    with pytest.raises(ValueError, match="weights must have 2"):
        LeastSquares(sp.eye(2), weights=[1.0])
    with pytest.raises(ValueError, match="non-negative"):
        LeastSquares(sp.eye(2), weights=[1.0, -1.0])
    with pytest.raises(ValueError, match="b must have shape"):
        LeastSquares(sp.eye(2)).solve(np.ones(3))
