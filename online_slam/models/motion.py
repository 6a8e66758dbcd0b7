"""Odometry: the measured increment between consecutive poses, and composing increments.

The odometry residual is the article's: ``e = between(a, b) - delta`` with its angle wrapped, i.e. the noise is
additive on the increment expressed in the earlier pose's frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, between_with_jacobians, compose_with_jacobians, exp, log

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


def split_increment(d: ArrayLike, cov: ArrayLike, fraction: float) -> tuple[Array, Array, Array, Array]:
    """Split one increment at a fraction of its time, at constant twist: ``d = a * b``.

    ``a = exp(fraction * log(d))`` and ``b = a^-1 * d``, so the two compose to ``d`` exactly. The covariance is
    split in proportion to time in the frame of the whole increment: ``cov_a = f J_a^-1 cov J_a^-T`` and
    ``cov_b = (1 - f) J_b^-1 cov J_b^-T`` (``J_a``, ``J_b`` the Jacobians of ``a * b``), so that
    :func:`compose_increments` of the two parts gives ``cov`` back exactly (to rounding).

    Args:
        d: Increment, shape (3,).
        cov: Its covariance, shape (3, 3).
        fraction: Share of its time before the split, in (0, 1).

    Returns:
        (a (3,), cov_a (3, 3), b (3,), cov_b (3, 3)).
    """
    d = np.asarray(d, dtype=float)
    cov = np.asarray(cov, dtype=float)
    a = exp(fraction * log(d))
    b = between(a, d)
    _, J_a, J_b = compose_with_jacobians(a, b)
    inv_a, inv_b = np.linalg.inv(J_a), np.linalg.inv(J_b)
    cov_a = fraction * (inv_a @ cov @ inv_a.T)
    cov_b = (1.0 - fraction) * (inv_b @ cov @ inv_b.T)
    return a, 0.5 * (cov_a + cov_a.T), b, 0.5 * (cov_b + cov_b.T)


def extrapolate_increment(d: ArrayLike, cov: ArrayLike, fraction: float) -> tuple[Array, Array]:
    """The motion over ``fraction`` times an increment's time span at its constant twist (``fraction`` >= 0, more
    than 1 to extrapolate), with its covariance scaled in proportion: ``(exp(f log d), f cov)``.

    Args:
        d: Increment, shape (3,).
        cov: Its covariance, shape (3, 3).
        fraction: Time span relative to the increment's.

    Returns:
        (increment (3,), covariance (3, 3)).
    """
    return exp(fraction * log(np.asarray(d, dtype=float))), fraction * np.asarray(cov, dtype=float)


Increment = tuple[float, float, Array, Array]
"""An odometry increment over time: (begin, end, ``[dx, dy, dtheta]`` (3,), its covariance (3, 3))."""


def predict_pose(
    pose: ArrayLike,
    cov: ArrayLike | None,
    t: float,
    increments: list[Increment],
    at: float,
    motion: Increment | None = None,
) -> tuple[Array, Array | None]:
    """A pose at time ``t`` moved on to time ``at`` with the increments that follow it, at constant twist.

    Increments ending by ``at`` are composed whole; one spanning ``at`` is cut there
    (:func:`split_increment`); past the last one the motion goes on at the twist of ``motion`` (default: the last
    increment; :func:`extrapolate_increment`). With neither the pose stays. Covariance is propagated to first
    order.

    Args:
        pose: ``[x, y, theta]`` at ``t``, shape (3,).
        cov: Its covariance (3, 3), or None (none is propagated).
        t: Its time, seconds.
        increments: In time order, the first beginning at ``t``.
        at: The time to predict to (>= ``t``).
        motion: The increment whose twist goes on past the last one, or None.

    Returns:
        (pose (3,), covariance (3, 3) or None).
    """
    pose = np.asarray(pose, dtype=float)
    sigma = None if cov is None else np.asarray(cov, dtype=float)
    now = t
    for begin, end, delta, delta_cov in increments:
        if at <= begin:
            break
        if at < end:
            delta, delta_cov = split_increment(delta, delta_cov, (at - begin) / (end - begin))[:2]
        pose, sigma = _moved(pose, sigma, delta, delta_cov)
        now = min(end, at)
    motion = motion if motion is not None else (increments[-1] if increments else None)
    if at > now and motion is not None:
        begin, end, delta, delta_cov = motion
        if end > begin:
            step, step_cov = extrapolate_increment(delta, delta_cov, (at - now) / (end - begin))
            pose, sigma = _moved(pose, sigma, step, step_cov)
    return pose, sigma


def _moved(pose: Array, cov: Array | None, delta: Array, delta_cov: Array) -> tuple[Array, Array | None]:
    moved, J_pose, J_delta = compose_with_jacobians(pose, delta)
    if cov is None:
        return moved, None
    out = J_pose @ cov @ J_pose.T + J_delta @ delta_cov @ J_delta.T
    return moved, 0.5 * (out + out.T)


def unbiased_increment(delta: ArrayLike, bias: ArrayLike, dt: float) -> tuple[Array, Array]:
    """An odometry increment with a robot's odometry bias taken off, and its Jacobian in the bias.

    The bias ``[s, w]`` is what the odometry reads beyond the motion: the share ``s`` of each logged distance that
    is not real (distances overstated by ``1 / (1 - s)``) and a heading rate ``w`` (rad/s) added to each turn, so
    the motion is ``[(1 - s) dx, (1 - s) dy, dtheta - w dt]`` (linear in the bias: its Jacobian is exact).

    Args:
        delta: Measured increment ``[dx, dy, dtheta]``, shape (3,).
        bias: ``[s, w]``, shape (2,).
        dt: The increment's time span, seconds.

    Returns:
        (the increment without the bias (3,), its derivative in ``[s, w]`` (3, 2)).
    """
    d = np.asarray(delta, dtype=float)
    s, w = np.asarray(bias, dtype=float)
    moved = np.array([(1.0 - s) * d[0], (1.0 - s) * d[1], d[2] - w * dt])
    jacobian = np.array([[-d[0], 0.0], [-d[1], 0.0], [0.0, -dt]])
    return moved, jacobian
