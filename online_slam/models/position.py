"""Position sighting of a 2D point landmark: its position in the robot frame, and its inverse.

An observation is ``z = [dx, dy] = R(theta)^T (l - t)``, the landmark ``l`` expressed in the frame of the robot
pose ``(t, theta)`` (a fiducial detector, a stereo or RGB-D cone detector give exactly this). No angle is
involved in z, so nothing is wrapped, and the model is defined everywhere (also for a landmark at the sensor).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def position(pose: ArrayLike, landmark: ArrayLike) -> Array:
    """Predicted observation.

    Args:
        pose: Robot poses ``T_world_robot``, shape (..., 3).
        landmark: Landmark positions in the world, shape (..., 2).

    Returns:
        ``[dx, dy]``, the landmark in the robot frame, shape (..., 2).
    """
    return position_with_jacobians(pose, landmark)[0]


def position_with_jacobians(pose: ArrayLike, landmark: ArrayLike) -> tuple[Array, Array, Array]:
    """``position`` with its Jacobians.

    Returns:
        (z (..., 2), dz/dpose (..., 2, 3), dz/dlandmark (..., 2, 2)).
    """
    pose = np.asarray(pose, dtype=float)
    landmark = np.asarray(landmark, dtype=float)
    dx = landmark[..., 0] - pose[..., 0]
    dy = landmark[..., 1] - pose[..., 1]
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    shape = np.broadcast_shapes(pose.shape[:-1], landmark.shape[:-1])
    z = np.empty((*shape, 2))
    z[..., 0] = c * dx + s * dy
    z[..., 1] = c * dy - s * dx
    J_l = np.empty((*shape, 2, 2))  # R(theta)^T
    J_l[..., 0, 0] = c
    J_l[..., 0, 1] = s
    J_l[..., 1, 0] = -s
    J_l[..., 1, 1] = c
    J_p = np.empty((*shape, 2, 3))
    J_p[..., :, :2] = -J_l
    J_p[..., 0, 2] = z[..., 1]
    J_p[..., 1, 2] = -z[..., 0]
    return z, J_p, J_l


def landmark_from_position(pose: ArrayLike, z: ArrayLike) -> Array:
    """Inverse observation model: the landmark position that explains z exactly, ``l = t + R(theta) z``.

    Args:
        pose: Robot poses, shape (..., 3).
        z: Observations ``[dx, dy]`` in the robot frame, shape (..., 2).

    Returns:
        Landmark positions in the world, shape (..., 2).
    """
    return landmark_from_position_with_jacobians(pose, z)[0]


def landmark_from_position_with_jacobians(pose: ArrayLike, z: ArrayLike) -> tuple[Array, Array, Array]:
    """``landmark_from_position`` with its Jacobians.

    Returns:
        (landmark (..., 2), d/dpose (..., 2, 3), d/dz (..., 2, 2)).
    """
    pose = np.asarray(pose, dtype=float)
    z = np.asarray(z, dtype=float)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    shape = np.broadcast_shapes(pose.shape[:-1], z.shape[:-1])
    ox = c * z[..., 0] - s * z[..., 1]  # the sighting's offset in the world frame
    oy = s * z[..., 0] + c * z[..., 1]
    J_p = np.zeros((*shape, 2, 3))
    J_p[..., 0, 0] = 1.0
    J_p[..., 1, 1] = 1.0
    J_p[..., 0, 2] = -oy
    J_p[..., 1, 2] = ox
    J_z = np.empty((*shape, 2, 2))  # R(theta)
    J_z[..., 0, 0] = c
    J_z[..., 0, 1] = -s
    J_z[..., 1, 0] = s
    J_z[..., 1, 1] = c
    value = np.stack([pose[..., 0] + ox, pose[..., 1] + oy], -1)
    return value, J_p, J_z


def range_bearing_from_position(z: ArrayLike, cov: ArrayLike) -> tuple[Array, Array]:
    """The same sighting as ``[range, bearing]`` with its covariance propagated to first order.

    Args:
        z: Observations ``[dx, dy]``, shape (..., 2), not at the sensor.
        cov: Their covariances, shape (..., 2, 2).

    Returns:
        (``[range, bearing]`` (..., 2), covariances (..., 2, 2)).
    """
    z = np.asarray(z, dtype=float)
    r = np.hypot(z[..., 0], z[..., 1])
    J = np.empty((*z.shape[:-1], 2, 2))
    J[..., 0, 0] = z[..., 0] / r
    J[..., 0, 1] = z[..., 1] / r
    J[..., 1, 0] = -z[..., 1] / (r * r)
    J[..., 1, 1] = z[..., 0] / (r * r)
    out = J @ np.asarray(cov, dtype=float) @ np.swapaxes(J, -1, -2)
    return np.stack([r, np.arctan2(z[..., 1], z[..., 0])], -1), 0.5 * (out + np.swapaxes(out, -1, -2))
