"""Least-squares reshape solver with handles eliminated (paper sections 3.3 and 3.4).

``A (m, 3 n)`` and ``b (m,)`` hold every weighted constraint row over the node positions
``x (3 n,)``. Handle and fixed nodes are *known*: their columns move to the right-hand side,
``A_u x_u = b - A_k x_k``, so the normal matrix ``A_u^T A_u`` depends only on which nodes are
known. :class:`ReshapeSolver` factors it once with :class:`synthkit.core.lsq.LeastSquares`
(sparse Cholesky or tuned SuperLU) and each step costs one pair of triangular solves. The paper's
weights span nine orders of magnitude, so the factorization is checked by its backward error
(``check="residual"``): a real model's normal matrix may have a condition number near 1e12.

:class:`FactorCache` keeps one factorization per set of known nodes, so a chain dragged with a
limited propagation length and then released (section 5) factors twice and reuses both.
:func:`drag` moves the handles to their targets in ``steps`` equal increments. After each step it
checks eq. 4 on every graph edge: an edge whose projected length ``u_ki . (x_i - x_k)`` fell below
``short_ratio`` of its rest length gets its stress target ``l_ki`` multiplied by ``raise_factor``
(only ``b`` changes) and the step is solved again; an edge whose projected length is at most
``flip_ratio`` of its rest length has collapsed or flipped, and the motion is refused: the result
is the last valid step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from synthkit.core.lsq import LeastSquares, have_cholespy
from synthkit.methods.reshape.options import DragOptions

__all__ = ["ReshapeSolver", "FactorCache", "DragResult", "drag", "known_columns", "floating_anchors"]


def known_columns(known: np.ndarray) -> np.ndarray:
    """Columns ``(3 k,)`` of the known nodes ``known (k,)``."""
    return (3 * np.asarray(known, np.int64)[:, None] + np.arange(3)).ravel()


def floating_anchors(n: int, pairs, known, used) -> np.ndarray:
    """The lowest node ``(c,)`` of every cluster of ``used (n,) bool`` nodes, linked by ``pairs (k, 2)``,
    that holds no ``known`` node. Without a known node such a cluster can translate freely and the
    normal matrix is singular; fixing one node keeps it where it is."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    G = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    held = np.zeros(label.max() + 1, bool)
    held[label[np.asarray(known, np.int64)]] = True
    nodes = np.flatnonzero(np.asarray(used, bool) & ~held[label])
    _, first = np.unique(label[nodes], return_index=True)
    return nodes[first]


class ReshapeSolver:
    """Factor the reshape system once for a set of known (handle and fixed) nodes; solve per step.

    Parameters
    ----------
    A : (m, 3 n) sparse weighted constraint matrix
    known : (k,) int64 nodes whose positions are given
    backend : "auto" (cholespy when installed, else splu), "cholespy" or "splu"

    Attributes: ``vars`` (unknowns), ``nnz_A`` (of ``A_u``), ``nnz_AtA`` (of ``A_u^T A_u``),
    ``factor_ms`` (forming and factoring ``A_u^T A_u``, :class:`~synthkit.core.lsq.LeastSquares`),
    ``solve_ms`` (one entry per solve), ``backend``.
    Raises ValueError when the normal matrix is singular (an unconstrained node or component).
    """

    def __init__(self, A, known, *, backend: str = "auto"):
        if backend not in ("auto", "cholespy", "splu"):
            raise ValueError(f"unknown backend {backend!r}")
        A = sp.csc_matrix(A)
        self.known = np.asarray(known, np.int64)
        self.known_cols = known_columns(self.known)
        free = np.ones(A.shape[1], bool)
        free[self.known_cols] = False
        self.free_cols = np.flatnonzero(free)
        A_u = A[:, self.free_cols].tocsr()
        self.A_k = A[:, self.known_cols].tocsr()
        self.vars = int(len(self.free_cols))
        self.nnz_A = int(A_u.nnz)
        self.n_nodes = A.shape[1] // 3
        self.backend = ("cholespy" if have_cholespy() else "splu") if backend == "auto" else backend
        start = time.perf_counter()
        self._lsq = LeastSquares(A_u, backend=self.backend, check="residual") if self.vars else None
        self.factor_ms = 1e3 * (time.perf_counter() - start)
        self.nnz_AtA = self._lsq.nnz_normal if self._lsq is not None else 0
        self.solve_ms: list[float] = []

    def solve(self, b, X_known) -> np.ndarray:
        """Node positions ``X (n, 3)`` for right-hand side ``b (m,)`` and known positions ``X_known (k, 3)``."""
        start = time.perf_counter()
        rhs = np.asarray(b, np.float64) - self.A_k @ np.asarray(X_known, np.float64).ravel()
        x = np.empty(3 * self.n_nodes)
        if self._lsq is not None:
            x[self.free_cols] = self._lsq.solve(rhs)
        x[self.known_cols] = np.asarray(X_known, np.float64).ravel()
        self.solve_ms.append(1e3 * (time.perf_counter() - start))
        return x.reshape(-1, 3)


@dataclass
class DragResult:
    """Outcome of :func:`drag`: ``X (n, 3)`` at the last valid step, ``steps_done``, ``status``
    ("ok" or "partial"), the refused ``edge`` (node pair) and ``step`` when partial, the number of
    ``length_raises`` and the stress targets ``lengths (E,)`` in use at the end."""

    X: np.ndarray
    steps_done: int
    status: str
    lengths: np.ndarray
    length_raises: int = 0
    edge: tuple[int, int] | None = None
    step: int | None = None


def _projected(X, edges, u) -> np.ndarray:
    return np.einsum("ij,ij->i", X[edges[:, 1]] - X[edges[:, 0]], u)


def drag(
    solver_at,
    b,
    *,
    X0,
    T,
    edges,
    stress_slice: slice,
    stress_weights,
    options: DragOptions,
    progress=None,
    lengths=None,
) -> DragResult:
    """Move the known nodes from ``X0`` toward ``T (n, 3)`` in ``options.steps`` increments
    (``options``: eq. 4's ``short_ratio`` and ``raise_factor``, the ``flip_ratio`` that refuses).

    ``solver_at(s)`` gives the :class:`ReshapeSolver` of step ``s`` (1..steps; the same solver for
    every step, or a limited-propagation one while dragging and a full one at release); at step
    ``s`` its known nodes sit at ``X0 + s / steps (T - X0)``. ``edges (E, 2)`` are the graph edges
    whose stress rows occupy ``b[stress_slice]`` with weights ``stress_weights (E,)``;
    ``progress``, when given, wraps the iterable of steps (a progress bar); ``lengths (E,)`` are
    the stress targets in ``b`` (default: the rest lengths of ``X0``). Returns the
    :class:`DragResult` of the last valid step.
    """
    X0 = np.asarray(X0, np.float64)
    T = np.asarray(T, np.float64)
    b = np.array(b, np.float64)
    u = X0[edges[:, 1]] - X0[edges[:, 0]]
    rest = np.linalg.norm(u, axis=1)
    u /= np.maximum(rest, 1e-300)[:, None]
    lengths = rest.copy() if lengths is None else np.array(lengths, np.float64)
    X_prev, raises = X0, 0
    steps = options.steps
    step_numbers = range(1, steps + 1)
    for s in progress(step_numbers) if progress is not None else step_numbers:
        solver = solver_at(s)
        Xk = X0[solver.known] + (s / steps) * (T[solver.known] - X0[solver.known])
        X = solver.solve(b, Xk)
        short = _projected(X, edges, u) < options.short_ratio * rest
        if short.any():
            lengths[short] *= options.raise_factor
            raises += int(short.sum())
            b[stress_slice] = stress_weights * lengths
            X = solver.solve(b, Xk)
        proj = _projected(X, edges, u)
        flipped = np.flatnonzero(proj <= options.flip_ratio * rest)
        if len(flipped):
            worst = flipped[np.argmin(proj[flipped] / rest[flipped])]
            edge = (int(edges[worst, 0]), int(edges[worst, 1]))
            return DragResult(X_prev, s - 1, "partial", lengths, raises, edge, s)
        X_prev = X
    return DragResult(X_prev, steps, "ok", lengths, raises)


class FactorCache:
    """Factorizations of one system ``A`` kept per set of known nodes (factor once per handle set).

    ``get(known)`` returns the cached :class:`ReshapeSolver` for that set, factoring on a miss;
    ``hits`` counts the reuses and ``len()`` the factorizations made.
    """

    def __init__(self, A, *, backend: str = "auto"):
        self.A = A
        self.backend = backend
        self._solvers: dict[bytes, ReshapeSolver] = {}
        self.hits = 0

    def get(self, known) -> ReshapeSolver:
        known = np.asarray(known, np.int64)
        key = np.sort(known).tobytes()
        if key in self._solvers:
            self.hits += 1
        else:
            self._solvers[key] = ReshapeSolver(self.A, known, backend=self.backend)
        return self._solvers[key]

    def __len__(self) -> int:
        return len(self._solvers)
