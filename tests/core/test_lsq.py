"""Sparse least squares: exact solutions, agreement with dense lstsq, many right-hand sides."""

import numpy as np
import pytest
import scipy.sparse as sp

from synthkit.core.lsq import ORDERINGS, LeastSquares, have_cholespy, solve_least_squares

BACKENDS = ["splu", pytest.param("cholespy", marks=pytest.mark.skipif(not have_cholespy(), reason="no cholespy"))]


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


@pytest.mark.parametrize("backend", BACKENDS)
def test_matches_dense_lstsq_many_rhs(backend):
    rng = np.random.default_rng(0)
    A = sp.random(300, 80, density=0.05, random_state=1, format="csr") + sp.eye(300, 80)
    w = rng.random(300) + 0.1
    B = rng.normal(size=(300, 5))
    solver = LeastSquares(A, weights=w, backend=backend)
    assert solver.backend == backend
    X = solver.solve(B)
    sw = np.sqrt(w)[:, None]
    ref = np.linalg.lstsq(A.toarray() * sw, B * sw, rcond=None)[0]
    np.testing.assert_allclose(X, ref, rtol=1e-8, atol=1e-10)
    # column by column gives the same as the block solve
    np.testing.assert_allclose(solver.solve(B[:, 2]), X[:, 2], rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(solve_least_squares(A, B[:, 0], weights=w, backend=backend), X[:, 0], rtol=1e-10)


@pytest.mark.parametrize("ordering", ORDERINGS)
def test_orderings_agree(ordering):
    A = sp.random(60, 20, density=0.2, random_state=3, format="csr") + sp.eye(60, 20)
    b = np.arange(60.0)
    ref = np.linalg.lstsq(A.toarray(), b, rcond=None)[0]
    np.testing.assert_allclose(LeastSquares(A, backend="splu", ordering=ordering).solve(b), ref, rtol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular(backend):
    with pytest.raises(ValueError, match="singular"):
        LeastSquares(sp.csr_matrix(np.array([[1.0, 1.0], [2.0, 2.0]])), backend=backend)
    # a Laplacian without anchors is singular too (constant null space)
    D = sp.csr_matrix(np.array([[1.0, -1.0, 0.0], [0.0, 1.0, -1.0]]))
    with pytest.raises(ValueError, match="singular"):
        LeastSquares(D, backend=backend)


def test_errors():
    with pytest.raises(ValueError, match="unknown backend"):
        LeastSquares(sp.eye(2), backend="magic")
    with pytest.raises(ValueError, match="unknown ordering"):
        LeastSquares(sp.eye(2), ordering="AMD")
    with pytest.raises(ValueError, match="weights must have 2"):
        LeastSquares(sp.eye(2), weights=[1.0])
    with pytest.raises(ValueError, match="non-negative"):
        LeastSquares(sp.eye(2), weights=[1.0, -1.0])
    with pytest.raises(ValueError, match="b must have shape"):
        LeastSquares(sp.eye(2)).solve(np.ones(3))


@pytest.mark.parametrize("backend", BACKENDS)
def test_residual_check(backend):
    """check="residual" accepts what "solution" accepts with the same solution, refuses a singular
    system, and reports the normal matrix's entries."""
    A = sp.random(60, 20, density=0.2, random_state=4, format="csr") + sp.eye(60, 20)
    b = np.arange(60.0)
    by_residual = LeastSquares(A, backend=backend, check="residual")
    np.testing.assert_array_equal(by_residual.solve(b), LeastSquares(A, backend=backend).solve(b))
    assert by_residual.nnz_normal == (A.T @ A).nnz
    with pytest.raises(ValueError, match="singular"):
        LeastSquares(sp.csr_matrix(np.array([[1.0, 1.0], [2.0, 2.0]])), backend=backend, check="residual")
    with pytest.raises(ValueError, match="unknown check"):
        LeastSquares(A, check="forward")
