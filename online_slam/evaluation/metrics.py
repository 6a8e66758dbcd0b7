"""Trajectory and map error metrics (pure, vectorised).

Position RMSE is the article's: the square root of the mean squared 2D distance between estimated and true
positions, compared in one frame. By default that frame is anchored at the first pose that has truth (the
estimate is moved rigidly so that this pose's start prior, or its estimate where it has none, coincides with its
truth; with the article's fixed origin the move is the identity); an SE(2) least-squares alignment is available
for data whose frame differs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap
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


def transform_pose_covariance(transform: ArrayLike, covariances: ArrayLike) -> Array:
    """Covariances of poses moved by a rigid motion ``T * p``: ``J C J^T`` with ``J = diag(R(T_theta), 1)``.

    Args:
        transform: ``[x, y, theta]``, shape (3,).
        covariances: Pose covariances, shape (N, 3, 3).

    Returns:
        Shape (N, 3, 3).
    """
    J = np.eye(3)
    J[:2, :2] = rotation(float(np.asarray(transform, dtype=float)[2]))
    return J @ np.asarray(covariances, dtype=float) @ J.T


def pose_nees(estimate: ArrayLike, covariances: ArrayLike, truth: ArrayLike) -> Array:
    """Normalised estimation error squared of poses, ``e^T C^-1 e`` with the heading error wrapped.

    Args:
        estimate: Estimated poses, shape (N, 3).
        covariances: Their covariances, shape (N, 3, 3); rows with a singular covariance give NaN.
        truth: True poses, shape (N, 3).

    Returns:
        NEES per pose, shape (N,) (3 dof: mean 3 for a consistent estimator).
    """
    e = np.asarray(estimate, dtype=float) - np.asarray(truth, dtype=float)
    e[:, 2] = wrap(e[:, 2])
    C = np.asarray(covariances, dtype=float)
    out = np.full(len(e), np.nan)
    if len(e) == 0:
        return out
    # A covariance is usable when it is finite and its smallest eigenvalue is a meaningful fraction of its largest.
    usable = np.all(np.isfinite(C), axis=(1, 2))
    eig = np.zeros((len(C), 3))
    eig[usable] = np.linalg.eigvalsh(C[usable])
    usable &= eig[:, 0] > 1e-12 * np.maximum(eig[:, -1], 1e-300)
    if usable.any():
        out[usable] = np.einsum("ni,ni->n", e[usable], np.linalg.solve(C[usable], e[usable][..., None])[..., 0])
    return out
