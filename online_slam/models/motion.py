"""Odometry: the measured increment between consecutive poses, and composing increments.

The odometry residual is the article's: ``e = between(a, b) - delta`` with its angle wrapped, i.e. the noise is
additive on the increment expressed in the earlier pose's frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between_with_jacobians, compose_with_jacobians

Array = NDArray[np.float64]


def odometry_residual_with_jacobians(a: ArrayLike, b: ArrayLike, delta: ArrayLike) -> tuple[Array, Array, Array]:
    """Residual of an odometry measurement between poses a and b.

    Args:
        a: Earlier poses, shape (..., 3).
        b: Later poses, shape (..., 3).
        delta: Measured increments in a's frame, shape (..., 3).

    Returns:
        (residual (..., 3) with wrapped angle, d/da (..., 3, 3), d/db (..., 3, 3)).
    """
    value, J_a, J_b = between_with_jacobians(a, b)
    e = value - np.asarray(delta, dtype=float)
    e[..., 2] = wrap(e[..., 2])
    return e, J_a, J_b


def compose_increments(d1: ArrayLike, cov1: ArrayLike, d2: ArrayLike, cov2: ArrayLike) -> tuple[Array, Array]:
    """Merge two consecutive independent increments into one, propagating covariance to first order.

    Args:
        d1: First increment, shape (3,).
        cov1: Its covariance, shape (3, 3).
        d2: Second increment (in the frame reached by d1), shape (3,).
        cov2: Its covariance, shape (3, 3).

    Returns:
        (increment (3,), covariance (3, 3)) of ``d1 * d2``.
    """
    d, J1, J2 = compose_with_jacobians(d1, d2)
    cov = J1 @ np.asarray(cov1, dtype=float) @ J1.T + J2 @ np.asarray(cov2, dtype=float) @ J2.T
    return d, 0.5 * (cov + cov.T)
