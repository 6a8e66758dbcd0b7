"""Where the EKF evaluates its Jacobians, so that what SLAM cannot observe stays unobserved.

The standard EKF evaluates every Jacobian at the current estimate. Those estimates change between the steps that
use them, and the linearized system then gains information along directions no sighting can observe (global
position and heading): the filter grows overconfident (Huang, Mourikis & Roumeliotis, IJRR 29(5), 2010). In 2-D
landmark SLAM those directions are the columns of

    N = [I, J p; 0, 1; I, J l_1; ...; I, J l_M]        (J: rotation by +90 degrees)

and a consistent linearization keeps ``H N = 0`` for every sighting, ``F N_k = N_k+1`` for every prediction and
maps the robot's block of N onto a new landmark's, with the same points throughout:

- ``fej`` (First-Estimates Jacobians, Huang et al., ISER 2008): every Jacobian at each variable's first estimate,
  the newest pose as predicted (``p_k|k-1``) and each landmark where it was placed. The prediction's becomes
  ``F = [I, J (p_k+1|k - p_k|k-1); 0, 1]``; a new landmark's ``d l / d robot = [I, J (l - p_k|k-1)]``.
- ``oc`` (observability-constrained, as Hesch et al. constrain OC-VINS, IEEE T-RO 2014): the same prediction and
  placement, but each sighting's Jacobian is the standard one (at the current estimate, more accurate than a
  first estimate far from it) projected onto the nearest one with ``H N = 0``: ``H - H N (N^T N)^-1 N^T``.

- ``invariant`` (the invariant EKF of Barrau & Bonnabel, as Brossard et al. apply it to SLAM, IEEE Sensors J.
  19(4), 2019): the error of the pose and map is taken on the group SE_{1+M}(2) (one heading, the robot's and
  every landmark's position), ``X = exp(xi) X_hat``. Its prediction and sighting Jacobians, expressed in our
  coordinates, are the standard ones; what differs is after each update: the correction moves the state
  through the group's exponential (the whole map turns with the heading's correction), and the covariance is
  carried to the new estimate (``P <- T P T^T``, ``T = I + c e_theta^T``, ``c = J (point_new - point_old)``
  per position). Its unobservable directions do not depend on the estimate, so no first estimate is needed.

Both hold for any point-landmark sighting model (range-bearing, position in the robot frame): the constraints
involve only the positions. The innovation always uses the current estimate.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import blas

from online_slam.estimators.kalman import mirror_upper

Array = NDArray[np.float64]

FIRST_ESTIMATES = ("fej", "oc")
"""The linearizations that need the newest pose as predicted and each landmark's first estimate."""
PERP = np.array([[0.0, -1.0], [1.0, 0.0]])
"""Rotation by +90 degrees, ``J``: ``d (R(theta) v) / d theta = J R(theta) v``."""


def heading_column(to: Array, origin: Array | float) -> Array:
    """``J (to - origin)``: how a point ``to`` moves per radian of a turn about ``origin``, shape (..., 2)."""
    d = np.asarray(to, dtype=float) - np.asarray(origin, dtype=float)
    return np.stack([-d[..., 1], d[..., 0]], -1)


def null_space(robot: Array, landmarks: Array) -> Array:
    """The unobservable directions of a sighting's variables [robot (3), landmark (2)], shape (k, 5, 3).

    Args:
        robot: Robot position the directions are taken at, shape (2,).
        landmarks: Each sighting's landmark position, shape (k, 2).
    """
    k = len(landmarks)
    N = np.zeros((k, 5, 3))
    N[:, 0:2, 0:2] = np.eye(2)
    N[:, 0:2, 2] = heading_column(robot, 0.0)
    N[:, 2, 2] = 1.0
    N[:, 3:5, 0:2] = np.eye(2)
    N[:, 3:5, 2] = heading_column(landmarks, 0.0)
    return N


def observable(J_pose: Array, J_landmark: Array, robot: Array, landmarks: Array) -> tuple[Array, Array]:
    """The sightings' Jacobians nearest (Frobenius) to the given ones that see nothing along :func:`null_space`.

    Args:
        J_pose: d z / d robot, shape (k, m, 3).
        J_landmark: d z / d landmark, shape (k, m, 2).
        robot: Robot position of the null space (the newest pose as predicted), shape (2,).
        landmarks: Landmark positions of the null space (their first estimates), shape (k, 2).

    Returns:
        (d z / d robot (k, m, 3), d z / d landmark (k, m, 2)) with ``[J_pose, J_landmark] N = 0``.
    """
    H = np.concatenate([J_pose, J_landmark], axis=-1)  # (k, m, 5)
    N = null_space(robot, landmarks)
    HN = H @ N
    H = H - HN @ np.linalg.solve(N.transpose(0, 2, 1) @ N, N.transpose(0, 2, 1))
    return H[..., :3], H[..., 3:]


def invariant_retraction(x: Array, dx: Array) -> tuple[Array, Array]:
    """Apply a correction ``dx`` (our coordinates) to ``x = [x, y, theta, l1x, l1y, ...]`` on SE_{1+M}(2).

    ``dx`` is read as the group error ``xi`` (``xi_p = dx_p - J p theta_dx`` for the robot and each landmark) and
    applied as ``exp(xi) X``: every position turns by the heading's correction about the origin.

    Args:
        x: State, shape (3 + 2M,).
        dx: Correction, shape (3 + 2M,).

    Returns:
        (the corrected state (3 + 2M,), the column ``c`` (3 + 2M,) of the covariance's transport
        ``T = I + c e_theta^T``: ``c = J (point_new - point_old)`` per position, 0 at the heading).
    """
    a = float(dx[2])
    points = np.r_[x[:2], x[3:]].reshape(-1, 2)
    xi = np.r_[dx[:2], dx[3:]].reshape(-1, 2) - a * heading_column(points, 0.0)
    c, s = math.cos(a), math.sin(a)
    if abs(a) > 1e-9:
        V = np.array([[s / a, -(1.0 - c) / a], [(1.0 - c) / a, s / a]])
    else:
        V = np.array([[1.0, -a / 2.0], [a / 2.0, 1.0]])
    moved = points @ np.array([[c, s], [-s, c]]) + xi @ V.T
    new = np.r_[moved[0], x[2] + a, moved[1:].ravel()]
    turn = heading_column(moved - points, 0.0).ravel()
    column = np.r_[turn[:2], 0.0, turn[2:]]
    return new, column


def transport(P: Array, column: Array, heading: int = 2) -> None:
    """``P <- T P T^T`` in place with ``T = I + column e_heading^T``; O(n^2).

    It is the symmetric rank-2 update ``P += c v^T + v c^T`` (``v = P e_heading + P_hh c / 2``). Contiguous P takes
    BLAS ``syr2`` on one triangle, mirrored (:func:`~online_slam.estimators.kalman.mirror_upper`): no n x n
    temporary, and symmetric bit for bit whatever kernel the CPU selects.
    """
    c = np.asarray(column, dtype=np.float64)
    v = P[:, heading] + 0.5 * P[heading, heading] * c
    F = P.T if P.flags.c_contiguous else P  # the Fortran-ordered view BLAS updates in place
    if not F.flags.f_contiguous or P.dtype != np.float64:
        P += np.triu(np.outer(c, v) + np.outer(v, c))
        mirror_upper(P)
        return
    updated = blas.dsyr2(1.0, c, v, a=F, overwrite_a=1, lower=0)
    assert np.shares_memory(updated, P), "syr2 did not update in place"
    mirror_upper(F)
