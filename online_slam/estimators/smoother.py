"""Sliding-window least-squares smoother with Schur-complement marginalization.

The smoother keeps the W newest poses and *every* landmark as variables. Each step adds the new pose
(propagated by odometry from the latest estimate), new landmarks (inverse observation model) and their
factors. Every K steps, and at the end of the stream, it relinearizes all factors in the window and iterates
Levenberg-Marquardt to convergence. A pose is never marginalized before it has been optimized at least once.

When the window holds more than W poses, the oldest is marginalized: its factors (odometry to the next pose,
its observations, a start prior) are linearized and folded into the marginal prior, and its 3 variables are
eliminated. The prior is a Gaussian ``d ~ N(mu, Sigma)`` on ``d = x - x_lin`` (heading wrapped) over the oldest
window pose and every landmark it has touched, kept in covariance form: folding a factor in is an exact
linear-Gaussian update (the next pose and new landmarks are appended through their factor, the other
observations update it like a Kalman filter), and eliminating a pose is dropping its rows — the same result
as a Schur complement of the information matrix, at O(n^2) per factor. The prior's quadratic is never
relinearized: by default it is re-centred (exactly) at the current estimate before new factors are folded in
and those are linearized there; ``first_estimate_jacobians=True`` instead linearizes them at the prior's first
estimates (FEJ). FEJ diverged on cityTrees (first estimates tens of metres off before a loop closure: 134 m error
after 1000 poses with W=50, against 3.6 m re-centred) and on MRCLAM robot 1 (11 m), so it is not the default.
Landmarks are never marginalized, so a re-observation long after the poses that saw a landmark left the
window (a loop closure) still corrects the map and the current pose.

Each solve eliminates from the prior the landmarks no window pose observes (its marginal on the rest is
``N(mu_a, Sigma_aa)``, read off directly) and recovers them afterwards from their conditional mean, so each
iteration factors a system over the window poses and the observed landmarks only.

Per-step cost depends on W and the size of the map, not on the length of the trajectory.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as la
from numpy.typing import NDArray
from scipy.stats import chi2
from threadpoolctl import ThreadpoolController

from online_slam.estimators.history import PoseHistory
from online_slam.estimators.kalman import apply_update, stacked_jacobian
from online_slam.estimators.landmark_book import AssociationConfig, LandmarkBook
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate, Snapshot
from online_slam.estimators.relinearize import (
    history_graph,
    inlier_graph,
    prior_covariance,
    prior_marginal,
    refine_recent,
    solve_all,
)
from online_slam.estimators.window_state import (
    pack_observations,
    pack_odometry,
    unpack_observations,
    unpack_odometry,
)
from online_slam.factors.graph import (
    FactorGraph,
    layout,
    observation_chi2,
    range_bearing_chi2,
    sqrt_information,
)
from online_slam.factors.robust import RobustLoss, outlier_threshold
from online_slam.frontend.steps import Step
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, compose, compose_with_jacobians, rotation
from online_slam.models.motion import odometry_residual_with_jacobians
from online_slam.models.range_bearing import landmark_from_observation, range_bearing_with_jacobians
from online_slam.solvers.least_squares import QuadraticPrior, SolverConfig, SolveResult, solve
from online_slam.sources.events import LandmarkId

Array = NDArray[np.float64]
Index = NDArray[np.int64]

GLOBAL_GROWTH = 20
"""Global relinearizations start at most every N / 20 steps after N steps: each costs O(N), so this keeps their
amortized cost per step bounded on long runs."""
GLOBAL_DELAY_GROWTH = 50
"""A background global solve is handed over at least N / 50 steps after it starts at step N: its cost grows with N
while a step's does not (measured on the 5000-pose grid world with 15 ms steps: the last solves took ~1.3 s, so a
hand-over 50 steps later waited up to 0.5 s for them)."""
GLOBAL_FALSE_ALARM = 1e-3
"""A global relinearization is kept unless the history's pull on the re-anchored prior exceeds the chi-square
bound a consistent history exceeds with this probability."""


@dataclass(frozen=True)
class SmootherConfig:
    """Settings of the sliding-window smoother."""

    window: int = 20
    """W: poses kept as variables at least (>= 1); older ones are marginalized once the window is full (below)."""
    window_distance: float = 18.0
    """The window also keeps poses beyond W until the path from its second-oldest pose to its newest is at least
    this long (metres, by odometry; up to ``window_max`` poses): sized by motion, it spans W poses where the robot moves
    far per pose and more where it creeps, so that the poses it freezes have seen enough geometry. Default 18 m:
    what W=20 spans at 1 m per pose (grid, the 5000-pose world, cityTrees keep 20 poses); it keeps 38 poses of
    the 0.5 m-per-pose waypoint world and up to ``window_max`` on MRCLAM. 0: W poses."""
    window_max: int = 120
    """Most poses the window keeps to span ``window_distance`` (never fewer than W; ignored when that is 0)."""
    relinearize_every: int = 1
    """K: relinearize and solve every K steps (and at the end); in between, new poses follow odometry."""
    solver: SolverConfig = field(
        default_factory=lambda: SolverConfig(
            max_iterations=10, relative_cost_tolerance=1e-5, step_tolerance=1e-5, model_tolerance=1e-4
        )
    )
    """Levenberg-Marquardt settings of each window solve during the stream (max iterations, tolerances)."""
    final_solver: SolverConfig = field(default_factory=SolverConfig)
    """Settings of the last solve, at the end of the stream (tight by default: it gives the final estimate)."""
    loss: RobustLoss | None = field(default_factory=lambda: RobustLoss("tail", math.sqrt(outlier_threshold(1e-6))))
    """Robust loss on observations, re-evaluated at every relinearization, or None for plain least squares.
    Default: least squares while a sighting's squared whitened residual is within 27.6 (the chi-square bound
    an inlier exceeds with probability 1e-6), a Cauchy tail beyond it, so a clean window solves exactly as
    least squares (measured: grid and a sparser world, 0/5/10/20% wrong ids; see the README)."""
    consensus: bool = True
    """After each solve, move a landmark to the consensus of its window sightings when they agree with each
    other but not with it (placed by a wrong association), releasing it from the prior if the prior holds it."""
    reject_false_alarm: float = 1e-3
    """Marginalization never folds into the prior a sighting whose squared whitened residual at the current
    estimate exceeds the chi-square bound this inlier would exceed with this probability (13.8 for 1e-3):
    it is judged an outlier and dropped. 0 folds every sighting in."""
    first_estimate_jacobians: bool = False
    """Linearize factors folded into the prior at the prior's own (first-estimate) linearization point (FEJ).
    False (default) re-centres the prior at the current estimate first (exact for a Gaussian) and linearizes
    there, which stays stable when first estimates are far off (see the module docstring)."""

    global_every: int = 200
    """Relinearize globally every this many steps, or every N / 20 steps after N steps if that is longer (0:
    never): re-solve every factor seen so far from the current
    estimate (``global_iterations`` Levenberg-Marquardt iterations), write the revised poses into the history
    and move the prior to them (see :mod:`~online_slam.estimators.relinearize`). Keeps every factor. Default 200,
    chosen on the square, the grid, the 5000-pose world, MRCLAM 6 (5 robots), Victoria Park and cityTrees (see
    the README): it brings the final estimate to the batch's."""
    global_iterations: int = 3
    """Levenberg-Marquardt iterations of each global relinearization (warm-started: few are needed)."""
    global_delay: int = 50
    """Steps between starting a global relinearization (in a background thread, from a copy of the state) and
    handing its result over, or N / 50 steps after N steps if that is longer (the solve's cost grows with N, a
    step's does not); the hand-over waits for the solve if it is not done, so results never depend on timing.
    0 solves at once, inside the step."""
    global_information_max: int = 0
    """Re-anchoring also relinearizes the prior's information (its covariance: the history's exact marginal at
    the revised estimate) while the prior holds at most this many landmarks (one sparse solve with 2 L + 3
    right-hand sides and a dense inverse of that size); otherwise only its mean moves and its covariance keeps
    the linearization of each fold-in. Default 0 (never): measured, it helps MRCLAM's online error, but makes
    cityTrees' worse and costs up to 0.5 s per hand-over there (see the README)."""
    association: AssociationConfig = field(default_factory=AssociationConfig)
    """How sightings are paired with landmarks: the stream's ids, or nearest neighbour / JCBB against the
    smoother's own belief (the window's information from the last solve, carried to the newest pose; the prior
    for landmarks the window does not see), with tentative landmarks. Associations are not revised later."""

    def __post_init__(self) -> None:
        if self.global_every < 0 or self.global_iterations < 1 or self.global_delay < 0:
            raise ValueError("global_every and global_delay must be >= 0, global_iterations >= 1")
        if self.global_information_max < 0:
            raise ValueError("global_information_max must be >= 0")
        if self.window < 1:
            raise ValueError("window must be >= 1")
        if not 0.0 <= self.window_distance < math.inf or self.window_max < 1:
            raise ValueError("window_distance must be finite and >= 0, window_max >= 1")
        if self.relinearize_every < 1:
            raise ValueError("relinearize_every must be >= 1")


@dataclass
class _Prior:
    """The marginal prior ``d ~ N(mu, Sigma)``, ``d = x - x_lin``, over ``[landmarks..., pose]``.

    The pose comes last, so that its rows and columns are the ones the next pose reuses.
    """

    pose: int
    landmarks: Index
    x_lin: Array
    mu: Array
    Sigma: Array
    """Contiguous (n, n), so that Kalman updates run in place (:func:`~online_slam.estimators.kalman.downdate`)."""


def _resized(Sigma: Array, size: int, keep: int) -> Array:
    """Sigma itself when the size does not change, else a new contiguous size x size array whose top-left
    ``keep`` x ``keep`` block holds Sigma's (the rest uninitialized)."""
    if len(Sigma) == size:
        return Sigma
    grown = np.empty((size, size))
    grown[:keep, :keep] = Sigma[:keep, :keep]
    return grown


def _fuse_repeats(indices: Index, z: Array, z_cov: Array) -> tuple[Index, Array, Array]:
    """Merge repeated observations of one landmark from one pose into a single equivalent observation.

    Both measure the same ``h(pose, landmark)``, so their two quadratics sum to one with information
    ``R1^-1 + R2^-1`` centred on the information-weighted mean (bearings averaged relative to the first).
    """
    if len(np.unique(indices)) == len(indices):
        return indices, z, z_cov
    keep_i, keep_z, keep_c = [], [], []
    for j in dict.fromkeys(indices.tolist()):
        rows = np.flatnonzero(indices == j)
        info = np.linalg.inv(z_cov[rows])
        offsets = z[rows] - z[rows[0]]
        offsets[:, 1] = wrap(offsets[:, 1])
        cov = np.linalg.inv(info.sum(axis=0))
        mean = z[rows[0]] + cov @ np.einsum("kij,kj->i", info, offsets)
        mean[1] = wrap(mean[1])
        keep_i.append(j)
        keep_z.append(mean)
        keep_c.append(0.5 * (cov + cov.T))
    return np.array(keep_i, dtype=np.int64), np.array(keep_z), np.array(keep_c)


def _locate(ids: Index, wanted: Index) -> tuple[Index, NDArray[np.bool_]]:
    """Where each of ``wanted`` (k,) is in ``ids`` (distinct, any order), and whether it is there; shapes (k,)."""
    if not len(ids):
        return np.zeros(len(wanted), dtype=np.int64), np.zeros(len(wanted), dtype=bool)
    order = np.argsort(ids, kind="stable")
    where = order[np.minimum(np.searchsorted(ids, wanted, sorter=order), len(ids) - 1)]
    return where, ids[where] == wanted


@dataclass(frozen=True)
class _Solved:
    """The last window solve's factored information, for association covariances until the state moves."""

    window: Index
    """The window poses it solved, shape (P,)."""
    pose_column: Index
    """Column of each window pose in its system (-1: fixed), shape (P,)."""
    active: Index
    """The landmarks it solved (sorted), shape (A,)."""
    landmark_column: Index
    """Column of each active landmark, shape (A,)."""
    factor: Array
    """``scipy.linalg.cho_factor`` of its information (upper triangle), shape (n, n)."""

    def columns(self, landmarks: Index) -> Index:
        """The columns of these solved landmarks (k,), shape (2k,)."""
        return (self.landmark_column[_locate(self.active, landmarks)[0]][:, None] + np.arange(2)).reshape(-1)


@dataclass
class _GlobalJob:
    """A global solve running in the background (or finished, or restored from a checkpoint)."""

    handover: int
    """Step count at which its result is applied."""
    n_poses: int
    """Poses in the state it started from (0 .. n_poses - 1)."""
    thread: threading.Thread | None = None
    result: SolveResult | None = None
    error: str | None = None


class SlidingWindowSmoother:
    """Fixed-lag smoother over poses, keeping all landmarks; follows the estimator protocol."""

    name = "smoother"
    online = True

    def __init__(self, config: SmootherConfig | None = None, name: str = "smoother") -> None:
        self.config = config or SmootherConfig()
        self.name = name
        self.window: list[int] = []
        self.poses: dict[int, Array] = {}
        self.history = PoseHistory()  # final estimates of the poses that left the window
        self.landmark_ids: list[LandmarkId] = []
        self._index: dict[LandmarkId, int] = {}
        self._landmarks = np.zeros((0, 2))
        # Window factors with their square-root information: odometry keyed by the later pose.
        self._odometry: dict[int, tuple[Array, Array, Array]] = {}
        self._observations: dict[int, tuple[Index, Array, Array, Array]] = {}
        self._start: tuple[int, Array, Array | None] | None = None
        self.prior: _Prior | None = None
        self._pose_cov = np.zeros((3, 3))
        self._since_solve = 0
        self._unsolved: set[int] = set()
        self.solves = self.marginalized = 0
        self.released = 0
        """Landmarks let go from the prior because the window's sightings contradicted it (see _revisit)."""
        self._step_report: dict[str, float] = {}  # the newest step's last solve and marginalizations
        self._step_marginalized: list[int] = []
        self._decisions: list[tuple[int, NDArray[np.bool_]]] = []  # (pose, outlier mask) when it left the window
        self._reject_bound = (
            outlier_threshold(self.config.reject_false_alarm) if self.config.reject_false_alarm > 0 else np.inf
        )
        self._blas = ThreadpoolController()
        self.log = ProblemLog(keep_factors=self.config.global_every > 0)  # every factor, for global solves
        self._since_global = 0
        self._steps = 0
        self._global_job: _GlobalJob | None = None
        self.global_solves = 0
        self.global_rejections = 0
        """Global relinearizations not kept (the solve did not reconcile the history)."""
        self.book = LandmarkBook(self.config.association, inside=False)
        self._resolved: Step | None = None  # the newest step with associated ids, when association changed it
        self._solved: _Solved | None = None  # the last solve's factored information, while the state has not moved

    @property
    def landmarks(self) -> Array:
        """Current landmark estimates, shape (M, 2)."""
        return self._landmarks

    # -- building the window ---------------------------------------------------------------------
    def _add_pose(self, step: Step) -> None:
        i = step.index
        if step.odometry is None:
            pose = np.array(step.prior, dtype=float)
            self._start = (i, pose.copy(), None if step.prior_cov is None else np.array(step.prior_cov))
            self._pose_cov = np.zeros((3, 3)) if step.prior_cov is None else np.array(step.prior_cov)
        else:
            previous = self.window[-1]
            pose, F, G = compose_with_jacobians(self.poses[previous], step.odometry)
            self._pose_cov = F @ self._pose_cov @ F.T + G @ step.odometry_cov @ G.T
            self._odometry[i] = (
                np.array(step.odometry),
                np.array(step.odometry_cov),
                sqrt_information(step.odometry_cov),
            )
        self.window.append(i)
        self.poses[i] = pose
        self._unsolved.add(i)

    def _resolve(self, step: Step, start: int) -> tuple[Step, int]:
        """The step with the sightings ``start:`` associated (those not used left out), and where they begin.

        Without association (every sighting has an id, ids used) this is the step itself.
        """
        ids = step.landmarks[start:]
        needed = self.book.needs(ids)
        if start == 0:
            self._resolved = None
        if not needed and self._resolved is None:
            return step, start
        base = self._resolved if self._resolved is not None else step
        cut = len(base.landmarks) if self._resolved is not None else start
        if needed:
            self.book.expire(step.index)
            ids = self.book.assign_ids(
                step.index,
                ids,
                step.z[start:],
                step.z_cov[start:],
                self.poses[self.window[-1]].copy(),
                self._pose_cov,
                self._landmarks,
                self.landmark_ids,
                self._association_covariance,
                known=self._index,
            )
        keep = np.array([lid is not None for lid in ids], dtype=bool)
        resolved = replace(
            step,
            landmarks=base.landmarks[:cut] + tuple(lid for lid, ok in zip(ids, keep) if ok),
            z=np.concatenate([base.z[:cut], step.z[start:][keep]]),
            z_cov=np.concatenate([base.z_cov[:cut], step.z_cov[start:][keep]]),
        )
        self._resolved = resolved
        return resolved, cut

    def _add_retro(self) -> None:
        """Earlier sightings of the landmarks association confirmed just now, at poses still in the window."""
        for lid, g, z, R in self.book.retro:
            if g not in self.poses or lid not in self._index:  # the pose left the window meanwhile
                continue
            factors = (np.array([self._index[lid]], dtype=np.int64), z[None], R[None], sqrt_information(R[None]))
            if g in self._observations:
                factors = tuple(np.concatenate([a, b]) for a, b in zip(self._observations[g], factors))  # type: ignore[assignment]
            self._observations[g] = factors
            self._unsolved.add(g)
            self.log.add_sightings(g, (lid,), z[None], R[None])
        self.book.retro = []

    def _association_covariance(self, indices: Index) -> Array:
        """Joint covariance of the newest pose and landmarks ``indices`` (c,), shape (3 + 2c, 3 + 2c).

        Usually the last solve's factored information, carried through the newest odometry (see
        :meth:`_propagated_covariance`). Otherwise the window (without the newest pose's sightings, still being
        associated) and the reduced prior are linearized at the current estimate; landmarks the window observes
        read the inverse information; landmarks only the prior holds are its conditional given the part the
        window shares, propagated.
        """
        propagated = self._propagated_covariance(indices)
        if propagated is not None:
            return propagated
        c = len(indices)
        active, sparse, quadratic, H = self._linearized_window()
        rows = 3 + 2 * c
        fallback = np.eye(rows) * 1e6  # a landmark nothing constrains (cannot happen with a consistent state)
        if H is None:
            return fallback
        n = len(H)
        L = np.zeros((rows, n))
        N = np.zeros((rows, rows))
        newest = sparse.pose_column[len(self.window) - 1]
        if newest >= 0:
            L[np.arange(3), newest + np.arange(3)] = 1.0
        position, is_active = _locate(active, indices)
        for k in np.flatnonzero(is_active):
            column = sparse.landmark_column[position[k]]
            L[3 + 2 * k + np.arange(2), column + np.arange(2)] = 1.0
        passive_k = np.flatnonzero(~is_active)
        if len(passive_k):
            p = self.prior
            if p is None or quadratic is None:
                return fallback
            slots, held = _locate(p.landmarks, indices[passive_k])
            if not held.all():
                return fallback
            order, _, _, A = self._prior_split(active)
            state_rows = (2 * slots[:, None] + np.arange(2)).reshape(-1)
            S_pa = p.Sigma[np.ix_(state_rows, order)]
            B = S_pa @ A
            out_rows = (3 + 2 * passive_k[:, None] + np.arange(2)).reshape(-1)
            L[np.ix_(out_rows, quadratic.columns)] = B
            N[np.ix_(out_rows, out_rows)] = p.Sigma[np.ix_(state_rows, state_rows)] - B @ S_pa.T
        try:
            X = la.cho_solve(la.cho_factor(H), L.T)
        except (la.LinAlgError, ValueError):
            return fallback
        joint = L @ X + N
        return 0.5 * (joint + joint.T)

    def _propagated_covariance(self, indices: Index) -> Array | None:
        """The association covariance from the last solve's factored information, or None if it does not apply.

        It applies while nothing moved since that solve but the newest pose's odometry: the newest pose is then
        the solved one composed with it, and its joint covariance with the landmarks is the solved one carried
        through the composition's Jacobians. Marginalizing old poses since does not change the remaining
        variables' marginal (exact for the linearized system with the default re-centred marginalization; with
        ``first_estimate_jacobians`` up to the prior's older linearization points). A landmark only the prior
        holds is, given the prior's part that the solve saw (its pose and solved landmarks), independent of the
        rest: its covariance is the prior's conditional plus that part's solved covariance carried through the
        regression. This saves linearizing and factoring the window per scan. None when the state moved
        otherwise (a sighting was added, a global solve handed over, judged outliers dropped from a marginalized
        pose, a landmark released from the prior).
        """
        s, newest = self._solved, self.window[-1]
        if s is None:
            return None
        if newest == s.window[-1] and not self._unsolved:
            carry = None
        elif len(self.window) > 1 and self.window[-2] == s.window[-1] and self._unsolved == {newest}:
            if newest in self._observations:
                return None
            delta, Q, _ = self._odometry[newest]
            _, F, G = compose_with_jacobians(self.poses[s.window[-1]], delta)
            carry = (F, G @ Q @ G.T)
        else:
            return None
        c = len(indices)
        _, is_solved = _locate(s.active, indices)
        passive = np.flatnonzero(~is_solved)
        # The joint is R^T H^-1 R (+ the prior's conditional), R mapping it onto the solved system's columns.
        R = np.zeros((len(s.factor), 3 + 2 * c))
        R[s.pose_column[-1] + np.arange(3), np.arange(3)] = 1.0
        known = 3 + (2 * np.flatnonzero(is_solved)[:, None] + np.arange(2)).reshape(-1)
        R[s.columns(indices[is_solved]), known] = 1.0
        conditional = None
        if len(passive):
            p = self.prior
            prior_pose = int(np.searchsorted(s.window, p.pose)) if p is not None else len(s.window)
            if p is None or not len(p.landmarks) or prior_pose == len(s.window) or s.window[prior_pose] != p.pose:
                return None
            if s.pose_column[prior_pose] < 0:  # the prior's pose was fixed in that solve
                return None
            slot, held = _locate(p.landmarks, indices[passive])
            if not held.all():  # not in the prior either (inconsistent state)
                return None
            is_held = np.isin(p.landmarks, s.active)
            n = len(p.mu)
            order = np.r_[(2 * np.flatnonzero(is_held)[:, None] + np.arange(2)).reshape(-1), np.arange(n - 3, n)]
            rows = (2 * slot[:, None] + np.arange(2)).reshape(-1)
            S_pa = p.Sigma[np.ix_(rows, order)]
            try:  # the regression of the passive landmarks on the held part: d_p = B d_a + noise
                B = la.cho_solve(la.cho_factor(p.Sigma[np.ix_(order, order)]), S_pa.T).T  # (2k, q)
            except (la.LinAlgError, ValueError):
                return None
            a_columns = np.r_[s.columns(p.landmarks[is_held]), s.pose_column[prior_pose] + np.arange(3)]
            out = 3 + (2 * passive[:, None] + np.arange(2)).reshape(-1)
            R[np.ix_(a_columns, out)] = B.T
            conditional = (out, p.Sigma[np.ix_(rows, rows)] - B @ S_pa.T)
        P = R.T @ la.cho_solve((s.factor, False), R)
        if conditional is not None:
            P[np.ix_(conditional[0], conditional[0])] += conditional[1]
        if carry is not None:
            F, noise = carry
            P[:3] = F @ P[:3]
            P[:, :3] = P[:, :3] @ F.T
            P[:3, :3] += noise
        return 0.5 * (P + P.T)

    def _add_observations(self, step: Step, start: int) -> None:
        """Factors for the newest pose's observations ``start:``; new landmarks from their first sight."""
        if len(step.landmarks) <= start:
            return
        i = step.index
        pose = self.poses[i]
        indices = []
        for lid, z in zip(step.landmarks[start:], step.z[start:]):
            if lid not in self._index:
                self._index[lid] = len(self.landmark_ids)
                self.landmark_ids.append(lid)
                self._landmarks = np.vstack([self._landmarks, landmark_from_observation(pose, z)])
            indices.append(self._index[lid])
        z, z_cov = step.z[start:], step.z_cov[start:]
        factors = (np.array(indices, dtype=np.int64), z, z_cov, sqrt_information(z_cov))
        if i in self._observations:  # more sightings of the newest pose
            factors = tuple(np.concatenate([a, b]) for a, b in zip(self._observations[i], factors))  # type: ignore[assignment]
        self._observations[i] = factors

    def _graph(self, active: Index) -> tuple[FactorGraph, dict[int, int]]:
        """The window's factors as a graph over local pose indices and the active landmarks (local order)."""
        local = {g: k for k, g in enumerate(self.window)}
        to_local = np.full(len(self.landmark_ids), -1, dtype=np.int64)
        to_local[active] = np.arange(len(active))
        odo = [(local[j] - 1, local[j], *self._odometry[j]) for j in self.window[1:]]
        obs = [(local[i], *self._observations[i]) for i in self.window if i in self._observations]
        fixed: list[int] = []
        prior_pose, prior_mean, prior_W = np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3, 3))
        if self._start is not None and self._start[0] in local:
            if self._start[2] is None:
                fixed = [local[self._start[0]]]
            else:
                prior_pose = np.array([local[self._start[0]]])
                prior_mean, prior_W = self._start[1][None], sqrt_information(self._start[2])[None]
        graph = FactorGraph(
            n_poses=len(self.window),
            n_landmarks=len(active),
            fixed_poses=np.array(fixed, dtype=np.int64),
            prior_pose=prior_pose,
            prior_mean=prior_mean,
            prior_sqrt_info=prior_W,
            odo_from=np.array([o[0] for o in odo], dtype=np.int64),
            odo_to=np.array([o[1] for o in odo], dtype=np.int64),
            odo_delta=np.array([o[2] for o in odo]).reshape(-1, 3),
            odo_sqrt_info=np.array([o[4] for o in odo]).reshape(-1, 3, 3),
            obs_pose=np.concatenate([np.full(len(o[1]), o[0]) for o in obs]).astype(np.int64)
            if obs
            else np.zeros(0, dtype=np.int64),
            obs_landmark=to_local[np.concatenate([o[1] for o in obs])] if obs else np.zeros(0, dtype=np.int64),
            obs_z=np.concatenate([o[2] for o in obs]) if obs else np.zeros((0, 2)),
            obs_sqrt_info=np.concatenate([o[4] for o in obs]) if obs else np.zeros((0, 2, 2)),
        )
        return graph, local

    # -- solving ---------------------------------------------------------------------------------
    def _solve(self, final: bool = False, depth: int = 0) -> dict[str, float]:
        """Relinearize the window and solve.

        Landmarks that no window pose observes (passive) appear only in the marginal prior, a quadratic: they
        are eliminated from it exactly (Schur complement) before the iterations and recovered afterwards from
        their conditional mean, so each iteration factors a system over the window poses and the observed
        landmarks only. The result equals the solve over all landmarks.
        """
        active = self._active()
        graph, sparse, quadratic, recover, poses = self._window_system(active)
        result = solve(
            graph,
            poses,
            self._landmarks[active],
            self.config.final_solver if final else self.config.solver,
            loss=self.config.loss,
            prior=quadratic,
            return_information=True,
            graph_layout=sparse,
        )
        for k, g in enumerate(self.window):
            self.poses[g] = result.poses[k]
        self._landmarks[active] = result.landmarks
        if recover is not None:
            recover(result.poses[0], result.landmarks)
        newest = sparse.pose_column[len(self.window) - 1]
        self._solved = None
        if newest >= 0 and result.information is not None:
            H = result.information
            H = H.toarray() if hasattr(H, "toarray") else H
            unit = np.zeros((H.shape[0], 3))
            unit[newest + np.arange(3), np.arange(3)] = 1.0
            try:
                factor, _ = la.cho_factor(H, lower=False)
                cov = la.cho_solve((factor, False), unit)[newest : newest + 3]
                self._pose_cov = 0.5 * (cov + cov.T)
                self._solved = _Solved(
                    np.array(self.window, dtype=np.int64),
                    sparse.pose_column[: len(self.window)].copy(),
                    active,
                    sparse.landmark_column[: len(active)].copy(),
                    factor,
                )
            except (la.LinAlgError, ValueError):  # singular, or not finite
                self._pose_cov = np.full((3, 3), np.nan)
        self._since_solve = 0
        self._unsolved.clear()
        self.solves += 1
        report = {"iterations": result.iterations, "cost_before": result.initial_cost, "cost_after": result.final_cost}
        if self.config.consensus and np.isfinite(self._reject_bound) and self._revisit(graph, active, depth):
            return self._solve(final, depth + 1)
        return report

    def _active(self) -> Index:
        """Landmarks some window pose observes (sorted)."""
        observed = [self._observations[i][0] for i in self.window if i in self._observations]
        return np.unique(np.concatenate(observed)) if observed else np.zeros(0, dtype=np.int64)

    def _window_system(self, active: Index) -> tuple:
        """The window's factor graph, its layout, the reduced prior (and passive recovery), the window poses."""
        graph, local = self._graph(active)
        sparse = layout(graph, entries=False)
        quadratic, recover = None, None
        if self.prior is not None:
            quadratic, recover = self._reduced_prior(
                active, sparse.pose_column[local[self.prior.pose]], sparse.landmark_column
            )
        return graph, sparse, quadratic, recover, np.array([self.poses[g] for g in self.window])

    def _prior_split(self, active: Index) -> tuple[Index, Index, NDArray[np.bool_], Array]:
        """The prior's state split into the part the window solve sees and the passive landmarks.

        Returns:
            (state rows of the active landmarks then the pose, rows of the passive landmarks, which prior
            landmarks are active, the information ``Sigma_aa^-1`` of the active part).
        """
        p = self.prior
        assert p is not None
        n = len(p.mu)
        is_active = np.isin(p.landmarks, active)
        order = np.r_[(2 * np.flatnonzero(is_active)[:, None] + np.arange(2)).reshape(-1), np.arange(n - 3, n)]
        passive = (2 * np.flatnonzero(~is_active)[:, None] + np.arange(2)).reshape(-1)
        S_aa = p.Sigma[np.ix_(order, order)]
        try:
            A = la.cho_solve(la.cho_factor(S_aa), np.eye(len(order)))
        except la.LinAlgError:  # rank-deficient: the information of the directions it has
            A = np.linalg.pinv(S_aa, hermitian=True)
        return order, passive, is_active, 0.5 * (A + A.T)

    def _revisit(self, graph: FactorGraph, active: Index, depth: int) -> bool:
        """After a solve: move landmarks whose window sightings agree with each other but not with them.

        Only landmarks with a sighting beyond the rejection bound are examined (none, usually). A landmark
        with three or more window sightings whose positions (from the solved poses) cluster away from its
        estimate — further than three times their median spread from their coordinate-wise median — was
        placed by a wrong association (its first sighting, or one folded into the prior long ago): a landmark
        only the window knows moves to that median; one the marginal prior holds is released from the prior
        (dropping its rows marginalizes it out, exactly) when two thirds of its sightings are outliers, then
        moves. Returns True when something moved (the caller solves again; at most twice in a row).
        """
        if depth >= 2 or len(graph.obs_pose) == 0:
            return False
        poses = np.array([self.poses[g] for g in self.window])
        landmarks = self._landmarks[active]
        outlying = observation_chi2(graph, poses, landmarks) > self._reject_bound
        if not outlying.any():
            return False
        ids = active[graph.obs_landmark]
        held = self.prior.landmarks if self.prior is not None else np.zeros(0, dtype=np.int64)
        moved, stale = False, []
        for j in np.unique(ids[outlying]):
            mine = ids == j
            in_prior = bool(np.isin(j, held))
            if mine.sum() < 3 or (in_prior and outlying[mine].mean() < 2.0 / 3.0):
                continue
            points = landmark_from_observation(poses[graph.obs_pose[mine]], graph.obs_z[mine])
            median = np.median(points, axis=0)
            spread = np.median(np.linalg.norm(points - median, axis=1))
            if np.linalg.norm(self._landmarks[j] - median) > 3.0 * spread + 1e-9:
                self._landmarks[j] = median
                moved = True
                if in_prior:
                    stale.append(int(j))
        if stale:
            self._release(stale)
        return moved

    def _release(self, stale: list[int]) -> None:
        """Marginalize landmarks out of the prior (in covariance form: drop their rows and columns)."""
        p = self.prior
        assert p is not None
        slots = np.flatnonzero(np.isin(p.landmarks, stale))
        drop = (2 * slots[:, None] + np.arange(2)).reshape(-1)
        keep = np.setdiff1d(np.arange(len(p.mu)), drop)
        Sigma = np.ascontiguousarray(p.Sigma[np.ix_(keep, keep)])
        self.prior = _Prior(p.pose, np.delete(p.landmarks, slots), p.x_lin[keep], p.mu[keep], Sigma)
        self.released += len(slots)
        self._solved = None

    def _reduced_prior(self, active: Index, pose_column: int, landmark_column: Index) -> tuple:
        """The prior's marginal on its pose and the active landmarks, and a function recovering the others."""
        p = self.prior
        assert p is not None
        order, passive, is_active, A = self._prior_split(active)
        mu_a = p.mu[order]
        local = np.searchsorted(active, p.landmarks[is_active])
        columns = np.r_[(landmark_column[local][:, None] + np.arange(2)).reshape(-1), pose_column + np.arange(3)]
        angle = np.zeros(len(order), dtype=bool)
        angle[-1] = True
        quadratic = QuadraticPrior(columns, p.x_lin[order], angle, A, -A @ mu_a)
        if len(passive) == 0:
            return quadratic, None
        passive_ids = p.landmarks[~is_active]

        def recover(oldest_pose: Array, active_landmarks: Array) -> None:
            """Passive landmarks at their conditional mean given the solved active part (matrix-vector only)."""
            d_a = np.r_[active_landmarks[local].reshape(-1), oldest_pose] - p.x_lin[order]
            d_a[-1] = wrap(d_a[-1])
            d_p = p.mu[passive] + p.Sigma[np.ix_(passive, order)] @ (A @ (d_a - mu_a))
            self._landmarks[passive_ids] = (p.x_lin[passive] + d_p).reshape(-1, 2)

        return quadratic, recover

    def _linearized_window(self) -> tuple[Index, Any, Any, Array | None]:
        """The window and the reduced prior linearized once at the current estimate (no iteration).

        Returns:
            (landmarks the window observes, the system's layout, the reduced prior, its dense information matrix
            or None when nothing is free).
        """
        active = self._active()
        graph, sparse, quadratic, _, poses = self._window_system(active)
        linearized = solve(
            graph,
            poses,
            self._landmarks[active],
            SolverConfig(max_iterations=0),
            loss=self.config.loss,
            prior=quadratic,
            return_information=True,
            graph_layout=sparse,
            dense=True,
        )
        H = None if linearized.information is None else np.asarray(linearized.information)
        return active, sparse, quadratic, H

    def landmark_marginals(self) -> Array:
        """2x2 marginal covariance of every landmark at the current estimate, shape (M, 2, 2).

        The window's factors and the reduced prior are linearized once at the current estimate (no iteration,
        no state change): landmarks a window pose observes read their block of the inverse information;
        passive landmarks add the prior's conditional covariance to the propagated uncertainty of the part
        they are conditioned on. NaN where the system is singular.
        """
        out = np.full((len(self.landmark_ids), 2, 2), np.nan)
        if not self.window:
            return out
        with self._blas.limit(limits=1, user_api="blas"):
            active, sparse, quadratic, H = self._linearized_window()
            if H is None:  # no free variable
                return out
            try:
                C = la.cho_solve(la.cho_factor(H), np.eye(len(H)))
            except (la.LinAlgError, ValueError):  # singular, or not finite
                return out
            cols = sparse.landmark_column[np.arange(len(active))][:, None] + np.arange(2)  # (A, 2)
            out[active] = C[cols[:, :, None], cols[:, None, :]]
            if self.prior is None or quadratic is None:
                return out
            p = self.prior
            order, passive, is_active, A = self._prior_split(active)
            if len(passive) == 0:
                return out
            S_pa = p.Sigma[np.ix_(passive, order)]
            B = S_pa @ A  # d_p = mu_p + B (d_a - mu_a) + noise
            C_a = C[np.ix_(quadratic.columns, quadratic.columns)]
            q = len(order)
            B3, S3 = B.reshape(-1, 2, q), S_pa.reshape(-1, 2, q)
            pairs = passive.reshape(-1, 2)
            S_pp = p.Sigma[pairs[:, :, None], pairs[:, None, :]]
            conditional = S_pp - np.einsum("piq,pjq->pij", B3, S3)
            propagated = np.einsum("piq,qr,pjr->pij", B3, C_a, B3)
            blocks = conditional + propagated
            out[p.landmarks[~is_active]] = 0.5 * (blocks + blocks.transpose(0, 2, 1))
        return out

    # -- marginalization -------------------------------------------------------------------------
    def _judge(self, pose: int) -> NDArray[np.bool_]:
        """Which observations of a window pose are outliers at the current estimate (chi-square bound)."""
        indices, z, _, W = self._observations[pose]
        if self.config.reject_false_alarm <= 0.0:
            return np.zeros(len(indices), dtype=bool)
        return range_bearing_chi2(self.poses[pose][None, :], self._landmarks[indices], z, W) > self._reject_bound

    def _initial_prior(self) -> _Prior:
        """The prior before any marginalization: the start pose, fixed (Sigma = 0) or with its prior."""
        assert self._start is not None
        index, mean, cov = self._start
        x_lin = self.poses[index].copy()
        mu = mean - x_lin
        mu[2] = wrap(mu[2])
        Sigma = np.zeros((3, 3))
        if cov is not None:
            Sigma[:] = cov
        return _Prior(index, np.zeros(0, dtype=np.int64), x_lin, mu, Sigma)

    def _marginalize_oldest(self) -> None:
        """Fold the oldest window pose o's factors into the prior ``[landmarks..., o]``, then eliminate o.

        First o's observations of landmarks the prior holds update it jointly (a Kalman update). Then every
        variable that o's remaining factors determine — landmarks seen for the first time, and the next pose
        n1 through the odometry — is appended from its factor, ``d_new = M d_o - J_new^-1 (r0 + v)`` with
        ``M = -J_new^-1 J_o``; their noises are independent, so one growth of Sigma serves them all and drops o
        on the way: ``[landmarks..., new landmarks..., n1]``.
        """
        o, n1 = self.window[0], self.window[1]
        p = self.prior if self.prior is not None else self._initial_prior()
        assert p.pose == o
        x_lin, mu, Sigma = p.x_lin, p.mu, p.Sigma
        n = len(mu)
        if not self.config.first_estimate_jacobians:
            current = np.r_[self._landmarks[p.landmarks].reshape(-1), self.poses[o]]
            shift = current - x_lin
            shift[-1] = wrap(shift[-1])
            x_lin, mu = current, mu - shift
        lin_o = x_lin[n - 3 :]
        landmarks = list(p.landmarks)
        slot = {int(j): k for k, j in enumerate(landmarks)}
        # factors that append a variable: (r0, J_o, J_new, lin_new)
        appended: list[tuple[Array, Array, Array, Array]] = []
        obs = self._observations.get(o)
        if obs is not None:
            keep = ~self._judge(o)
            self._decisions.append((o, ~keep))
            if not keep.all():  # judged outliers are never folded into the prior
                self._solved = None  # the solved information holds them
                obs = tuple(a[keep] for a in obs) if keep.any() else None
        if obs is not None:
            indices, z, z_cov = _fuse_repeats(*obs[:3])
            held = np.array([int(j) in slot for j in indices], dtype=bool)
            first = ~held  # first sight (repeats are fused): appends the landmark
            for j in indices[first]:
                slot[int(j)] = len(landmarks)
                landmarks.append(int(j))
            lin_l = np.array(
                [
                    self._landmarks[j] if first[k] else x_lin[2 * slot[int(j)] : 2 * slot[int(j)] + 2]
                    for k, j in enumerate(indices)
                ]
            )
            z_hat, J_p, J_l = range_bearing_with_jacobians(lin_o, lin_l)
            e = z_hat - z
            e[:, 1] = wrap(e[:, 1])
            W = obs[3] if z_cov is obs[2] else sqrt_information(z_cov)  # stored unless repeats were fused
            r0 = np.einsum("kij,kj->ki", W, e)
            if self.config.loss is not None:
                W = W * np.sqrt(self.config.loss.weight(np.sum(r0 * r0, axis=1)))[:, None, None]
                r0 = np.einsum("kij,kj->ki", W, e)
            Jp, Jl = W @ J_p, W @ J_l
            update = np.flatnonzero(held)
            if len(update):
                cols = np.r_[
                    (2 * np.array([slot[int(indices[k])] for k in update])[:, None] + np.arange(2)).reshape(-1),
                    np.arange(n - 3, n),
                ]
                J_s = stacked_jacobian(Jp[update], Jl[update], pose_first=False)
                PHt = Sigma[:, cols] @ J_s.T
                S = J_s @ PHt[cols] + np.eye(len(J_s))  # whitened factors: unit noise
                # in place: the prior owns its covariance (untouched if S is not positive definite in floating point)
                with contextlib.suppress(np.linalg.LinAlgError):
                    innovation = -(r0[update].reshape(-1) + J_s @ mu[cols])
                    dmu, _, _ = apply_update(Sigma, PHt, S, innovation, exactly_symmetric=False)
                    mu = mu + dmu
            appended += [(r0[k], Jp[k], Jl[k], lin_l[k]) for k in np.flatnonzero(first)]
        delta, _, W = self._odometry[n1]
        e, J_a, J_b = odometry_residual_with_jacobians(lin_o, self.poses[n1], delta)
        appended.append((W @ e, W @ J_a, W @ J_b, self.poses[n1]))
        # One growth: keep the landmarks, append the new variables, drop o.
        inv = [np.linalg.inv(a[2]) for a in appended]
        M = np.vstack([-i @ a[1] for i, a in zip(inv, appended)])  # (q, 3)
        offset = np.concatenate([-i @ a[0] for i, a in zip(inv, appended)])
        noise = la.block_diag(*[i @ i.T for i in inv])
        keep = n - 3
        q = len(M)
        cross = M @ Sigma[:keep, keep:].T  # (q, keep): read o's rows before they are overwritten
        block = M @ Sigma[keep:, keep:] @ M.T + noise
        grown = _resized(Sigma, keep + q, keep)  # o's rows and columns are reused when the size holds
        grown[keep:, :keep] = cross
        grown[:keep, keep:] = cross.T
        grown[keep:, keep:] = 0.5 * (block + block.T)
        mu = np.r_[mu[:keep], M @ mu[keep:] + offset]
        x_lin = np.r_[x_lin[:keep], np.concatenate([a[3] for a in appended])]
        self.prior = _Prior(n1, np.array(landmarks, dtype=np.int64), x_lin, mu, grown)
        self.history.append(self.poses.pop(o))
        self._odometry.pop(n1)
        self._observations.pop(o, None)
        self.window.pop(0)
        self.marginalized += 1

    @property
    def _global_solver(self) -> SolverConfig:
        """The window's solver settings with ``global_iterations`` iterations."""
        return replace(self.config.solver, max_iterations=self.config.global_iterations)

    def _global_inputs(self) -> tuple[ProblemLog, list[tuple[int, NDArray[np.bool_]]], Array, Array] | None:
        """What a global solve needs, copied (the log's lists, the outlier decisions, the current values)."""
        window = self.window
        if len(self.log.poses) != len(self.history) + len(window) or self.log.landmark_ids != tuple(self.landmark_ids):
            return None
        poses = np.vstack([self.history.view(), np.array([self.poses[g] for g in window])])
        return self.log.frozen(), list(self._decisions), poses, self._landmarks.copy()

    def _relinearize_globally(self) -> dict[str, float]:
        """Re-solve every factor from the current estimate now; revise the history; re-anchor the prior there."""
        started = time.perf_counter()
        inputs = self._global_inputs()
        if inputs is None:
            return {}
        result = solve_all(*inputs, self._global_solver, self.config.loss)
        report = self._apply_global(result, len(inputs[2]), at_once=True)
        report["global_s"] = time.perf_counter() - started
        return report

    def _start_global(self) -> None:
        """Solve every factor in a background thread from a copy of the current state; the result is handed
        over ``global_delay`` steps later (waiting for it if need be), so the outcome never depends on timing."""
        inputs = self._global_inputs()
        self._since_global = 0
        if inputs is None:
            return
        solver = self._global_solver
        delay = max(self.config.global_delay, self._steps // GLOBAL_DELAY_GROWTH)
        job = _GlobalJob(handover=self._steps + delay, n_poses=len(inputs[2]))

        def work() -> None:
            try:
                job.result = solve_all(*inputs, solver, self.config.loss)
            except Exception as exc:  # noqa: BLE001 - handed over as "no result"; the smoother goes on without it
                job.error = repr(exc)

        job.thread = threading.Thread(target=work, name=f"{self.name} global relinearization", daemon=True)
        job.thread.start()
        self._global_job = job

    def _finish_job(self) -> _GlobalJob | None:
        """The pending background solve, finished (joined); None if there is none."""
        job = self._global_job
        if job is not None and job.thread is not None:
            job.thread.join()
            job.thread = None
        return job

    def _apply_global(self, result: SolveResult, n_poses: int, at_once: bool) -> dict[str, float]:
        """Revise the history with a global solution over poses ``0..n_poses-1`` and re-anchor the prior.

        ``at_once``: the solution is of the current state (window poses and landmarks take its values too);
        otherwise it is of an earlier one (handed over from the background): window poses and landmark estimates
        keep their newer values, poses marginalized since keep theirs, and the prior is re-anchored at the
        revised history and the current oldest window pose.
        """
        oldest = self.window[0]
        history = self.history.view().copy()
        revised = min(oldest, n_poses)
        history[:revised] = result.poses[:revised]
        landmarks = self._landmarks.copy()
        landmarks[: len(result.landmarks)] = result.landmarks
        oldest_value = result.poses[oldest] if at_once else self.poses[oldest].copy()
        if not at_once and oldest >= n_poses:
            # Poses that left the window after the solve started, and landmarks first seen since, follow the
            # solution rigidly: their geometry relative to the last solved pose is kept (it holds newer data).
            anchor = n_poses - 1
            before, after = self.history.view()[anchor], result.poses[anchor]
            history[anchor + 1 :] = compose(after, between(before, self.history.view()[anchor + 1 :]))
            oldest_value = compose(after, between(before, oldest_value))
            new = landmarks[len(result.landmarks) :]
            if len(new):
                local = (new - before[:2]) @ rotation(before[2])  # R(before)^T (l - t)
                landmarks[len(result.landmarks) :] = local @ rotation(after[2]).T + after[:2]
        p = self.prior
        anchored = None
        if p is not None and p.pose == oldest:
            past = history_graph(inlier_graph(self.log, self._decisions), oldest)
            values = np.vstack([history, oldest_value[None]])
            if not at_once and oldest >= n_poses:  # bring the poses that left since to agree with the solution
                values, landmarks = refine_recent(
                    past, n_poses, values, landmarks, self._global_solver, self.config.loss
                )
                history, oldest_value = values[:-1], values[-1]
            relinearized = len(p.landmarks) <= self.config.global_information_max
            g_k, H_k = prior_marginal(past, values, landmarks, p.landmarks, self.config.loss, relinearized)
            Sigma = p.Sigma if H_k is None else prior_covariance(H_k, p.Sigma)
            # The history's pull on the prior's variables, in its own metric: an inlier-consistent history gives
            # a chi-square value; a larger one means the solve did not reconcile it (a poor minimum): keep all.
            if float(g_k @ Sigma @ g_k) > chi2.isf(GLOBAL_FALSE_ALARM, len(g_k)):
                self.global_rejections += 1
                return {"global_rejected": 1.0}
            x_lin = np.r_[landmarks[p.landmarks].reshape(-1), oldest_value]
            anchored = _Prior(oldest, p.landmarks, x_lin, -(Sigma @ g_k), Sigma)
        self.history.replace(history)
        self._solved = None
        if at_once:
            for g in self.window:
                self.poses[g] = result.poses[g].copy()
            self._landmarks = landmarks
        if anchored is not None:
            self.prior = anchored
        self.global_solves += 1
        return {
            "global_iterations": result.iterations,
            "global_cost_before": result.initial_cost,
            "global_cost_after": result.final_cost,
        }

    def _window_full(self) -> bool:
        """Whether the oldest window pose is to be marginalized (see ``window`` and ``window_distance``)."""
        c, n = self.config, len(self.window)
        if n <= c.window:
            return False
        if not c.window_distance or n > c.window_max:  # n > W already: never fewer than W poses
            return True
        path = sum(math.hypot(*self._odometry[g][0][:2]) for g in self.window[2:] if g in self._odometry)
        return path >= c.window_distance

    # -- protocol --------------------------------------------------------------------------------
    def step(self, step: Step) -> Snapshot:
        """Add the step; solve every K steps; marginalize beyond W poses."""
        with self._blas.limit(limits=1, user_api="blas"):
            self._add_pose(step)
            step, _ = self._resolve(step, 0)
            self._add_observations(step, 0)
            self.log.add(step)
            self._add_retro()
            self._since_solve += 1
            report: dict[str, float] = {}
            if self._since_solve >= self.config.relinearize_every:
                report = self._solve()
            marginalized = []
            while self._window_full():
                if self.window[0] in self._unsolved:
                    report = self._solve()
                marginalized.append(self.window[0])
                self._marginalize_oldest()
            self._since_global += 1
            self._steps += 1
            job = self._global_job
            if job is not None and self._steps >= job.handover:
                started = time.perf_counter()
                self._finish_job()
                self._global_job = None
                if job.result is not None:
                    report = {**report, **self._apply_global(job.result, job.n_poses, at_once=False)}
                    report["global_s"] = time.perf_counter() - started
            every = self.config.global_every and max(self.config.global_every, self._steps // GLOBAL_GROWTH)
            due = every and self._since_global >= every and len(self.history) and not self._unsolved
            if due and self._global_job is None:
                if self.config.global_delay:
                    self._start_global()
                else:
                    self._since_global = 0
                    report = {**report, **self._relinearize_globally()}
            self._step_report, self._step_marginalized = report, marginalized
            return self.snapshot(step)

    def extend(self, step: Step, start: int) -> Snapshot:
        """The newest step grew: add its observations ``start:``; solve again if this step was a solve step."""
        with self._blas.limit(limits=1, user_api="blas"):
            step, start = self._resolve(step, start)
            self._add_observations(step, start)
            self.log.extend(step, start)
            self._add_retro()
            if self._since_solve == 0:  # this step solved: its new sightings are used at once
                self._step_report = self._solve()
            return self.snapshot(step)

    def trajectory(self) -> Array:
        """Current estimate of every pose so far (window poses as now, older ones as they left), shape (N, 3)."""
        return np.concatenate(self.trajectory_parts())

    def trajectory_parts(self) -> tuple[Array, Array]:
        """(poses that left the window, read-only (N - W, 3) view; the window's poses now, a copy (W, 3))."""
        return self.history.view(), np.array([self.poses[g] for g in self.window]).reshape(-1, 3)

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue exactly where the smoother is (numbers and arrays only)."""
        p = self.prior
        return {
            "window": list(self.window),
            "poses": np.array([self.poses[g] for g in self.window]).reshape(-1, 3),
            "final_poses": self.trajectory(),
            "landmark_ids": list(self.landmark_ids),
            "landmarks": self._landmarks.copy(),
            "odometry": pack_odometry(self._odometry),
            "observations": pack_observations(self._observations),
            "start": None if self._start is None else list(self._start),
            "prior": None
            if p is None
            else {
                "pose": p.pose,
                "landmarks": p.landmarks,
                "x_lin": p.x_lin,
                "mu": p.mu,
                "Sigma": p.Sigma.copy(),
                "capacity": len(p.Sigma),  # read by versions that kept a larger buffer
            },
            "pose_cov": self._pose_cov,
            "since_solve": self._since_solve,
            "unsolved": sorted(self._unsolved),
            "solves": self.solves,
            "marginalized": self.marginalized,
            "released": self.released,
            "step_report": dict(self._step_report),
            "step_marginalized": list(self._step_marginalized),
            "decision_poses": np.array([d[0] for d in self._decisions], dtype=np.int64),
            "decision_sizes": np.array([len(d[1]) for d in self._decisions], dtype=np.int64),
            "decisions": np.concatenate([d[1] for d in self._decisions]) if self._decisions else np.zeros(0, bool),
            "log": self.log.state_dict(),
            "steps": self._steps,
            "global_job": self._job_state(),
            "since_global": self._since_global,
            "global_solves": self.global_solves,
            "global_rejections": self.global_rejections,
            "book": self.book.state_dict(),
            "resolved": None
            if self._resolved is None
            else {"landmarks": list(self._resolved.landmarks), "z": self._resolved.z, "z_cov": self._resolved.z_cov},
            "solved": None
            if self._solved is None
            else {
                "window": self._solved.window,
                "pose_column": self._solved.pose_column,
                "active": self._solved.active,
                "landmark_column": self._solved.landmark_column,
                "factor": self._solved.factor,
                "size": len(self._solved.factor),
            },
        }

    def _job_state(self) -> dict[str, Any] | None:
        """The pending global solve, finished first (its result is part of the state)."""
        job = self._finish_job()
        if job is None:
            return None
        r = job.result
        return {
            "handover": job.handover,
            "n_poses": job.n_poses,
            "error": job.error,
            "poses": None if r is None else r.poses,
            "landmarks": None if r is None else r.landmarks,
            "iterations": 0 if r is None else r.iterations,
            "converged": False if r is None else r.converged,
            "initial_cost": 0.0 if r is None else r.initial_cost,
            "final_cost": 0.0 if r is None else r.final_cost,
            "message": "" if r is None else r.message,
        }

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict` (this smoother's config is kept)."""
        as_float = lambda a: np.array(a, dtype=float)  # noqa: E731
        self.window = [int(g) for g in state["window"]]
        self.poses = {g: pose.copy() for g, pose in zip(self.window, as_float(state["poses"]).reshape(-1, 3))}
        self.history = PoseHistory(
            as_float(state["final_poses"]).reshape(-1, 3)[: len(state["final_poses"]) - len(self.window)]
        )
        self.landmark_ids = list(state["landmark_ids"])
        self._index = {lid: j for j, lid in enumerate(self.landmark_ids)}
        self._landmarks = as_float(state["landmarks"]).reshape(-1, 2)
        self._odometry = unpack_odometry(state["odometry"])
        self._observations = unpack_observations(state["observations"])
        start = state["start"]
        self._start = (
            None
            if start is None
            else (int(start[0]), as_float(start[1]), None if start[2] is None else as_float(start[2]))
        )
        prior = state["prior"]
        self.prior = None
        if prior is not None:
            n = len(prior["mu"])
            self.prior = _Prior(
                int(prior["pose"]),
                np.array(prior["landmarks"], dtype=np.int64),
                as_float(prior["x_lin"]),
                as_float(prior["mu"]),
                np.ascontiguousarray(as_float(prior["Sigma"]).reshape(n, n)),
            )
        self._pose_cov = as_float(state["pose_cov"])
        self._since_solve = int(state["since_solve"])
        self._unsolved = {int(g) for g in state["unsolved"]}
        self.solves, self.marginalized = int(state["solves"]), int(state["marginalized"])
        self.released = int(state["released"])
        self._step_report = dict(state["step_report"])
        self._step_marginalized = [int(g) for g in state["step_marginalized"]]
        cuts = np.cumsum(np.array(state["decision_sizes"], dtype=np.int64))[:-1]
        masks = np.split(np.array(state["decisions"], dtype=bool), cuts) if len(state["decision_sizes"]) else []
        self._decisions = [(int(g), m.copy()) for g, m in zip(state["decision_poses"], masks)]
        self.log.load_state(state["log"])
        self._steps = int(state["steps"])
        job = state["global_job"]
        self._global_job = None
        if job is not None:
            restored = _GlobalJob(int(job["handover"]), int(job["n_poses"]), error=job["error"])
            if job["poses"] is not None:
                restored.result = SolveResult(
                    as_float(job["poses"]).reshape(-1, 3),
                    as_float(job["landmarks"]).reshape(-1, 2),
                    int(job["iterations"]),
                    bool(job["converged"]),
                    float(job["initial_cost"]),
                    float(job["final_cost"]),
                    str(job["message"]),
                )
            self._global_job = restored
        self._since_global = int(state["since_global"])
        self.global_solves = int(state["global_solves"])
        self.global_rejections = int(state["global_rejections"])
        self.book.load_state(state["book"])
        resolved = state["resolved"]
        self._resolved = (
            None
            if resolved is None
            else Step(  # only its sightings are read again (extend keeps them and appends)
                index=self.window[-1],
                t=math.nan,
                odometry=None,
                odometry_cov=None,
                landmarks=tuple(resolved["landmarks"]),
                z=as_float(resolved["z"]).reshape(-1, 2),
                z_cov=as_float(resolved["z_cov"]).reshape(-1, 2, 2),
            )
        )

        solved = state.get("solved")  # absent from checkpoints of versions before it
        self._solved = (
            None
            if solved is None
            else _Solved(
                np.array(solved["window"], dtype=np.int64),
                np.array(solved["pose_column"], dtype=np.int64),
                np.array(solved["active"], dtype=np.int64),
                np.array(solved["landmark_column"], dtype=np.int64),
                np.array(solved["factor"], dtype=float).reshape(int(solved["size"]), int(solved["size"])),
            )
        )

    def snapshot(self, step: Step) -> Snapshot:
        """The current estimate as an immutable snapshot."""
        report = self._step_report
        return Snapshot(
            estimator=self.name,
            index=step.index,
            t=step.t,
            pose=self.poses[self.window[-1]].copy(),
            pose_cov=self._pose_cov.copy(),
            landmark_ids=tuple(self.landmark_ids),
            landmarks=self._landmarks.copy(),
            info={
                "window": tuple(self.window),
                "window_poses": np.array([self.poses[g] for g in self.window]),
                "relinearized": bool(report),
                "marginalized": tuple(self._step_marginalized),
                **report,
            },
        )

    def finish(self) -> Estimate:
        """Solve once more if anything arrived since the last solve; each pose's last estimate is final.

        A global relinearization still running in the background is waited for and dropped: its hand-over
        step never came (the final estimate is what the regular schedule gave).
        """
        started = time.perf_counter()
        self._finish_job()
        self._global_job = None
        if self.window:
            with self._blas.limit(limits=1, user_api="blas"):
                self._solve(final=True)
        decisions = self._decisions + [(g, self._judge(g)) for g in self.window if g in self._observations]
        rejected = np.concatenate([d[1] for d in decisions]) if decisions else np.zeros(0, dtype=bool)
        return Estimate(
            self.name,
            self.trajectory(),
            tuple(self.landmark_ids),
            self._landmarks.copy(),
            {
                "rejected": rejected,
                "solves": self.solves,
                "marginalized_poses": self.marginalized,
                "global_solves": self.global_solves,
                "global_rejections": self.global_rejections,
                "landmarks_released": self.released,
                "window": self.config.window,
                "relinearize_every": self.config.relinearize_every,
                "final_solve_s": time.perf_counter() - started,
                **self.book.info(),
            },
        )
