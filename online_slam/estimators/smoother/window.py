"""The smoother's window: its poses, factors and landmarks, the graph and system it solves, consensus moves.

The window keeps the newest poses and *every* landmark as variables. Landmarks that no window pose observes
(passive) appear only in the marginal prior, a quadratic: a window system holds the prior's marginal on its
pose and the observed (active) landmarks only (:func:`~online_slam.estimators.smoother.prior.reduced`), so
each iteration factors a system over the window poses and the observed landmarks; the passive landmarks are
recovered from their conditional mean after the solve. The result equals the solve over all landmarks.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.history import PoseHistory
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.smoother.config import WindowConfig
from online_slam.estimators.smoother.prior import Prior, Sightings, reduced
from online_slam.factors.fixes import with_fixes
from online_slam.factors.graph import (
    FactorGraph,
    JacobianPoint,
    SparseLayout,
    layout,
    observation_chi2,
    sighting_chi2,
    sqrt_information,
)
from online_slam.factors.robust import RobustLoss
from online_slam.frontend.steps import Step
from online_slam.geometry.se2 import compose_with_jacobians
from online_slam.models.fix import fix_factors
from online_slam.models.observation import landmark_from_sighting, tags
from online_slam.solvers.least_squares import QuadraticPrior, SolverConfig, SolveResult, solve
from online_slam.sources.events import LandmarkId, RobotId
from online_slam.sources.landmark_map import block_diagonal, joint_of

Array = NDArray[np.float64]
Index = NDArray[np.int64]


@dataclass(eq=False)
class Window:
    """The window's poses and factors, the poses that left it, and every landmark."""

    indices: list[int] = field(default_factory=list)
    """Indices of the window's poses, oldest first."""
    poses: dict[int, Array] = field(default_factory=dict)
    """Current estimate of each window pose, shape (3,), keyed by index."""
    history: PoseHistory = field(default_factory=PoseHistory)
    """Final estimates of the poses that left the window."""
    landmark_ids: list[LandmarkId] = field(default_factory=list)
    """Landmark ids in order of first sighting."""
    landmarks: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """Current estimate of every landmark, shape (M, 2)."""
    odometry: dict[int, tuple[Array, Array, Array]] = field(default_factory=dict)
    """Window odometry factors (delta, covariance, square-root information), keyed by the later pose."""
    observations: dict[int, Sightings] = field(default_factory=dict)
    """Window pose sightings (landmark rows, z, covariances, square-root information, model tags), keyed by pose."""
    start: tuple[int, Array, Array | None] | None = None
    """(start pose, its prior mean, its prior covariance or None when fixed)."""
    pose_cov: Array = field(default_factory=lambda: np.zeros((3, 3)))
    """Covariance of the newest pose, shape (3, 3); with several robots, the robot's next pose propagates it from
    its own newest pose's (``robot_cov``)."""
    unsolved: set[int] = field(default_factory=set)
    """Window poses with factors added since the last solve."""
    since_solve: int = 0
    """Steps since the last solve."""
    robots: list[RobotId | None] = field(default_factory=list)
    """The robots begun, in order (several robots: see :mod:`~online_slam.estimators.smoother.robots`)."""
    robot_times: list[float] = field(default_factory=list)
    """The time of each robot's newest pose, in the order of ``robots``."""
    robot_of: dict[int, RobotId | None] = field(default_factory=dict)
    """The robot of each window pose, once several robots began (empty with one)."""
    previous: dict[int, int] = field(default_factory=dict)
    """The earlier pose of each window odometry factor, keyed by the later pose, once several robots began (with
    one it is the pose before)."""
    starts: dict[int, tuple[Array, Array | None]] = field(default_factory=dict)
    """Start prior (mean, covariance or None when fixed) of each robot after the first, by its start pose, while
    the marginal prior does not hold it."""
    robot_factors: list[tuple[int, int, Array, Array, int]] = field(default_factory=list)
    """Window robot sightings: (sighting pose, seen pose, z (2,), square-root information (2, 2), the sighting's
    number in the log's :class:`~online_slam.estimators.problem.RobotSightings`)."""
    left: list[int] = field(default_factory=list)
    """The pose index of each ``history`` row, once several robots began (with one, row k is pose k)."""
    robot_cov: dict[int, Array] = field(default_factory=dict)
    """The covariance of each robot's newest pose but the window's newest (``pose_cov``), by pose, as it was when
    that pose stopped being the window's newest (several robots)."""
    sightings_read: int = 0
    """Robot sightings of the log read so far."""
    sightings_waiting: list[int] = field(default_factory=list)
    """Robot sightings read whose seen pose may still come (their time is the newest step's)."""
    map_size: int = 0
    """The first ``map_size`` landmarks are a map's (``--map``): each has a prior, in the window's graph until the
    marginal prior holds it (:func:`~.prior.fold_map`)."""
    map_xy: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """The map's positions, shape (map_size, 2)."""
    map_cov: Array = field(default_factory=lambda: np.zeros((0, 2, 2)))
    """Their prior covariances, shape (map_size, 2, 2)."""
    map_joint: Array = field(default_factory=lambda: np.zeros((0, 0)))
    """Their joint covariance, shape (2 map_size, 2 map_size), when the map has one (empty: independent)."""
    fixes: dict[int, tuple[Array, Array, Array]] = field(default_factory=dict)
    """Window poses' absolute fixes (mean (f, 3), offset (f, 2), square-root information (f, 3, 3):
    :func:`~online_slam.models.fix.fix_factors`), keyed by pose."""
    index: dict[LandmarkId, int] = field(init=False)
    """Each landmark id's row in ``landmarks``."""

    def __post_init__(self) -> None:
        self.index = {lid: j for j, lid in enumerate(self.landmark_ids)}

    @property
    def several(self) -> bool:
        """Whether a second robot began."""
        return len(self.robots) > 1

    def joint_map(self) -> tuple[Array, Array, Array] | None:
        """(the map landmarks' estimates, their map positions, the joint covariance) for the marginal prior to hold
        from its start (:func:`~.prior.initial_prior`), or None without a joint map."""
        if not len(self.map_joint):
            return None
        return self.landmarks[: self.map_size], self.map_xy, self.map_joint

    def map_covariance(self, rows: Index) -> Array | None:
        """The map's prior covariance of landmarks ``rows`` (k,), shape (2k, 2k) (joint when the map has one), or
        None when one of them is no map landmark."""
        if not len(rows) or rows.max() >= self.map_size:
            return None
        return joint_of(self.map_joint, rows) if len(self.map_joint) else block_diagonal(self.map_cov[rows])

    def values(self) -> Array:
        """The window poses' estimates, oldest first, shape (P, 3)."""
        return np.array([self.poses[g] for g in self.indices])

    def all_poses(self) -> Array:
        """Every pose's estimate in index order (the history's as they left, the window's now), shape (N, 3)."""
        if not self.several:
            return np.vstack([self.history.view(), self.values()])
        out = np.zeros((len(self.history) + len(self.indices), 3))
        out[self.left] = self.history.view()
        out[self.indices] = self.values()
        return out

    def add_pose(self, step: Step) -> None:
        """Add the step's pose: a start (from its prior) or the robot's newest pose composed with the odometry."""
        i = step.index
        if step.odometry is None:
            pose = np.array(step.prior, dtype=float)
            start = (pose.copy(), None if step.prior_cov is None else np.array(step.prior_cov))
            if self.robots:  # another robot begins
                self.starts[i] = start
                if not self.several:
                    self.robot_of = dict.fromkeys(self.indices, self.robots[0])
                    self.previous = {g: g - 1 for g in self.odometry}
                    self.left = list(range(len(self.history)))
            else:
                self.start = (i, *start)
            self.robots.append(step.robot)
            self.robot_times.append(step.t)
            if self.several:
                self.robot_cov[self.indices[-1]] = self.pose_cov
            self.pose_cov = np.zeros((3, 3)) if step.prior_cov is None else np.array(step.prior_cov)
        else:
            previous = self.newest(step.robot)
            self.robot_times[self.robots.index(step.robot)] = step.t
            cov = self.pose_cov
            if self.several:
                self.previous[i] = previous
                if previous != self.indices[-1]:  # another robot's pose is the newest: keep its covariance
                    self.robot_cov[self.indices[-1]] = self.pose_cov
                    cov = self.robot_cov.pop(previous, self.pose_cov)
            odometry_cov = cast(Array, step.odometry_cov)  # a step with odometry has its covariance
            pose, F, G = compose_with_jacobians(self.poses[previous], step.odometry)
            self.pose_cov = F @ cov @ F.T + G @ odometry_cov @ G.T
            self.odometry[i] = (
                np.array(step.odometry),
                np.array(odometry_cov),
                sqrt_information(odometry_cov),
            )
        self.indices.append(i)
        self.poses[i] = pose
        self.unsolved.add(i)
        if self.several:
            self.robot_of[i] = step.robot

    def newest(self, robot: RobotId | None) -> int:
        """The robot's newest pose (the newest pose with one robot)."""
        if not self.several:
            return self.indices[-1]
        return next(g for g in reversed(self.indices) if self.robot_of[g] == robot)

    def add_sightings(self, step: Step, start: int) -> None:
        """Factors for the newest pose's sightings ``start:``; new landmarks from their first sight."""
        if len(step.landmarks) <= start:
            return
        i = step.index
        pose = self.poses[i]
        indices = []
        ids = cast("tuple[LandmarkId, ...]", step.landmarks[start:])  # a resolved step: every sighting has its id
        for lid, z, model in zip(ids, step.z[start:], step.z_model[start:]):
            if lid not in self.index:
                self.index[lid] = len(self.landmark_ids)
                self.landmark_ids.append(lid)
                self.landmarks = np.vstack([self.landmarks, landmark_from_sighting(pose, z, model)])
            indices.append(self.index[lid])
        z, z_cov = step.z[start:], step.z_cov[start:]
        self._merge(i, (np.array(indices, dtype=np.int64), z, z_cov, sqrt_information(z_cov), step.z_model[start:]))

    def add_fixes(self, step: Step) -> None:
        """Factors for every fix of the newest pose (all of them again when the step grew)."""
        if step.fixes and len(self.fixes.get(step.index, ((),))[0]) != len(step.fixes):
            self.fixes[step.index] = fix_factors(step.fixes)
            self.unsolved.add(step.index)

    def add_earlier_sighting(self, lid: LandmarkId, pose: int, z: Array, R: Array, model: Any) -> bool:
        """Add a sighting ``z`` (2,) with covariance ``R`` (2, 2) and model tag ``model`` of a known landmark from
        an earlier window pose; False (nothing added) when the pose left the window or the landmark is unknown."""
        if pose not in self.poses or lid not in self.index:
            return False
        row, tag = np.array([self.index[lid]], dtype=np.int64), tags(model, 1)
        self._merge(pose, (row, z[None], R[None], sqrt_information(R[None]), tag))
        self.unsolved.add(pose)
        return True

    def _merge(self, pose: int, factors: Sightings) -> None:
        """Append sightings to a window pose's."""
        if pose in self.observations:
            merged = tuple(np.concatenate([a, b]) for a, b in zip(self.observations[pose], factors))
            factors = cast(Sightings, merged)  # the same five columns, longer
        self.observations[pose] = factors

    def drop_oldest(self) -> None:
        """Move the oldest pose to the history and drop its factors (the prior holds them now)."""
        o, n1 = self.indices[0], self.indices[1]
        self.history.append(self.poses.pop(o))
        self.odometry.pop(n1)
        self.observations.pop(o, None)
        self.fixes.pop(o, None)
        self.indices.pop(0)

    def drop(self, pose: int, successor: int) -> None:
        """Move a pose (its robot's oldest) to the history and drop its factors: several robots."""
        self.history.append(self.poses.pop(pose))
        self.left.append(pose)
        self.odometry.pop(successor)
        self.previous.pop(successor)
        self.observations.pop(pose, None)
        self.fixes.pop(pose, None)
        self.indices.remove(pose)
        self.robot_of.pop(pose)

    def chain(self, robot: RobotId | None) -> list[int]:
        """The robot's window poses, oldest first (several robots)."""
        return [g for g in self.indices if self.robot_of[g] == robot]

    def is_full(self, config: WindowConfig) -> bool:
        """Whether the oldest pose is to be marginalized (see :class:`WindowConfig`)."""
        n = len(self.indices)
        if n <= config.size:
            return False
        if not config.distance or n > config.max_poses:  # n > W already: never fewer than W poses
            return True
        path = sum(math.hypot(*self.odometry[g][0][:2]) for g in self.indices[2:] if g in self.odometry)
        return path >= config.distance


@dataclass(frozen=True)
class System:
    """A window's least-squares system over its poses and active landmarks."""

    graph: FactorGraph
    """The window's factors over local pose indices and the active landmarks (local order)."""
    layout: SparseLayout
    """The graph's layout (columns of every variable)."""
    quadratic: QuadraticPrior | None
    """The prior's marginal on its pose and the active landmarks, or None without a prior."""
    recover: Callable[[Array, Array], tuple[Index, Array]] | None
    """The passive landmarks from the solved prior poses and active landmarks, or None when there are none."""
    poses: Array
    """The window poses' current estimates, shape (P, 3)."""
    prior_poses: Index
    """The local index of each pose the prior holds, in its order (empty without a prior)."""
    jacobian_point: JacobianPoint | None = None
    """First-Estimates Jacobians: the prior's variables' Jacobians taken at its linearization point (or None)."""


@dataclass(frozen=True)
class Linearized:
    """A window system linearized once at the current estimate (no iteration)."""

    active: Index
    """The landmarks the window observes (sorted), shape (A,)."""
    layout: SparseLayout
    """The system's layout."""
    quadratic: QuadraticPrior | None
    """The reduced prior, or None without a prior."""
    information: Array | None
    """Dense information matrix, or None when nothing is free."""
    poses: int
    """Window poses (the newest is the last)."""


def active(window: Window) -> Index:
    """Landmarks some window pose observes (sorted)."""
    observed = [window.observations[i][0] for i in window.indices if i in window.observations]
    return np.unique(np.concatenate(observed)) if observed else np.zeros(0, dtype=np.int64)


def window_graph(window: Window, active: Index) -> tuple[FactorGraph, dict[int, int]]:
    """The window's factors as a graph over local pose indices and the active landmarks (local order), and each
    window pose's local index."""
    local = {g: k for k, g in enumerate(window.indices)}
    to_local = np.full(len(window.landmark_ids), -1, dtype=np.int64)
    to_local[active] = np.arange(len(active))
    if window.several:
        odo = [
            (local[window.previous[j]], local[j], *window.odometry[j]) for j in window.indices if j in window.previous
        ]
    else:
        odo = [(local[j] - 1, local[j], *window.odometry[j]) for j in window.indices[1:]]
    obs = [(local[i], *window.observations[i]) for i in window.indices if i in window.observations]
    fixed: list[int] = []
    prior_pose, prior_mean, prior_W = np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3, 3))
    starts = {} if window.start is None else {window.start[0]: window.start[1:]}
    starts |= window.starts
    free = [(local[i], mean, cov) for i, (mean, cov) in starts.items() if i in local and cov is not None]
    fixed = [local[i] for i, (_, cov) in starts.items() if i in local and cov is None]
    if free:
        prior_pose = np.array([f[0] for f in free], dtype=np.int64)
        prior_mean, prior_W = np.array([f[1] for f in free]), sqrt_information(np.array([f[2] for f in free]))
    graph = FactorGraph(
        n_poses=len(window.indices),
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
        obs_model=np.concatenate([o[5] for o in obs]) if obs else np.zeros(0, dtype=np.int8),
        **robot_arrays(window.robot_factors, local),
    )
    return with_fixes(graph, *fix_arrays(window.fixes, local)), local


def fix_arrays(
    fixes: dict[int, tuple[Array, Array, Array]], local: dict[int, int]
) -> tuple[Index, Array, Array, Array]:
    """The fixes of the poses in ``local`` as (local pose (f,), mean (f, 3), offset (f, 2), square-root information
    (f, 3, 3))."""
    held = [g for g in fixes if g in local]
    if not held:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3, 3))
    pose = np.concatenate([np.full(len(fixes[g][0]), local[g], dtype=np.int64) for g in held])
    mean, offset, W = (np.concatenate([fixes[g][k] for g in held]) for k in range(3))
    return pose, mean, offset, W


def robot_arrays(factors: list[tuple[int, int, Array, Array, int]], local: dict[int, int]) -> dict[str, NDArray[Any]]:
    """Robot sightings as the robot-sighting arrays of a :class:`FactorGraph` over local pose indices ({} when
    there are none)."""
    if not factors:
        return {}
    return {
        "rob_from": np.array([local[f[0]] for f in factors], dtype=np.int64),
        "rob_to": np.array([local[f[1]] for f in factors], dtype=np.int64),
        "rob_z": np.array([f[2] for f in factors]),
        "rob_sqrt_info": np.array([f[3] for f in factors]),
    }


def system(window: Window, prior: Prior | None, active: Index, fej: bool = False) -> System:
    """The window's factor graph, its layout, the reduced prior (and passive recovery), the window poses.

    ``fej``: the Jacobians of the variables the prior holds are taken at its linearization point
    (:func:`first_estimates`).
    """
    graph, local = window_graph(window, active)
    graph = with_map_factors(graph, window, prior, active)
    sparse = layout(graph, entries=False)
    quadratic, recover, point = None, None, None
    held = np.zeros(0, dtype=np.int64)
    if prior is not None:
        held = np.array([local[g] for g in prior.poses], dtype=np.int64)
        quadratic, recover = reduced(prior, active, sparse.pose_column[held], sparse.landmark_column)
        if fej:
            point = first_estimates(prior, held, active)
    return System(graph, sparse, quadratic, recover, window.values(), held, point)


def with_map_factors(graph: FactorGraph, window: Window, prior: Prior | None, active: Index) -> FactorGraph:
    """The window's graph with the map's priors on the active landmarks the marginal prior does not hold (it holds
    the others' with their sightings), over the active landmarks' local order."""
    rows = active[active < window.map_size]
    if prior is not None:
        rows = rows[~np.isin(rows, prior.landmarks)]
    joint = sqrt_information(joint_of(window.map_joint, rows)) if len(window.map_joint) and len(rows) else None
    return replace(
        graph,
        lp_landmark=np.searchsorted(active, rows).astype(np.int64),
        lp_mean=window.map_xy[rows],
        lp_sqrt_info=sqrt_information(window.map_cov[rows]) if len(rows) else np.zeros((0, 2, 2)),
        lp_joint=np.zeros((0, 0)) if joint is None else joint,
    )


def first_estimates(prior: Prior, held: Index, active: Index) -> JacobianPoint:
    """Where the window's factors take the Jacobians of the prior's variables: its linearization point.

    The prior's information was built with those Jacobians; taking the window's at the same point gives each
    variable one linearization, so the window and the prior cannot together gain information along directions
    no sighting observes (Dong-Si & Mourikis, ICRA 2011). ``held``: the local index of each pose the prior holds,
    in its order; ``active``: the window's landmarks (sorted).
    """
    count = len(prior.landmarks)
    inside = np.isin(prior.landmarks, active)
    return JacobianPoint(
        held,
        prior.x_lin[2 * count :].reshape(-1, 3),
        np.searchsorted(active, prior.landmarks[inside]),
        prior.x_lin[: 2 * count].reshape(-1, 2)[inside],
    )


def solve_window(
    window: Window,
    prior: Prior | None,
    active: Index,
    solver: SolverConfig,
    loss: RobustLoss | None,
    fej: bool = False,
) -> tuple[System, SolveResult]:
    """The window's system over the ``active`` landmarks, solved from the current estimate (with its
    information at the solution); ``fej`` as in :func:`system`."""
    s = system(window, prior, active, fej)
    result = solve(
        s.graph,
        s.poses,
        window.landmarks[active],
        solver,
        loss=loss,
        prior=s.quadratic,
        return_information=True,
        graph_layout=s.layout,
        jacobian_point=s.jacobian_point,
    )
    return s, result


def linearize(window: Window, prior: Prior | None, loss: RobustLoss | None, fej: bool = False) -> Linearized:
    """The window and the reduced prior linearized once at the current estimate (no iteration); ``fej`` as in
    :func:`system`."""
    observed = active(window)
    s = system(window, prior, observed, fej)
    linearized = solve(
        s.graph,
        s.poses,
        window.landmarks[observed],
        SolverConfig(max_iterations=0),
        loss=loss,
        prior=s.quadratic,
        return_information=True,
        graph_layout=s.layout,
        dense=True,
        jacobian_point=s.jacobian_point,
    )
    H = None if linearized.information is None else np.asarray(linearized.information)
    return Linearized(observed, s.layout, s.quadratic, H, len(window.indices))


def judge(window: Window, pose: int, bound: float) -> NDArray[np.bool_]:
    """Which sightings of a window pose are outliers at the current estimate (chi-square ``bound``; none when
    it is infinite)."""
    indices, z, _, W, model = window.observations[pose]
    if not np.isfinite(bound):
        return np.zeros(len(indices), dtype=bool)
    return sighting_chi2(window.poses[pose][None, :], window.landmarks[indices], z, W, model) > bound


def consensus(
    graph: FactorGraph,
    active: Index,
    poses: Array,
    landmarks: Array,
    held: Index,
    bound: float,
    outside: Callable[[int], int] | None = None,
) -> tuple[list[tuple[int, Array]], list[int]]:
    """Landmarks whose window sightings agree with each other but not with them, and where they go.

    Only landmarks with a sighting beyond the rejection ``bound`` are examined (none, usually). A landmark
    with three or more window sightings whose positions (from the solved poses) cluster away from its
    estimate — further than three times their median spread from their coordinate-wise median, with at least
    three of them agreeing with that median within ``bound`` — was placed by a wrong association (its first
    sighting, or one folded into the prior long ago): a landmark only the window knows moves to that median;
    one the marginal prior holds (``held``) moves when two thirds of its sightings are outliers, and is to be
    released from the prior.

    Args:
        graph: The solved window graph (:func:`window_graph`).
        active: The landmarks it solved (sorted), shape (A,).
        poses: The solved window poses, shape (P, 3).
        landmarks: Every landmark's estimate, shape (M, 2).
        held: The landmarks the prior holds.
        bound: The rejection bound on a sighting's squared whitened residual.
        outside: Sightings of landmark j outside the window (folded into the prior), or None: many. A cluster
            moves a landmark when it has three sightings, or when it outnumbers every sighting that supports the
            landmark where it is (those outside the window and the window's that agree with it), at least two:
            a landmark placed by one wrong-id sighting moves as soon as two true ones agree (issue 50).

    Returns:
        ((landmark, new position (2,)) for each landmark to move, the moved landmarks the prior holds).
    """
    outlying = observation_chi2(graph, poses, landmarks[active]) > bound
    if not outlying.any():
        return [], []
    ids = active[graph.obs_landmark]
    moves, stale = [], []
    examined = np.unique(ids[outlying])
    for j, in_prior in zip(examined, np.isin(examined, held).tolist()):
        mine = ids == j
        if np.count_nonzero(mine) < 2:  # fewer than any cluster needs
            continue
        supporters = int(np.count_nonzero(~outlying[mine])) + (3 if outside is None else outside(int(j)))
        need = max(2, min(3, supporters + 1))
        if mine.sum() < need or (in_prior and outlying[mine].mean() < 2.0 / 3.0):
            continue
        seen_from, z, model = poses[graph.obs_pose[mine]], graph.obs_z[mine], graph.obs_model[mine]
        points = landmark_from_sighting(seen_from, z, model)
        median = np.median(points, axis=0)
        spread = np.median(np.linalg.norm(points - median, axis=1))
        at_median = sighting_chi2(seen_from, np.broadcast_to(median, points.shape), z, graph.obs_sqrt_info[mine], model)
        if np.count_nonzero(at_median <= bound) < need:
            continue
        if np.linalg.norm(landmarks[j] - median) > 3.0 * spread + 1e-9:
            moves.append((int(j), median))
            if in_prior:
                stale.append(int(j))
    return moves, stale


def sightings_outside(log: ProblemLog, window: Window) -> Callable[[int], int]:
    """Sightings of window landmark j at poses older than the window (one robot), counted over the log once, when
    first asked."""
    counts: list[Index] = []

    def outside(j: int) -> int:
        if not counts:
            pose, landmark = log.sightings()[:2]
            older = landmark[(pose < window.indices[0]) & (landmark >= 0)]
            counts.append(np.bincount(older, minlength=len(log.landmark_ids)))
        (k,) = log.landmark_indices([window.landmark_ids[j]])
        return int(counts[0][k]) if k >= 0 else 0

    return outside
