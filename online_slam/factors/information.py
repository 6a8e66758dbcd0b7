"""Square-root information: how every factor whitens its residual."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def sqrt_information(cov: ArrayLike) -> NDArray[np.float64]:
    """Square-root information matrices ``W`` with ``W^T W = cov^-1``.

    Args:
        cov: Covariances, shape (..., n, n), symmetric positive definite.

    Returns:
        Lower-triangular ``W = chol(cov)^-1``, shape (..., n, n).
    """
    L = np.linalg.cholesky(np.asarray(cov, dtype=float))
    return np.linalg.inv(L)
