"""Square-root information: how every factor whitens its residual."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FLOOR = 1e-12
"""A covariance that is not positive definite in floating point has its eigenvalues raised to this fraction of its
largest before it is factored (see :func:`sqrt_information`)."""


def sqrt_information(cov: ArrayLike) -> NDArray[np.float64]:
    """Square-root information matrices ``W`` with ``W^T W = cov^-1``.

    Decision: a covariance that Cholesky refuses (positive definite in exact arithmetic, not in floating point: an
    odometry with sigmas 1e8 and 1e-8, composed across a turn, mixes 1e16 and 1e-16 in one matrix) is factored
    with its eigenvalues raised to :data:`FLOOR` of its largest: double precision holds no information below that.
    Every covariance Cholesky takes is factored as it is.

    Args:
        cov: Covariances, shape (..., n, n), symmetric positive definite.

    Returns:
        Lower-triangular ``W = chol(cov)^-1``, shape (..., n, n).

    Raises:
        numpy.linalg.LinAlgError: A covariance without a positive eigenvalue.
    """
    cov = np.asarray(cov, dtype=float)
    try:
        L = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        L = np.linalg.cholesky(floored(cov))
    return np.linalg.inv(L)


def floored(cov: ArrayLike, fraction: float = FLOOR) -> NDArray[np.float64]:
    """Symmetric parts of covariances, shape (..., n, n), with their eigenvalues raised to ``fraction`` of their
    largest (0: to their positive semidefinite part)."""
    cov = np.asarray(cov, dtype=float)
    values, vectors = np.linalg.eigh(0.5 * (cov + np.swapaxes(cov, -1, -2)))
    values = np.maximum(values, fraction * values.max(axis=-1, keepdims=True))
    out: NDArray[np.float64] = (vectors * values[..., None, :]) @ np.swapaxes(vectors, -1, -2)
    return out
