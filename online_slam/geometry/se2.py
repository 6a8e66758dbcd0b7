"""SE(2) poses as ``[x, y, theta]`` arrays, vectorised over leading axes.

A pose ``T_world_b`` maps points of frame b into the world. ``compose(a, d)`` is ``a * d``; ``between(a, b)`` is
``a^-1 * b``, the motion from a to b expressed in a's frame. Jacobians are with respect to the vector
``[x, y, theta]`` of each argument (the parameterisation the estimators use).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap

Array = NDArray[np.float64]


def rotation(theta: ArrayLike) -> Array:
    """Rotation matrices.

    Args:
        theta: Angles, shape (...).

    Returns:
        Shape (..., 2, 2).
    """
    t = np.asarray(theta, dtype=float)
    c, s = np.cos(t), np.sin(t)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def compose(a: ArrayLike, d: ArrayLike) -> Array:
    """``a * d``: apply the increment d (in a's frame) to pose a.

    Args:
        a: Poses, shape (..., 3).
        d: Increments, shape (..., 3).

    Returns:
        Poses, shape (..., 3), heading wrapped.
    """
    a = np.asarray(a, dtype=float)
    d = np.asarray(d, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * d[..., 0] - s * d[..., 1]
    y = a[..., 1] + s * d[..., 0] + c * d[..., 1]
    return np.stack([x, y, wrap(a[..., 2] + d[..., 2])], -1)


def compose_with_jacobians(a: ArrayLike, d: ArrayLike) -> tuple[Array, Array, Array]:
    """``compose`` with its Jacobians.

    Returns:
        (pose (..., 3), d/da (..., 3, 3), d/dd (..., 3, 3)).
    """
    a = np.asarray(a, dtype=float)
    d = np.asarray(d, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    shape = np.broadcast_shapes(a.shape, d.shape)[:-1]
    J_a = np.zeros((*shape, 3, 3))
    J_a[..., 0, 0] = 1.0
    J_a[..., 1, 1] = 1.0
    J_a[..., 2, 2] = 1.0
    J_a[..., 0, 2] = -s * d[..., 0] - c * d[..., 1]
    J_a[..., 1, 2] = c * d[..., 0] - s * d[..., 1]
    J_d = np.zeros((*shape, 3, 3))
    J_d[..., :2, :2] = rotation(a[..., 2])
    J_d[..., 2, 2] = 1.0
    return compose(a, d), J_a, J_d


def between(a: ArrayLike, b: ArrayLike) -> Array:
    """``a^-1 * b``: the motion from a to b in a's frame.

    Args:
        a: Poses, shape (..., 3).
        b: Poses, shape (..., 3).

    Returns:
        Increments, shape (..., 3), angle wrapped.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx = b[..., 0] - a[..., 0]
    dy = b[..., 1] - a[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap(b[..., 2] - a[..., 2])], -1)


def between_with_jacobians(a: ArrayLike, b: ArrayLike) -> tuple[Array, Array, Array]:
    """``between`` with its Jacobians.

    Returns:
        (increment (..., 3), d/da (..., 3, 3), d/db (..., 3, 3)).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx = b[..., 0] - a[..., 0]
    dy = b[..., 1] - a[..., 1]
    shape = np.broadcast_shapes(a.shape, b.shape)[:-1]
    J_b = np.zeros((*shape, 3, 3))
    J_b[..., 0, 0] = c
    J_b[..., 0, 1] = s
    J_b[..., 1, 0] = -s
    J_b[..., 1, 1] = c
    J_b[..., 2, 2] = 1.0
    J_a = -J_b
    J_a[..., 0, 2] = -s * dx + c * dy
    J_a[..., 1, 2] = -c * dx - s * dy
    value = np.stack([c * dx + s * dy, -s * dx + c * dy, wrap(b[..., 2] - a[..., 2])], -1)
    return value, J_a, J_b


def inverse(a: ArrayLike) -> Array:
    """``a^-1``.

    Args:
        a: Poses, shape (..., 3).

    Returns:
        Inverse poses, shape (..., 3).
    """
    a = np.asarray(a, dtype=float)
    return between(a, np.zeros_like(a))
