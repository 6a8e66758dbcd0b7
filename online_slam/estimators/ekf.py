"""EKF-SLAM on filterpy: a state that grows as landmarks appear, and updates that use the sparsity of H.

The state is ``x = [x, y, theta, l1x, l1y, l2x, l2y, ...]`` (a filterpy column vector, shape (n, 1)) with
covariance ``P`` (n, n). filterpy's :class:`~filterpy.kalman.ExtendedKalmanFilter` keeps its meaning: ``x``,
``P``, ``y``, ``S``, ``K``, ``z``, ``R``, ``log_likelihood`` and ``mahalanobis`` describe the last update, and
the stock ``update`` still works on our state (used to cross-check). What we change, and why:

- ``predict`` composes the odometry increment onto the robot pose and touches only the robot block and its
  cross-covariances: O(n) instead of filterpy's dense ``F P F^T`` (O(n^3)).
- landmarks are added from the inverse observation model with their full cross-covariance with the robot and
  the map (``P_lx = G_r P_rx``), not an arbitrary large diagonal.
- the update (each sighting with its own model: range-bearing, or a position in the robot frame) gathers only
  the robot and observed-landmark columns of ``P``
  (``P H^T = P[:, cols] H_s^T``) and applies ``P -= W W^T`` with ``W = P H^T L^-T`` (``S = L L^T``): O(n^2 k)
  per step instead of the dense Joseph form's O(n^3), equal to it for the optimal gain, and exactly symmetric.
  A step's observations are combined into one update (``joint``), or applied one at a time (``sequential``).
- every observation is gated on its own NIS against a chi-square quantile; gated ones are reported, never
  silently lost. Two causes of persistent gating are told apart. A landmark whose gated sightings agree with
  each other while the rest of the scan agrees with the filter is stale (placed by a wrong association, or
  moved): it is re-anchored from its newest sighting (its old correlations dropped) instead of pulling the
  robot. When sightings of confirmed landmarks mostly fail over the last few updates and one robot correction
  explains them, the filter has drifted: a confirmed landmark failing ``gate_persistence`` times in a row is
  used again (without it a strict gate starves the filter on Victoria Park), unless its NIS is beyond any
  drift (:data:`DRIFT_NIS`): then it is re-anchored.
  Bearing innovations are wrapped; the heading is wrapped after every update.
- ``linearization``: the standard EKF evaluates its Jacobians at the current estimate and grows overconfident;
  ``fej`` (First-Estimates Jacobians) and ``oc`` (observability-constrained) keep the unobservable directions
  unobserved (:mod:`~online_slam.estimators.linearization`). They need the newest pose as predicted and each
  landmark's first estimate, which the state keeps. ``invariant`` takes the error on the group SE_{1+M}(2):
  the same Jacobians as ``standard``, but each correction turns the whole map with the heading's and the
  covariance is carried to the corrected estimate. Its group has one heading, so with several robots its
  updates are the standard ones (the covariance is in the same coordinates either way).

``x_prior``/``P_prior``/``x_post``/``P_post`` are not maintained (copying P every step would cost O(n^2) for
nothing); ``dim_x``, ``_I``, ``F`` and ``Q`` follow the state size so that stock filterpy calls stay valid.

Each step runs with BLAS limited to one thread: the products here are small (n up to a few thousand, rank 2k),
and OpenBLAS's thread hand-off costs more than it saves. The evidence behind these choices is in
benchmarks/RESULTS.md ("The invariant EKF", "The EKF's BLAS on one thread").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import AbstractContextManager
from typing import Any, cast

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from numpy.typing import NDArray
from scipy.stats import chi2

from online_slam.checkpoint import from_tree, to_tree
from online_slam.errors import OnlineSlamError
from online_slam.estimators import ekf_gating
from online_slam.estimators.adaptation import adapted_info, entering, update_adaptation
from online_slam.estimators.blas import OneThreadBlas
from online_slam.estimators.ekf_bias import OdometryBias, invariant_points
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.ekf_fixes import AbsoluteFixes
from online_slam.estimators.ekf_map import PriorMap
from online_slam.estimators.ekf_robots import SeveralRobots, landmark_columns
from online_slam.estimators.ekf_state import EkfState
from online_slam.estimators.kalman import apply_update, stacked_jacobian
from online_slam.estimators.landmark_book import LandmarkBook
from online_slam.estimators.linearization import (
    FIRST_ESTIMATES,
    heading_column,
    invariant_retraction,
    observable,
    transport,
)
from online_slam.estimators.protocol import Estimate, Snapshot
from online_slam.frontend.steps import Step
from online_slam.geometry.pose_moments import reported
from online_slam.geometry.se2 import compose_with_jacobians
from online_slam.models.motion import unbiased_increment
from online_slam.models.observation import (
    RANGE_BEARING,
    as_models,
    landmark_from_sighting_with_jacobians,
    predict_with_jacobians,
    wrap_bearings,
)
from online_slam.sources.events import LandmarkId

Array = NDArray[np.float64]


AGREEMENT_UPDATES = 5
"""Updates (before the current one) whose confirmed sightings count when deciding whether the filter drifted."""
REANCHOR_AFTER = 3
"""Gated sightings in a row (mutually consistent, while the scan agrees with the filter) that restart a landmark."""
DRIFT_NIS = 1000.0
"""NIS beyond which a gated sighting is never taken for the filter's drift, only for a misplaced landmark (which
is re-anchored). Drift sightings let in on MRCLAM and Victoria Park read at most 204; a landmark first placed
by a wrong id and then seen where it is reads 51,000, and letting it in moved the robot 50 m (sparse grid,
10% wrong ids, world 2, seed 0)."""


class EkfSlam(SeveralRobots, OdometryBias, AbsoluteFixes, PriorMap, ExtendedKalmanFilter):
    """EKF-SLAM with a growing state; follows the estimator protocol (``step`` / ``finish``)."""

    name = "ekf"
    online = True
    K: Array
    """filterpy's Kalman gain of the last update, shape (n, k)."""

    def __init__(self, config: EkfConfig | None = None) -> None:
        self.config = config or EkfConfig()
        self.state = EkfState(LandmarkBook(self.config.association, inside=True))
        super().__init__(dim_x=3, dim_z=2)
        self.P = np.zeros((3, 3))
        self.Q = np.zeros((3, 3))
        self._gate = (
            math.inf if self.config.gate_probability >= 1.0 else float(chi2.ppf(self.config.gate_probability, 2))
        )
        self._blas = OneThreadBlas()

    # filterpy's names for the state's mean and covariance, and the parts others read
    @property
    def x(self) -> Array:
        """State mean ``[x, y, theta, l1x, l1y, ...]``, shape (n, 1)."""
        return self.state.x

    @x.setter
    def x(self, value: Array) -> None:
        self.state.x = value

    @property
    def P(self) -> Array:  # noqa: N802 - filterpy's name
        """State covariance, shape (n, n)."""
        return self.state.P

    @P.setter
    def P(self, value: Array) -> None:  # noqa: N802
        self.state.P = value

    @property
    def landmark_ids(self) -> list[LandmarkId]:
        """Landmark ids in state order."""
        return self.state.landmark_ids

    @property
    def book(self) -> LandmarkBook:
        """Association state (tentative landmarks, ids given out, each sighting's label)."""
        return self.state.book

    @classmethod
    def from_state(cls, x: Array, P: Array, landmark_ids: list[LandmarkId], config: EkfConfig | None = None) -> EkfSlam:
        """A filter holding a given state (e.g. to resume, or to benchmark at a chosen map size).

        Args:
            x: State ``[x, y, theta, l1x, l1y, ...]``, shape (3 + 2M,) or (3 + 2M, 1).
            P: Its covariance, shape (3 + 2M, 3 + 2M), symmetric positive semi-definite.
            landmark_ids: The M landmark ids in state order.
            config: Filter settings.
        """
        ekf = cls(config)
        m = len(landmark_ids)
        ekf.state = EkfState(
            ekf.book,
            x=np.array(x, dtype=float).reshape(-1, 1),
            P=np.array(P, dtype=float),
            landmark_ids=list(landmark_ids),
            streak=np.zeros(m, dtype=np.int64),
            confirmed=np.ones(m, dtype=bool),
            predicted=np.array(x, dtype=float).reshape(-1)[:3].copy(),
            first=np.array(x, dtype=float).reshape(-1)[3:].reshape(-1, 2).copy(),
        )
        ekf._resized()
        return ekf

    def load_state(self, state: Any) -> None:
        """Restore a :meth:`state_dict` (this filter's config is kept)."""
        self.state = from_tree(EkfState, state)
        self._resized()

    def state_dict(self) -> Any:
        """Everything needed to continue exactly where the filter is: the tree of :class:`EkfState`."""
        return to_tree(self.state)

    def single_threaded(self) -> AbstractContextManager[Any]:
        """Context manager limiting BLAS to one thread, as every ``step`` runs (see the module docstring)."""
        return self._blas.limit()

    # -- state size -----------------------------------------------------------------------------
    def _grow(self, rows: Array, cross: Array, block: Array) -> None:
        """Append new state entries with their cross-covariance (m, n) and covariance (m, m)."""
        n, m = self.dim_x, len(rows)
        P = np.empty((n + m, n + m))
        P[:n, :n] = self.P
        P[n:, :n] = cross
        P[:n, n:] = cross.T
        P[n:, n:] = block
        self.P = P
        self.x = np.vstack([self.x, rows.reshape(-1, 1)])
        self._resized()

    def _resized(self) -> None:
        """The state's size changed: filterpy's matrices (I, F, Q, K) follow it; Q keeps the robot block."""
        self.dim_x = len(self.x)
        self._I = np.eye(self.dim_x)
        self.F = self._I
        Q = np.zeros((self.dim_x, self.dim_x))
        Q[:3, :3] = self.state.Q
        self.Q = Q
        self.K = np.zeros((self.dim_x, self.K.shape[1] if self.K.ndim == 2 else 1))

    # -- predict ---------------------------------------------------------------------------------
    def predict(self, u: Array, Q: Array | None = None, dt: float = 0.0) -> None:
        """Move the robot by the odometry increment u (3,) with covariance Q (3, 3) over ``dt`` seconds; O(n).

        Only the robot block and its cross-covariances change: ``P_rr = F P_rr F^T + G Q G^T``, ``P_rm = F P_rm``
        (with a bias state, :mod:`~online_slam.estimators.ekf_bias`, its columns ``B`` too).
        """
        Q = self.state.Q if Q is None else np.asarray(Q, dtype=float)
        P, bias = self.P, self._bias_columns() if self.state.biased else None
        if bias is not None:
            u, D = unbiased_increment(u, self.x[bias, 0], dt)
        pose, F, G = self._motion(u)
        self.state.predicted = pose.copy()
        self.x[:3, 0] = pose
        if bias is None:
            P[:3, 3:] = F @ P[:3, 3:]
            P[3:, :3] = P[:3, 3:].T
            P_rr = F @ P[:3, :3] @ F.T + G @ Q @ G.T
        else:
            B = G @ D
            A = F @ P[:3, :] + B @ P[bias, :]
            P_rr = A[:, :3] @ F.T + A[:, bias] @ B.T + G @ Q @ G.T
            P[:3, :], P[:, :3] = A, A.T
        P[:3, :3] = 0.5 * (P_rr + P_rr.T)
        self.state.Q = Q
        self.Q[:3, :3] = Q

    def _motion(self, u: Array) -> tuple[Array, Array, Array]:
        """The pose moved by u (3,), and the prediction's ``F``, ``G`` (3, 3) (fej, oc: ``J (p_k+1|k - p_k|k-1)``)."""
        pose, F, G = compose_with_jacobians(self.x[:3, 0], u)
        if self.config.linearization in FIRST_ESTIMATES:  # at the poses as predicted, not p_k|k
            F[:2, 2] = heading_column(pose[:2], self.state.predicted[:2])
        return pose, F, G

    # -- landmarks -------------------------------------------------------------------------------
    def add_landmark(self, landmark: LandmarkId, z: Array, R: Array, model: int = RANGE_BEARING) -> None:
        """Initialise a landmark from one observation z (2,) with covariance R (2, 2) and model tag ``model``.

        ``l = g(x_r, z)``; ``P_ll = G_r P_rr G_r^T + G_z R G_z^T``; ``P_lx = G_r P_rx`` (robot and map).
        """
        position, G_r, G_z = self._placed(z, model)
        cross = G_r @ self.P[:3, :]
        block = cross[:, :3] @ G_r.T + G_z @ R @ G_z.T
        self.state.index[landmark] = len(self.landmark_ids)
        self.landmark_ids.append(landmark)
        self.state.streak = np.append(self.state.streak, 0)
        self.state.confirmed = np.append(self.state.confirmed, False)
        self.state.first = np.vstack([self.state.first, position[None]])
        self._grow(position, cross, 0.5 * (block + block.T))

    def _placed(self, z: Array, model: int) -> tuple[Array, Array, Array]:
        """A landmark placed from sighting z (2,) at the robot's estimate: (position (2,), d/drobot (2, 3),
        d/dz (2, 2)); fej and oc take d/drobot at the newest pose as predicted (``[I, J (l - p_k|k-1)]``)."""
        position, G_r, G_z = landmark_from_sighting_with_jacobians(self.x[:3, 0], z, model)
        if self.config.linearization in FIRST_ESTIMATES:
            G_r[:, 2] = heading_column(position, self.state.predicted[:2])
        return position, G_r, G_z

    def remove_landmarks(self, ids: list[LandmarkId]) -> None:
        """Delete landmarks from the state: their rows and columns (exact marginalization in covariance form)."""
        gone = np.array(sorted(self.state.index[lid] for lid in ids), dtype=np.int64)
        m = len(self.landmark_ids)
        kept = np.setdiff1d(np.arange(m), gone)
        rows = np.r_[np.arange(self._offset), landmark_columns(kept, self._offset)]
        self.x = self.x[rows]
        self.P = self.P[np.ix_(rows, rows)]
        self._resized()
        renumber = np.full(m, -1, dtype=np.int64)
        renumber[kept] = np.arange(len(kept))
        self.state.landmark_ids = [self.landmark_ids[j] for j in kept]
        self.state.index = {lid: j for j, lid in enumerate(self.landmark_ids)}
        self.state.streak, self.state.confirmed = self.state.streak[kept], self.state.confirmed[kept]
        self.state.first = self.state.first[kept]
        self.state.recent = {int(renumber[j]): v for j, v in self.state.recent.items() if renumber[j] >= 0}

    # -- update ----------------------------------------------------------------------------------
    def _innovation(
        self, indices: NDArray[np.int64], z: Array, model: NDArray[np.int8]
    ) -> tuple[Array, Array, NDArray[np.int64]]:
        """Innovations y (k, 2), compact Jacobian H_s (2k, 3 + 2k) and its state columns (3 + 2k,)."""
        landmarks = self.x[self._offset :, 0].reshape(-1, 2)[indices]
        z_hat, J_p, J_l = predict_with_jacobians(self.x[:3, 0], landmarks, model)
        if self.config.linearization == "fej":  # Jacobians at the first estimates, innovation at the current one
            _, J_p, J_l = predict_with_jacobians(self.state.predicted, self.state.first[indices], model)
        elif self.config.linearization == "oc":
            J_p, J_l = observable(J_p, J_l, self.state.predicted[:2], self.state.first[indices])
        y = wrap_bearings(z - z_hat, model)
        H_s = stacked_jacobian(J_p, J_l)
        columns = np.r_[np.arange(3), landmark_columns(indices, self._offset)]
        return y, H_s, columns

    def update_structured(
        self, indices: NDArray[np.int64], z: Array, R: Array, model: Any = RANGE_BEARING, own: Array | None = None
    ) -> tuple[Array, NDArray[np.bool_]]:
        """Joint update with k observations of known landmarks; O(n^2 k).

        Args:
            indices: Landmark indices, shape (k,) (repeats allowed).
            z: Observations, shape (k, 2).
            R: Their covariances, shape (k, 2, 2).
            model: Their model tags (k,), or one tag for all (default range-bearing).
            own: Their own covariances (k, 2, 2) where R is widened (:meth:`Step.z_own_cov`); None: R.

        Returns:
            (NIS of each observation at the predicted state, shape (k,); which were accepted, shape (k,)).
        """
        k = len(indices)
        model = as_models(model, k)
        y, H_s, columns = self._innovation(indices, z, model)
        PHt = self.P[:, columns] @ H_s.T  # (n, 2k): only 3 + 2k columns of P are read
        S = H_s @ PHt[columns]
        diagonal = np.arange(k)
        S.reshape(k, 2, k, 2)[diagonal, :, diagonal, :] += R  # + block_diag(R)
        blocks = S.reshape(k, 2, k, 2)[np.arange(k), :, np.arange(k), :]  # (k, 2, 2) marginal S of each
        try:
            nis = np.einsum("ki,ki->k", y, np.linalg.solve(blocks, y[..., None])[..., 0])
        except np.linalg.LinAlgError:  # numerically singular (absurd noise settings): use none of them
            return np.full(k, np.inf), np.zeros(k, dtype=bool)
        nis = np.where(np.isfinite(nis), nis, np.inf)
        passed = nis <= self._gate
        accepted = passed.copy()
        reanchor = np.zeros(k, dtype=bool)
        streak = self.state.streak[indices]
        confirmed = self.state.confirmed[indices]
        if self.config.gate_persistence and not passed.all():
            # Drift: sightings of confirmed landmarks (ones that passed the gate since they were placed) fail,
            # and few of them pass. Unconfirmed landmarks are no evidence either way.
            failing, agreeing = int((confirmed & ~passed).sum()), int((confirmed & passed).sum())
            # over the last few updates: a lone failing sighting is no drift while others nearby in time agree
            recent_fail = failing + sum(f for f, _ in self.state.agreement)
            recent_agree = agreeing + sum(a for _, a in self.state.agreement)
            drifted = failing > 0 and recent_agree < max(2.0, 0.25 * (recent_fail + recent_agree))
            if drifted and failing >= 2:  # several: drift moves them all by one robot correction
                f = confirmed & ~passed
                cols = landmark_columns(indices[f], self._offset).reshape(-1, 2)
                drifted = ekf_gating.one_robot_correction_explains(
                    self.x[:3, 0], self.x[self._offset :, 0].reshape(-1, 2)[indices[f]],
                    self.P[cols[:, :, None], cols[:, None, :]], z[f], R[f], model[f])  # fmt: skip
            beyond = nis > DRIFT_NIS  # no drift of the robot explains these: the landmark is off
            if drifted:  # the filter drifted: let the persistent sightings of confirmed landmarks in
                accepted |= ~passed & ~beyond & confirmed & (streak >= self.config.gate_persistence - 1)
            if self.config.reanchor:  # the scan agrees with the filter, or no drift explains it: the landmark is off
                due = ~passed & (beyond | (not drifted)) & (streak >= REANCHOR_AFTER - 1)
                due &= indices >= self.state.fixed  # a fixed map's landmark stays
                if due.any():
                    reanchor = due & ekf_gating.recent_agree(self.state.recent, indices)
        self.state.agreement.append((int((confirmed & ~passed).sum()), int((confirmed & passed).sum())))
        del self.state.agreement[:-AGREEMENT_UPDATES]
        self.state.confirmed[indices[passed]] = True
        if not passed.all():
            self._remember(indices[~passed], z[~passed], R[~passed], model[~passed])
        self.state.streak[indices] = np.where(accepted | reanchor, 0, self.state.streak[indices] + 1)
        if not accepted.all():
            keep = np.repeat(accepted, 2)
            PHt, S, y = PHt[:, keep], S[np.ix_(keep, keep)], y[accepted]
        rise = 1.0
        if len(y) and self.config.adaptation.enabled:
            own = R if own is None else own
            rise = update_adaptation(self.state.adaptation, S, R[accepted], y, self.config.adaptation, own[accepted])
        if len(y):
            try:
                self._apply(PHt, S, y.reshape(-1))
            except np.linalg.LinAlgError:  # S not positive definite in floating point: the update is not made
                accepted[:] = False
        if rise > 1.0:  # the state's covariance was built with the odometry too sure, as the future's would be
            self.P *= rise
        for i in np.flatnonzero(reanchor):
            self.reanchor_landmark(int(indices[i]), z[i], R[i], model[i])
        return nis, accepted | reanchor

    def _remember(self, indices: NDArray[np.int64], z: Array, R: Array, model: NDArray[np.int8]) -> None:
        """Keep where each gated sighting puts its landmark (with that position's covariance)."""
        points, G_r, G_z = landmark_from_sighting_with_jacobians(self.x[:3, 0], z, model)
        covs = G_r @ self.P[:3, :3] @ G_r.transpose(0, 2, 1) + G_z @ R @ G_z.transpose(0, 2, 1)
        for j, point, cov in zip(indices.tolist(), points, covs):
            recent = self.state.recent.setdefault(j, [])
            recent.append((point, cov))
            del recent[: -max(1, self.config.gate_persistence)]

    def reanchor_landmark(self, index: int, z: Array, R: Array, model: int = RANGE_BEARING) -> None:
        """Restart a landmark from one sighting (model tag ``model``), as if it were new (its old estimate and
        correlations dropped).

        ``l = g(x_r, z)``; ``P_ll = G_r P_rr G_r^T + G_z R G_z^T``; ``P_lx = G_r P_rx`` for every other entry.
        """
        position, G_r, G_z = self._placed(z, model)
        cols = self._offset + 2 * index + np.arange(2)
        cross = G_r @ self.P[:3, :]
        block = cross[:, :3] @ G_r.T + G_z @ R @ G_z.T
        self.P[cols, :] = cross
        self.P[:, cols] = cross.T
        self.P[np.ix_(cols, cols)] = 0.5 * (block + block.T)
        self.x[cols, 0] = position
        self.state.first[index] = position
        self.state.recent.pop(index, None)
        self.state.confirmed[index] = False
        self.state.reanchored += 1

    def _apply(self, PHt: Array, S: Array, y: Array) -> None:
        """``x += K y``, ``P -= K S K^T`` with ``K = P H^T S^-1``, through the Cholesky factor of S."""
        dx, W, L_inv = apply_update(self.P, PHt, S, y)
        if self.config.linearization == "invariant" and len(self.state.robots) == 1 and not self.state.fixed:
            points, column = invariant_points(len(dx), self.state.biased), np.zeros(len(dx))
            moved, column[points] = invariant_retraction(self.x[points, 0], dx[points])
            if self.state.biased:  # the bias: no position, nothing turns
                bias = self._bias_columns()
                self.x[bias, 0] += dx[bias]
            self.x[points, 0] = moved
            transport(self.P, column)
        else:
            self.x[:, 0] += dx
        self._wrap_headings()
        # filterpy's view of the last update
        self.S, self.y = S, y.reshape(-1, 1)
        self.K = W @ L_inv
        self.SI = L_inv.T @ L_inv
        self._log_likelihood = self._likelihood = self._mahalanobis = None

    # -- protocol --------------------------------------------------------------------------------
    def step(self, step: Step) -> Snapshot:
        """Predict with the step's odometry, update with its observations, add new landmarks."""
        with self.single_threaded():
            return self._step(entering(step, self.state.adaptation))

    def extend(self, step: Step, start: int) -> Snapshot:
        """The newest step grew: update with its observations ``start:`` (no prediction)."""
        with self.single_threaded():
            step = entering(step, self.state.adaptation)
            self._observe(step, start)
            self._fix(step, self.state.fixes_used)
            return self.snapshot(step)

    def _step(self, step: Step) -> Snapshot:
        if self.state.waiting:
            self._sightings_before(step.t)
        if step.odometry is None and step.index > 0:  # another robot begins
            if self.config.linearization in FIRST_ESTIMATES:
                raise OnlineSlamError(
                    "several robots: the EKF's fej and oc linearizations take one robot; use invariant or standard"
                )
            self._add_robot(step)
        elif step.odometry is None:
            self.x[:3, 0] = step.prior
            self.P[:3, :3] = 0.0 if step.prior_cov is None else step.prior_cov
            self.state.predicted = self.x[:3, 0].copy()
            self.state.robots[0] = step.robot
            self._begin_bias(step)
        else:
            self._activate(step.robot)
            self._moved_on()
            self.state.history.append(self.x[:3, 0])  # the previous pose is complete
            self.predict(step.odometry, step.odometry_cov, step.t - self.state.robot_times[0])
        self.state.robot_steps[0], self.state.robot_times[0] = step.index, step.t
        self.state.step_nis, self.state.step_gated, self.state.step_new, self.state.step_ids = [], [], [], []
        self._observe(step, 0)
        self.state.fixes_used = 0
        self._fix(step)
        if step.robots_seen or self.state.waiting:
            self._sight_robots(step)
        return self.snapshot(step)

    def _observe(self, step: Step, start: int) -> None:
        """Update with the step's observations ``start:``, add new landmarks, record what happened."""
        ids: tuple[LandmarkId | None, ...] | list[LandmarkId | None]  # as given, or as associated
        ids, z_all, R_all, m_all = step.landmarks[start:], step.z[start:], step.z_cov[start:], step.z_model[start:]
        own = R_all if self.book.needs(ids) else step.z_own_cov()[start:]  # associated: judged as declared

        def rows(at: Any) -> tuple[Array, Array, NDArray[np.int8], Array]:  # z, R, models, own covariances
            return z_all[at], R_all[at], m_all[at], own[at]

        nis = np.full(len(ids), np.nan)
        if self.book.needs(ids):
            ids = self._associate(step.index, ids, z_all, R_all, m_all)
        self.state.step_ids += ids
        held = np.array([lid is None for lid in ids], dtype=bool)
        rejected = held.copy()  # a sighting association kept back is not used
        gated: list[LandmarkId] = []
        known = np.array([lid in self.state.index for lid in ids], dtype=bool)
        if known.any():
            where = np.flatnonzero(known)
            # Cast: a known sighting's id is in the index, so it is not None.
            indices = np.array([self.state.index[cast(LandmarkId, ids[i])] for i in where], dtype=np.int64)
            if self.config.update == "joint":
                nis[where], accepted = self.update_structured(indices, *rows(where))
            else:
                accepted = np.ones(len(where), dtype=bool)
                for j, i in enumerate(where):
                    nis[i : i + 1], accepted[j : j + 1] = self.update_structured(
                        indices[j : j + 1], *rows(slice(i, i + 1))
                    )
            gated = [ids[i] for i in where[~accepted]]
            rejected[where[~accepted]] = True
        new: list[LandmarkId] = []
        for i in np.flatnonzero(~known & ~held):
            lid = cast(LandmarkId, ids[i])  # not held: it has an id
            if lid in self.state.index:  # seen twice in this step: the first sighting initialised it
                nis[i : i + 1], ok = self.update_structured(np.array([self.state.index[lid]]), *rows(slice(i, i + 1)))
                if not ok[0]:
                    gated.append(lid)
                    rejected[i] = True
                continue
            self.add_landmark(lid, z_all[i], R_all[i], m_all[i])
            new.append(lid)
        self.state.gated_total += len(gated)
        self.state.rejected.append(rejected)
        self.state.step_nis.append(nis)
        self.state.step_gated += gated
        self.state.step_new += new

    def _associate(
        self, step_index: int, ids: Sequence[LandmarkId | None], z: Array, R: Array, model: NDArray[np.int8]
    ) -> list[LandmarkId | None]:
        """Ids for the sightings to associate (all of them, or those without one) against the filter's belief."""
        dropped = self.book.expire(step_index)
        if dropped:
            self.remove_landmarks(dropped)
        P, offset = self.P, self._offset

        def covariance_of(indices: NDArray[np.int64]) -> Array:
            cols = np.r_[0, 1, 2, landmark_columns(indices, offset)]
            return P[np.ix_(cols, cols)]

        positions = self.x[offset:, 0].reshape(-1, 2)
        pose = self.x[:3, 0].copy()
        return self.book.assign_ids(
            step_index, ids, z, R, model, pose, P[:3, :3], positions, self.landmark_ids, covariance_of
        )

    def trajectory_parts(self) -> tuple[Array, Array]:
        """(poses that no longer change, read-only (N - 1, 3) view; the newest pose, a copy (1, 3)); with several
        robots (nothing; every pose in step order)."""
        if len(self.state.robots) > 1:
            return np.zeros((0, 3)), self._robots_trajectory()
        return self.state.history.view(), self.x[:3, 0].reshape(1, 3).copy()

    def trajectory(self) -> Array:
        """Estimate of every pose so far (each as it was when newest), shape (N, 3)."""
        return np.concatenate(self.trajectory_parts())

    def snapshot(self, step: Step) -> Snapshot:
        """The current estimate as an immutable snapshot; ``info`` covers all of the step's observations."""
        ids, landmarks, covs = self._map()
        return Snapshot(
            estimator=self.name,
            index=step.index,
            t=step.t,
            pose=self.x[:3, 0].copy(),
            pose_cov=reported(self.P[:3, :3], self.config.pose_covariance),
            landmark_ids=ids,
            landmarks=landmarks,
            landmark_covs=covs,
            info={
                "nis": np.concatenate(self.state.step_nis) if self.state.step_nis else np.zeros(0),
                "observed": tuple(self.state.step_ids),
                "gated": tuple(self.state.step_gated),
                "new_landmarks": tuple(self.state.step_new),
                **self._fix_info(),
                **self._step_bias(),
            },
        )

    def finish(self) -> Estimate:
        """The filter has no smoothing: each pose keeps the estimate it had when it was the newest (with several
        robots: when its robot moved on)."""
        if self.state.waiting:
            self._sightings_before(math.inf)
        ids, landmarks, covs = self._map()
        return Estimate(
            self.name,
            self.trajectory(),
            ids,
            landmarks,
            {
                "gated_observations": self.state.gated_total,
                "landmarks_reanchored": self.state.reanchored,
                **adapted_info(self.state.adaptation, self.config.adaptation),
                **self._fix_info(),
                "state_size": self.dim_x,
                "linearization": self.config.linearization,
                "pose_covariance": self.config.pose_covariance,
                "rejected": np.concatenate(self.state.rejected) if self.state.rejected else np.zeros(0, dtype=bool),
                **self.book.info(),
                **self._robot_info(),
                **self._bias_info(),
            },
            landmark_covs=covs,
            landmark_joint=self.landmark_joint(),
        )
