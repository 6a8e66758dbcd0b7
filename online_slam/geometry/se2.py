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


def _v_terms(theta: Array) -> tuple[Array, Array]:
    """``sin(t)/t`` and ``(1 - cos(t))/t`` of SE(2)'s left Jacobian V, with their Taylor series near 0."""
    small = np.abs(theta) < 1e-6
    safe = np.where(small, 1.0, theta)
    t2 = theta * theta
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, theta / 2.0 - theta * t2 / 24.0, (1.0 - np.cos(safe)) / safe)
    return a, b


def exp(xi: ArrayLike) -> Array:
    """The pose reached by moving with constant twist ``xi = [vx, vy, omega]`` (body frame) for unit time.

    Args:
        xi: Twists, shape (..., 3).

    Returns:
        Increments ``[dx, dy, dtheta]``, shape (..., 3), heading wrapped.
    """
    xi = np.asarray(xi, dtype=float)
    a, b = _v_terms(xi[..., 2])
    x = a * xi[..., 0] - b * xi[..., 1]
    y = b * xi[..., 0] + a * xi[..., 1]
    return np.stack([x, y, wrap(xi[..., 2])], -1)


def log(d: ArrayLike) -> Array:
    """The constant twist that reaches the increment ``d`` in unit time (inverse of :func:`exp` for headings in
    [-pi, pi)).

    Args:
        d: Increments, shape (..., 3).

    Returns:
        Twists ``[vx, vy, omega]``, shape (..., 3).
    """
    d = np.asarray(d, dtype=float)
    theta = wrap(d[..., 2])
    a, b = _v_terms(theta)
    det = a * a + b * b  # V = [[a, -b], [b, a]], never singular for |theta| < 2 pi
    vx = (a * d[..., 0] + b * d[..., 1]) / det
    vy = (-b * d[..., 0] + a * d[..., 1]) / det
    return np.stack([vx, vy, theta], -1)
