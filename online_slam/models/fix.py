"""Absolute fixes of a pose: a point of the robot frame at a map position (GPS), or the heading (a compass).

Both are one residual on a single pose, ``e = fixed(pose, offset) - mean`` with

    fixed(pose, offset) = [x + R(theta) offset, theta]     (shape 3: the fixed point, then the heading)

whitened by a square-root information ``W`` (3 x 3) whose rows pick what the fix measures: a position fix has
its 2 x 2 ``W`` in the top-left block and a zero last row, a heading fix only ``W[2, 2] = 1 / sigma``. With a zero
offset and a full ``W`` it is the prior on a pose that starts carry, so a fix is a prior row of the factor graph
(:class:`~online_slam.factors.graph.FactorGraph`'s ``prior_offset``) and every estimator takes it as such.
The heading residual is wrapped (:func:`~online_slam.geometry.angles.wrap`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from online_slam.geometry.angles import wrap

if TYPE_CHECKING:  # events import the models: only their types here
    from online_slam.sources.events import Heading, Position

Array = NDArray[np.float64]

FIX_FALSE_ALARM = 1e-9
"""The fixes' gate, looser than the sightings' (1e-4): a fix is the only absolute measurement and comes seldom, so
refusing one that disagrees because the estimate drifted costs more than a sighting; a GPS jump of metres still
fails. Victoria Park, fixes every 30 s: 45 of 48 used and 0.705x the error without fixes, against 37 and 0.777x at
the sightings' gate (benchmarks/RESULTS.md, "Victoria Park with GPS fixes")."""


def fix_residual_with_jacobians(pose: ArrayLike, offset: ArrayLike, mean: ArrayLike) -> tuple[Array, Array]:
    """Unwhitened fix residuals and their Jacobians.

    Args:
        pose: Poses ``[x, y, theta]``, shape (..., 3).
        offset: Fixed points ``[dx, dy]`` in the robot frame, shape (..., 2).
        mean: Fixed values ``[x, y, theta]`` in the map frame, shape (..., 3).

    Returns:
        (e = fixed(pose, offset) - mean with the heading wrapped (..., 3), de/dpose (..., 3, 3)).
    """
    pose, offset, mean = (np.asarray(a, dtype=float) for a in (pose, offset, mean))
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    ox = c * offset[..., 0] - s * offset[..., 1]  # the offset in the map frame
    oy = s * offset[..., 0] + c * offset[..., 1]
    shape = np.broadcast_shapes(pose.shape[:-1], offset.shape[:-1], mean.shape[:-1])
    e = np.empty((*shape, 3))
    e[..., 0] = pose[..., 0] + ox - mean[..., 0]
    e[..., 1] = pose[..., 1] + oy - mean[..., 1]
    e[..., 2] = wrap(pose[..., 2] - mean[..., 2])
    J = np.zeros((*shape, 3, 3))
    J[..., 0, 0] = J[..., 1, 1] = J[..., 2, 2] = 1.0
    J[..., 0, 2] = -oy
    J[..., 1, 2] = ox
    return e, J


GPS_CORRELATION_S = 5.0
"""Time constant (s) of a GPS receiver's errors, which the importers declare with GPS fixes (the header's
``fix_correlation_s``: the raw Victoria Park log's, and a bag's NavSatFix): chosen on Victoria Park's first half with a
fix every 2 s among 0, 5, 10, 20 and 40 s (EKF and smoother both best there), scored on its second half
(benchmarks/RESULTS.md, "Victoria Park with GPS fixes"). The one GPS log we have: a guess for another receiver."""


def fixed_point(pose: ArrayLike, offset: ArrayLike) -> Array:
    """The map position of the robot-frame point ``offset`` at ``pose``, shape (..., 2)."""
    pose = np.asarray(pose, dtype=float)
    zero = np.zeros(pose.shape[:-1] + (3,))
    return fix_residual_with_jacobians(pose, offset, zero)[0][..., :2]


def fix_factors(fixes: Sequence[Position | Heading]) -> tuple[Array, Array, Array]:
    """The factor rows of fix events: (mean (f, 3), offset (f, 2), square-root information (f, 3, 3)).

    A position fix's ``W`` is ``chol(cov)^-1`` in its top-left block (its heading row zero); a heading fix's is
    ``1 / sigma`` at ``[2, 2]`` (its position rows zero).
    """
    f = len(fixes)
    mean, offset, W = np.zeros((f, 3)), np.zeros((f, 2)), np.zeros((f, 3, 3))
    for k, fix in enumerate(fixes):
        if hasattr(fix, "theta"):  # a Heading (the types only are imported here)
            heading = cast("Heading", fix)
            mean[k, 2] = heading.theta
            W[k, 2, 2] = 1.0 / heading.sigma
        else:
            assert not hasattr(fix, "theta")  # a Position
            mean[k, :2] = fix.xy
            W[k, :2, :2] = np.linalg.inv(np.linalg.cholesky(fix.covariance))
            if fix.offset is not None:
                offset[k] = fix.offset
    return mean, offset, W


def fix_nis(pose: ArrayLike, cov: ArrayLike, fixes: Sequence[Position | Heading]) -> tuple[Array, NDArray[np.int64]]:
    """Each fix's NIS against a pose estimate ``pose`` (3,) of covariance ``cov`` (3, 3), by the fix's own covariance
    (not as widened for correlation in time: ``widened`` taken off), over the rows it measures, and its degrees of
    freedom (2 for a position, 1 for a heading); shapes (f,)."""
    mean, offset, W = fix_factors(fixes)
    e, J = fix_residual_with_jacobians(np.broadcast_to(np.asarray(pose, dtype=float), (len(fixes), 3)), offset, mean)
    own = np.sqrt([fix.widened for fix in fixes])
    y, H = own[:, None] * np.einsum("kij,kj->ki", W, e), own[:, None, None] * (W @ J)  # (f, 3), (f, 3, 3)
    nis, dof = np.zeros(len(fixes)), np.zeros(len(fixes), dtype=np.int64)
    for k in range(len(fixes)):  # a step's few fixes
        rows = np.any(H[k] != 0.0, axis=1)  # what a fix does not measure: zero rows
        S = H[k][rows] @ np.asarray(cov, dtype=float) @ H[k][rows].T + np.eye(int(rows.sum()))
        nis[k], dof[k] = float(y[k][rows] @ np.linalg.solve(S, y[k][rows])), int(rows.sum())
    return nis, dof


def correlated_widening(dt: float, tau: float) -> float:
    """How much to widen a fix's covariance whose error is first-order Markov with time constant ``tau`` (s), taken
    ``dt`` (s) after the previous fix of its kind: ``(1 + rho) / (1 - rho)``, ``rho = exp(-dt / tau)``.

    A long run of such fixes, every ``dt``, holds the information of independent ones with that much wider
    covariance (the mean of n AR(1) samples has variance ``sigma^2 (1 + rho) / ((1 - rho) n)`` as n grows), so the
    widened fixes can be used as independent factors. 1 when far apart (``dt >> tau``); a fix at the same time as
    the previous one (``dt <= 0``) carries nothing new: widened by 1e12.
    """
    if dt <= 0.0:
        return 1e12
    rho = math.exp(-dt / tau)
    return min(1e12, (1.0 + rho) / -math.expm1(-dt / tau))
