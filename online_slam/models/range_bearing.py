"""Range-bearing observation of a 2D point landmark, and its inverse (landmark initialisation).

An observation is ``z = [range, bearing]`` with bearing measured from the robot's heading,
``bearing = wrap(atan2(ly - y, lx - x) - theta)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap

Array = NDArray[np.float64]


def range_bearing(pose: ArrayLike, landmark: ArrayLike) -> Array:
    """Predicted observation.

    Args:
        pose: Robot poses ``T_world_robot``, shape (..., 3).
        landmark: Landmark positions in the world, shape (..., 2).

    Returns:
        ``[range, bearing]``, shape (..., 2), bearing wrapped.
    """
    pose = np.asarray(pose, dtype=float)
    landmark = np.asarray(landmark, dtype=float)
    dx = landmark[..., 0] - pose[..., 0]
    dy = landmark[..., 1] - pose[..., 1]
    return np.stack([np.hypot(dx, dy), wrap(np.arctan2(dy, dx) - pose[..., 2])], -1)


def range_bearing_with_jacobians(pose: ArrayLike, landmark: ArrayLike) -> tuple[Array, Array, Array]:
    """``range_bearing`` with its Jacobians.

    Decision: at a landmark exactly on the pose (range 0, where the bearing is undefined) the position Jacobians are
    0, not NaN (and the bearing is ``wrap(-theta)``, as ``atan2(0, 0)`` gives): a solver's trial step can land there
    (a robust solve pulling an outlier landmark onto a pose that sights it), and one such point must not put NaN
    into the normal equations. Any other point is unchanged.

    Returns:
        (z (..., 2), dz/dpose (..., 2, 3), dz/dlandmark (..., 2, 2)).
    """
    pose = np.asarray(pose, dtype=float)
    landmark = np.asarray(landmark, dtype=float)
    dx = landmark[..., 0] - pose[..., 0]
    dy = landmark[..., 1] - pose[..., 1]
    q = dx * dx + dy * dy
    r = np.sqrt(q)
    q_safe = np.where(q == 0.0, 1.0, q)  # on the pose dx = dy = 0: Jacobians 0
    r_safe = np.sqrt(q_safe)
    shape = np.broadcast_shapes(pose.shape[:-1], landmark.shape[:-1])
    J_l = np.empty((*shape, 2, 2))
    J_l[..., 0, 0] = dx / r_safe
    J_l[..., 0, 1] = dy / r_safe
    J_l[..., 1, 0] = -dy / q_safe
    J_l[..., 1, 1] = dx / q_safe
    J_p = np.zeros((*shape, 2, 3))
    J_p[..., :, :2] = -J_l
    J_p[..., 1, 2] = -1.0
    z = np.stack([r, wrap(np.arctan2(dy, dx) - pose[..., 2])], -1)
    return z, J_p, J_l


def landmark_from_observation(pose: ArrayLike, z: ArrayLike) -> Array:
    """Inverse observation model: the landmark position that explains z exactly.

    Args:
        pose: Robot poses, shape (..., 3).
        z: Observations ``[range, bearing]``, shape (..., 2).

    Returns:
        Landmark positions in the world, shape (..., 2).
    """
    pose = np.asarray(pose, dtype=float)
    z = np.asarray(z, dtype=float)
    angle = pose[..., 2] + z[..., 1]
    return np.stack([pose[..., 0] + z[..., 0] * np.cos(angle), pose[..., 1] + z[..., 0] * np.sin(angle)], -1)


def landmark_from_observation_with_jacobians(pose: ArrayLike, z: ArrayLike) -> tuple[Array, Array, Array]:
    """``landmark_from_observation`` with its Jacobians.

    Returns:
        (landmark (..., 2), d/dpose (..., 2, 3), d/dz (..., 2, 2)).
    """
    pose = np.asarray(pose, dtype=float)
    z = np.asarray(z, dtype=float)
    angle = pose[..., 2] + z[..., 1]
    c, s = np.cos(angle), np.sin(angle)
    rng = z[..., 0]
    shape = np.broadcast_shapes(pose.shape[:-1], z.shape[:-1])
    J_p = np.zeros((*shape, 2, 3))
    J_p[..., 0, 0] = 1.0
    J_p[..., 1, 1] = 1.0
    J_p[..., 0, 2] = -rng * s
    J_p[..., 1, 2] = rng * c
    J_z = np.empty((*shape, 2, 2))
    J_z[..., 0, 0] = c
    J_z[..., 1, 0] = s
    J_z[..., 0, 1] = -rng * s
    J_z[..., 1, 1] = rng * c
    value = np.stack([pose[..., 0] + rng * c, pose[..., 1] + rng * s], -1)
    return value, J_p, J_z


def robot_sighting_residual_with_jacobians(pose_a: Array, pose_b: Array, z: Array) -> tuple[Array, Array, Array]:
    """Residual of robot sightings (pose b's position seen from pose a) with its Jacobians.

    Args:
        pose_a: Sighting poses, shape (R, 3). pose_b: Sighted poses, shape (R, 3).
        z: Measured ``[range, bearing]``, shape (R, 2).

    Returns:
        (e = h(a, b_xy) - z with the bearing wrapped (R, 2), de/da (R, 2, 3), de/db (R, 2, 3); b's heading has none).
    """
    h, J_a, J_xy = range_bearing_with_jacobians(pose_a, pose_b[:, :2])
    e = h - z
    e[:, 1] = wrap(e[:, 1])
    J_b = np.zeros_like(J_a)
    J_b[:, :, :2] = J_xy
    return e, J_a, J_b
