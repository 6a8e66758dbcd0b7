"""What variance-component estimation needs from a least-squares solution's linearization: each group of residuals'
redundancy, a Gauss-Newton step and the covariance of extra parameters (:mod:`online_slam.evaluation.noise_self`).

For whitened residuals ``r`` (m,) and their Jacobian ``A`` (m, n) at the solution, ``N = A^T A``. A group g of rows
has the redundancy ``m_g - tr(N^-1 N_g)``, with ``N_g = A_g^T A_g``: its share of the ``m - n`` degrees of freedom
(the sum over its rows of ``1 - h_i``, ``h_i`` the diagonal of ``A N^-1 A^T``; Forstner 1979). The trace is the
derivative of ``log det(N + (e^t - 1) N_g)`` at ``t = 0``, taken here as a central difference of two sparse LDL^T
factorizations (QDLDL, as the solver's): exact to about 1e-6 relative, for the price of two factorizations, where
the diagonal itself would need a selected inverse of N (no sparse factorization in scipy gives one).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import qdldl
import scipy.sparse as sp
from numpy.typing import NDArray

Array = NDArray[np.float64]


class SingularMatrix(ValueError):
    """A normal matrix that is singular or indefinite (to the precision of its factorization)."""


TRACE_STEP = 1e-3
"""The step t of the central difference: its error is about t^2 / 6 of the trace; rounding stays far below."""


def factorize(N: sp.spmatrix) -> tuple[qdldl.Solver, Array]:
    """LDL^T of a symmetric positive definite sparse matrix (upper triangle used).

    Returns:
        The factorization (its ``solve`` takes one right-hand side (n,)) and the pivots D, shape (n,).

    Raises:
        SingularMatrix: N is singular or indefinite (a variable no residual determines, or information so lopsided
            that the factorization loses it).
    """
    upper = sp.triu(N, format="csc")
    upper.sort_indices()
    solver = qdldl.Solver(upper)
    pivots = np.asarray(solver.factors()[1], dtype=float)
    if not np.all(pivots > 0.0):
        raise SingularMatrix("the normal matrix is singular: some variable is not determined by the residuals")
    return solver, pivots


def group_traces(A: sp.csr_matrix, groups: Mapping[str, NDArray[np.bool_]]) -> dict[str, float]:
    """``tr(N^-1 N_g)`` for each group of rows of A (the parameters its rows determine, summed over them).

    Args:
        A: Whitened Jacobian, shape (m, n), of full column rank.
        groups: Rows of each group, masks of shape (m,).

    Returns:
        The trace of each group, by name; the traces of groups that cover every row once add up to n.
    """
    N = (A.T @ A).tocsc()
    traces = {}
    for name, rows in groups.items():
        part = A[np.flatnonzero(rows)]
        N_g = (part.T @ part).tocsc()
        plus = _log_det(N + np.expm1(TRACE_STEP) * N_g)
        minus = _log_det(N + np.expm1(-TRACE_STEP) * N_g)
        traces[name] = (plus - minus) / (2.0 * TRACE_STEP)
    return traces


def _log_det(N: sp.spmatrix) -> float:
    """log det N of a symmetric positive definite sparse matrix."""
    return float(np.sum(np.log(factorize(N)[1])))


def gauss_newton(A: sp.csr_matrix, r: Array, extra: int) -> tuple[Array, Array]:
    """The Gauss-Newton step ``-N^-1 A^T r``, and the covariance ``(N^-1)`` of the last ``extra`` parameters.

    Args:
        A: Whitened Jacobian, shape (m, n), of full column rank.
        r: Whitened residuals, shape (m,).
        extra: How many parameters, the last columns of A, to give the covariance of.

    Returns:
        (the step, shape (n,); the covariance of the last ``extra`` parameters, shape (extra, extra)).
    """
    solver, _ = factorize((A.T @ A).tocsc())
    n = A.shape[1]
    step = -np.asarray(solver.solve(A.T @ r), dtype=float)
    cov = np.zeros((extra, extra))
    for k in range(extra):
        unit = np.zeros(n)
        unit[n - extra + k] = 1.0
        cov[:, k] = np.asarray(solver.solve(unit), dtype=float)[n - extra :]
    return step, 0.5 * (cov + cov.T)
