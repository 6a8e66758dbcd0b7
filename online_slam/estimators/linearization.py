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

Both hold for any point-landmark sighting model (range-bearing, position in the robot frame): the constraints
involve only the positions. The innovation always uses the current estimate.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

LINEARIZATIONS = ("standard", "fej", "oc")
"""Where the EKF evaluates its Jacobians (see the module docstring)."""
PERP = np.array([[0.0, -1.0], [1.0, 0.0]])
"""Rotation by +90 degrees, ``J``: ``d (R(theta) v) / d theta = J R(theta) v``."""


def heading_column(to: Array, origin: Array) -> Array:
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
