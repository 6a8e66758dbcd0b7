"""The EKF's odometry bias: per robot ``[s, w]`` in the state, estimated with the poses and the map.

A robot whose odometry errs alike for minutes (a wheel radius off, a drift in the turn rate) is lost by a filter
that takes each increment's error as independent: the composed error grows with the stretch, the covariance with
its square root (benchmarks/RESULTS.md, "Odometry biased beyond the model"). Where the stream asks for it
(:attr:`~online_slam.frontend.pose.Step.odometry_bias`: the prior sigmas on each robot's first step), the state
holds each robot's bias after the robots' poses and before the landmarks, in the robots' order
(``[poses (3R), biases (2R), landmarks (2M)]``), constant with a zero-mean prior: the increment is read as
:func:`~online_slam.models.motion.unbiased_increment` says, and its Jacobian in the bias enters the prediction
(``P_rr = F P_rr F^T + F P_rb B^T + B P_br F^T + B P_bb B^T + G Q G^T`` with ``B = G d(increment)/d(bias)``).
No sighting sees the bias; it moves through its correlation with the pose. The invariant retraction turns
positions only: a bias keeps its value under the group's turn (:func:`invariant_points`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.ekf_state import EkfState

Array = NDArray[np.float64]


class OdometryBias:
    """The bias part of :class:`~online_slam.estimators.ekf.EkfSlam` (a mixin)."""

    state: EkfState
    x: Array
    P: Array
    _resized: Callable[[], None]
    """The filter's bookkeeping after the state's size changed."""

    @property
    def _pose_end(self) -> int:
        """Column after the robots' poses (3 per robot)."""
        return 3 * len(self.state.robots)

    @property
    def _offset(self) -> int:
        """First state column of the landmarks: after the poses and, when modelled, the biases (2 per robot)."""
        return (5 if self.state.biased else 3) * len(self.state.robots)

    def _inserted(self, at: int, values: Array, cov: Array) -> None:
        """Insert entries with the given mean (m,) and covariance (m, m), uncorrelated with the rest, at ``at``."""
        n, m = len(self.x), len(values)
        where = np.r_[np.arange(at), np.arange(at, n) + m]
        x, P = np.zeros((n + m, 1)), np.zeros((n + m, n + m))
        x[where], x[at : at + m, 0] = self.x, values
        P[np.ix_(where, where)] = self.P
        P[at : at + m, at : at + m] = cov
        self.x, self.P = x, P

    def _bias_block(self, step: Any) -> Array:
        """A robot's bias prior covariance (2, 2) from its first step (zero, the bias held at 0, without one)."""
        sigmas = step.odometry_bias
        return np.zeros((2, 2)) if sigmas is None else np.diag(np.square(np.asarray(sigmas, dtype=float)))

    def _begin_bias(self, step: Any) -> None:
        """The first robot's first step: a bias state when the step asks for one (the state then holds one per
        robot from now on)."""
        if step.odometry_bias is None or self.state.biased:
            return
        self._inserted(self._pose_end, np.zeros(2), self._bias_block(step))
        self.state.biased = True
        self._resized()

    def _bias_columns(self, k: int = 0) -> NDArray[np.int64]:
        """Robot k's bias columns (2,) (0: the active robot's)."""
        return self._pose_end + 2 * k + np.arange(2)

    def _swap_biases(self, order: NDArray[np.int64], k: int) -> None:
        """Robot k's block becomes the first: swap the bias blocks too in the permutation ``order``."""
        if self.state.biased:
            a, b = self._bias_columns(), self._bias_columns(k)
            order[a], order[b] = order[b], order[a]

    def _bias_of(self, k: int) -> tuple[float, float, float, float]:
        """Robot k's ``(s, w, sd of s, sd of w)``."""
        cols = self._bias_columns(k)
        s, w = self.x[cols, 0]
        sd_s, sd_w = np.sqrt(np.maximum(self.P[cols, cols], 0.0))
        return float(s), float(w), float(sd_s), float(sd_w)

    def _step_bias(self) -> dict[str, Any]:
        """A snapshot's ``odometry_bias``: the newest pose's robot's ``(s, w, sd of s, sd of w)`` (none when not
        modelled)."""
        return {"odometry_bias": self._bias_of(0)} if self.state.biased else {}

    def _bias_info(self) -> dict[str, Any]:
        """The final estimate's ``odometry_bias``: by robot, ``(s, w, sd of s, sd of w)`` (none when not modelled)."""
        if not self.state.biased:
            return {}
        return {"odometry_bias": {robot: self._bias_of(k) for k, robot in enumerate(self.state.robots)}}


def invariant_points(n: int, biased: bool) -> NDArray[np.int64]:
    """The state entries the invariant retraction reads as ``[x, y, theta, l1x, l1y, ...]`` (one robot): all but
    the bias (entries 3 and 4 when ``biased``)."""
    return np.r_[0:3, 5:n] if biased else np.arange(n)
