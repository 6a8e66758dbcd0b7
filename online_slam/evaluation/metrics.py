"""Trajectory and map error metrics (pure, vectorised).

Position RMSE is the article's: the square root of the mean squared 2D distance between estimated and true
positions, compared in one frame. By default that frame is anchored at the first pose that has truth (the
estimate is moved rigidly so that this pose coincides with its truth; with the article's fixed origin the move
is the identity); an SE(2) least-squares alignment is available for data whose frame differs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.se2 import compose, inverse, rotation

Array = NDArray[np.float64]


def position_rmse(estimate: ArrayLike, truth: ArrayLike) -> float:
    """Root mean squared 2D position error.

    Args:
        estimate: Estimated positions or poses, shape (N, >=2).
        truth: True positions or poses, shape (N, >=2).

    Returns:
        RMSE in metres (NaN for N = 0).
    """
    e = np.asarray(estimate, dtype=float)[:, :2] - np.asarray(truth, dtype=float)[:, :2]
    if len(e) == 0:
        return float("nan")
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


def endpoint_gap(poses: ArrayLike) -> float:
    """Distance between the last and the first position of a trajectory, shape (N, >=2)."""
    p = np.asarray(poses, dtype=float)
    return float(np.linalg.norm(p[-1, :2] - p[0, :2]))


def landmark_rmse(estimate: ArrayLike, truth: ArrayLike) -> float:
    """Root mean squared landmark position error, both shape (M, 2), rows paired."""
    return position_rmse(estimate, truth)


def anchor_transform(estimate_pose: ArrayLike, truth_pose: ArrayLike) -> Array:
    """The rigid motion that takes an estimated pose onto its true value.

    Args:
        estimate_pose: Estimated pose, shape (3,).
        truth_pose: True pose, shape (3,).

    Returns:
        ``T = truth * estimate^-1`` as ``[x, y, theta]``, shape (3,).
    """
    return compose(truth_pose, inverse(estimate_pose))


def align_se2(estimate: ArrayLike, truth: ArrayLike) -> Array:
    """Least-squares rigid alignment (rotation and translation, no scale) of positions onto truth.

    Args:
        estimate: Estimated positions, shape (N, >=2), N >= 2.
        truth: True positions, shape (N, >=2).

    Returns:
        ``T`` as ``[x, y, theta]`` minimising ``sum |T(estimate_i) - truth_i|^2``, shape (3,).
    """
    p = np.asarray(estimate, dtype=float)[:, :2]
    q = np.asarray(truth, dtype=float)[:, :2]
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    a, b = p - pc, q - qc
    theta = np.arctan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a * b))
    t = qc - rotation(theta) @ pc
    return np.array([t[0], t[1], theta])


def apply_transform(transform: ArrayLike, points_or_poses: ArrayLike) -> Array:
    """Apply a rigid motion ``[x, y, theta]`` to positions (N, 2) or poses (N, 3)."""
    T = np.asarray(transform, dtype=float)
    x = np.asarray(points_or_poses, dtype=float)
    if x.shape[-1] == 3:
        return compose(T, x)
    return x @ rotation(T[2]).T + T[:2]
