"""Pieces of a Kalman update that touches few columns, shared by the EKF and the smoother's marginal prior."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def stacked_jacobian(J_pose: Array, J_landmark: Array, pose_first: bool = True) -> Array:
    """The compact Jacobian of k range-bearing observations over [pose, landmark 1..k] (or [landmarks.., pose]).

    Args:
        J_pose: d z_i / d pose, shape (k, 2, 3).
        J_landmark: d z_i / d landmark_i, shape (k, 2, 2).
        pose_first: Pose columns first (else last).

    Returns:
        Shape (2k, 3 + 2k); observation i's landmark occupies its own two columns.
    """
    k = len(J_pose)
    H = np.zeros((2 * k, 3 + 2 * k))
    pose, first = (slice(0, 3), 3) if pose_first else (slice(2 * k, 2 * k + 3), 0)
    H[:, pose] = J_pose.reshape(2 * k, 3)
    rows = np.arange(2 * k)[:, None]
    H[rows, first + 2 * (rows // 2) + np.arange(2)] = J_landmark.reshape(2 * k, 2)
    return H


def apply_update(cov: Array, PHt: Array, S: Array, y: Array) -> tuple[Array, Array, Array]:
    """``cov -= K S K^T`` in place with ``K = P H^T S^-1``, through the Cholesky factor of S (exactly symmetric).

    Args:
        cov: Covariance, shape (n, n); updated in place.
        PHt: ``P H^T``, shape (n, m).
        S: Innovation covariance, shape (m, m).
        y: Innovation, shape (m,).

    Returns:
        (state correction K y (n,), W = P H^T L^-T (n, m), L^-1 (m, m)) with ``S = L L^T``.
    """
    L_inv = np.linalg.inv(np.linalg.cholesky(S))  # S is small (m x m); raises LinAlgError, cov untouched
    W = PHt @ L_inv.T
    cov -= W @ W.T  # numpy computes W W^T with syrk: exactly symmetric, so cov stays symmetric bit for bit
    return W @ (L_inv @ y), W, L_inv
