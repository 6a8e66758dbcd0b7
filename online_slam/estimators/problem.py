"""Accumulates steps into the arrays of a factor graph, with odometry-composed initial values.

With several robots each robot's poses form their own odometry chain from their own start (poses indexed over
all robots in step order), and a sighting of a robot links the sighting pose to the seen robot's newest pose
at the step's time (:class:`RobotSightings`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.checkpoint import Checkpointed
from online_slam.estimators.protocol import Snapshot
from online_slam.factors.fixes import fix_gate_ratio, with_fixes, without_fixes
from online_slam.factors.graph import FactorGraph, robot_sighting_chi2, sqrt_information, without_robot_sightings
from online_slam.frontend.steps import Step
from online_slam.geometry.se2 import compose
from online_slam.models.fix import fix_factors
from online_slam.models.observation import landmark_from_sighting, tags
from online_slam.solvers.config import SolverConfig
from online_slam.solvers.pairing import Pairing, Sightings, repair
from online_slam.sources.events import LandmarkId, RobotId
from online_slam.sources.landmark_map import FIXED_STD, LandmarkMap, joint_of

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def _concat(chunks: list[np.ndarray], shape: tuple[int, ...], dtype: type) -> np.ndarray:
    return np.concatenate(chunks) if chunks else np.zeros((0, *shape), dtype=dtype)


def _extended(cached: tuple[np.ndarray, ...], new: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """Cached concatenations with the arrays of the chunks added since appended (``new`` when nothing cached)."""
    return tuple(np.concatenate([a, b]) for a, b in zip(cached, new)) if cached else new


@dataclass(eq=False)
class RobotSightings:
    """Sightings of robots by robots, each linking its step's pose to the seen robot's newest pose at the step's
    time. That pose may begin after the step (another robot's pose of the same time comes later in step order):
    a sighting stays open while poses of its time may still come."""

    pose: list[int] = field(default_factory=list)
    """The sighting pose of each."""
    robot: list[RobotId] = field(default_factory=list)
    """The seen robot of each."""
    seen_pose: list[int] = field(default_factory=list)
    """The seen robot's newest pose at the sighting step's time (-1: none, so far)."""
    t: list[float] = field(default_factory=list)
    """The sighting step's time."""
    z: list[Array] = field(default_factory=list)
    """Range and bearing, each shape (2,)."""
    cov: list[Array] = field(default_factory=list)
    """Their covariances, each shape (2, 2)."""
    open: list[int] = field(default_factory=list)
    """Sightings of the newest step time (the seen robot may still get a pose of that time)."""

    def add(self, step: Step, newest: dict[RobotId | None, int]) -> None:
        """Take a new step (``newest``: each robot's newest pose, this step's included): it may be the pose an
        open sighting sees; then record its own sightings."""
        if self.open and self.t[self.open[0]] < step.t:
            self.open = []
        for k in self.open:
            if self.robot[k] == step.robot:
                self.seen_pose[k] = step.index
        for robot, z, cov in zip(step.robots_seen, step.z_robots, step.z_robots_cov):
            self.open.append(len(self.pose))
            self.pose.append(step.index)
            self.robot.append(robot)
            self.seen_pose.append(newest.get(robot, -1))
            self.t.append(step.t)
            self.z.append(z)
            self.cov.append(cov)

    def frozen(self) -> RobotSightings:
        """A copy that later steps do not change (the lists are copied; their arrays are never modified)."""
        return replace(self, **{f.name: list(getattr(self, f.name)) for f in fields(self)})

    def linked(self) -> NDArray[np.bool_]:
        """Which sightings link two poses (the seen robot had a pose at the step's time), shape (R,)."""
        return np.array(self.seen_pose, dtype=np.int64) >= 0

    def factors(self) -> dict[str, NDArray[Any]]:
        """The linked sightings as the robot-sighting arrays of a :class:`FactorGraph` ({} when there are none)."""
        linked = np.flatnonzero(self.linked())
        if not len(linked):
            return {}
        cov = np.array(self.cov)[linked]
        return {
            "rob_from": np.array(self.pose, dtype=np.int64)[linked],
            "rob_to": np.array(self.seen_pose, dtype=np.int64)[linked],
            "rob_z": np.array(self.z, dtype=float)[linked],
            "rob_sqrt_info": sqrt_information(cov),
        }


@dataclass(eq=False)
class ProblemLog(Checkpointed):
    """Every factor seen so far, plus initial values: poses by composed odometry, landmarks by first sight.

    Every field set by ``__init__`` is state a checkpoint keeps (:meth:`state_dict`, :meth:`load_state`); the
    others are derived from them.
    """

    keep_factors: bool = True
    """False: keep initial values only (dead reckoning needs no factor), so memory grows with the path alone."""
    use_ids: bool = True
    """False: the stream's ids are not used (association decides later); every sighting is kept unpaired."""
    poses: list[Array] = field(default_factory=list)
    """Initial pose values in step order, each shape (3,)."""
    landmark_ids: tuple[LandmarkId, ...] = ()
    """Landmark ids in order of first observation."""
    _landmarks: list[Array] = field(default_factory=list)
    """Initial landmark values (from their first sight), each shape (2,)."""
    prior: tuple[Array, Array | None] | None = None
    """The start pose and its covariance (None: held fixed), once step 0 arrived."""
    robots: list[RobotId | None] = field(default_factory=list)
    """The robot of each pose, in step order."""
    starts: dict[int, tuple[Array, Array | None]] = field(default_factory=dict)
    """The start pose and covariance of every robot after the first, by its first pose's index."""
    seen: RobotSightings = field(default_factory=lambda: RobotSightings())
    """Sightings of robots by robots."""
    _odo_delta: list[Array] = field(default_factory=list)
    """Odometry increments, each shape (3,)."""
    _odo_cov: list[Array] = field(default_factory=list)
    """Their covariances, each shape (3, 3)."""
    _obs_pose: list[NDArray[np.int64]] = field(default_factory=list)
    """Sightings in chunks (one per call): the pose of each, shape (k,)."""
    _obs_landmark: list[NDArray[np.int64]] = field(default_factory=list)
    """The landmark index of each (-1: without id), shape (k,)."""
    _obs_z: list[Array] = field(default_factory=list)
    """The measurements ``[range, bearing]`` or ``[dx, dy]``, shape (k, 2)."""
    _obs_cov: list[Array] = field(default_factory=list)
    """Their covariances, shape (k, 2, 2)."""
    _obs_model: list[NDArray[np.int8]] = field(default_factory=list)
    """Their model tags, shape (k,)."""
    map_size: int = 0
    """The first ``map_size`` landmarks are a map's (``--map``): each has a prior factor."""
    map_xy: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """The map's positions, shape (map_size, 2)."""
    map_cov: Array = field(default_factory=lambda: np.zeros((0, 2, 2)))
    """Their prior covariances, shape (map_size, 2, 2) (a fixed map's: :data:`FIXED_STD` squared)."""
    map_joint: Array = field(default_factory=lambda: np.zeros((0, 0)))
    """The map's joint covariance, shape (2 map_size, 2 map_size), when it has one (empty: independent)."""
    fixes: dict[int, tuple[Array, Array, Array]] = field(default_factory=dict)
    """Absolute fixes of each pose that has some: (mean (f, 3), offset (f, 2), square-root information (f, 3, 3)),
    as :func:`~online_slam.models.fix.fix_factors` gives them."""
    fix_widening: dict[int, Array] = field(default_factory=dict)
    """How much each of them was widened for correlation in time (shape (f,); the gates judge by their own)."""
    _landmark_index: dict[LandmarkId, int] = field(init=False)
    """Index of each landmark id in ``landmark_ids``."""
    _cached_obs: int = field(init=False)
    """Observation chunks the concatenations cover."""
    _cat_obs: tuple[NDArray[Any], ...] = field(init=False)
    """Concatenated observation arrays (see :meth:`_observation_arrays`)."""
    _cached_odo: int = field(init=False)
    """Odometry entries the concatenations cover."""
    _cat_odo: tuple[Array, ...] = field(init=False)
    """Concatenated odometry arrays (see :meth:`_odometry_arrays`)."""
    _newest: dict[RobotId | None, int] = field(init=False)
    """Index of each robot's newest pose."""

    def __post_init__(self) -> None:
        self._landmark_index = {lid: k for k, lid in enumerate(self.landmark_ids)}
        self._newest = {robot: k for k, robot in enumerate(self.robots)}
        self._reset_cache()

    def _reset_cache(self) -> None:
        """Forget the concatenated factor arrays (rebuilt on demand)."""
        # The chunk lists only grow and their arrays never change, so the concatenations (and the square-root
        # information, computed per matrix) are extended with the chunks added since, never recomputed.
        self._cached_obs, self._cat_obs = 0, ()
        self._cached_odo, self._cat_odo = 0, ()

    def _observation_arrays(self) -> tuple[NDArray[Any], ...]:
        """Every sighting's pose, landmark index, z, covariance, square-root information and model tag, concatenated."""
        n = len(self._obs_pose)
        if not self._cat_obs or self._cached_obs < n:
            new = slice(self._cached_obs, n)
            cov = _concat(self._obs_cov[new], (2, 2), float)
            parts = (
                _concat(self._obs_pose[new], (), np.int64).astype(np.int64),
                _concat(self._obs_landmark[new], (), np.int64).astype(np.int64),
                _concat(self._obs_z[new], (2,), float),
                cov,
                sqrt_information(cov) if len(cov) else np.zeros((0, 2, 2)),
                _concat(self._obs_model[new], (), np.int8),
            )
            self._cat_obs, self._cached_obs = _extended(self._cat_obs, parts), n
        return self._cat_obs

    def _odometry_arrays(self) -> tuple[Array, ...]:
        """Every odometry increment and its square-root information, shapes (K, 3) and (K, 3, 3)."""
        n = len(self._odo_delta)
        if not self._cat_odo or self._cached_odo < n:
            new = slice(self._cached_odo, n)
            cov = np.array(self._odo_cov[new], dtype=float).reshape(-1, 3, 3)
            parts = (
                np.array(self._odo_delta[new], dtype=float).reshape(-1, 3),
                sqrt_information(cov) if len(cov) else np.zeros((0, 3, 3)),
            )
            self._cat_odo, self._cached_odo = _extended(self._cat_odo, parts), n
        return self._cat_odo

    @property
    def landmarks(self) -> Array:
        """Initial landmark values, shape (M, 2)."""
        return np.array(self._landmarks).reshape(-1, 2)

    def load_map(self, landmark_map: LandmarkMap, fixed: bool = False) -> None:
        """Start from a map (before the first step): its landmarks come first, at their positions, each with a prior
        factor of its covariance (at least :data:`FIXED_STD` squared; exactly that with ``fixed``)."""
        if self.poses or self.landmark_ids:
            raise ValueError("a map is loaded before the first step")
        floor = FIXED_STD**2 * np.eye(2)
        self.landmark_ids = tuple(landmark_map.ids)
        self._landmark_index = {lid: k for k, lid in enumerate(self.landmark_ids)}
        self._landmarks = list(landmark_map.xy.copy())
        self.map_size, self.map_xy = len(landmark_map), landmark_map.xy.copy()
        self.map_cov = np.broadcast_to(floor, landmark_map.cov.shape).copy() if fixed else landmark_map.cov + floor
        if landmark_map.joint is not None and not fixed:
            self.map_joint = landmark_map.joint + FIXED_STD**2 * np.eye(2 * len(landmark_map))

    def map_priors(self, ids: Sequence[LandmarkId] | None = None) -> dict[str, Any]:
        """The map's prior factors (keyword arguments of a graph) on the landmarks ``ids`` index (default: this
        log's landmarks); none without a map."""
        if not self.map_size:
            return {}
        where = {lid: k for k, lid in enumerate(self.landmark_ids[: self.map_size])}
        pairs = [(j, where[lid]) for j, lid in enumerate(self.landmark_ids if ids is None else ids) if lid in where]
        rows = np.array([j for j, _ in pairs], dtype=np.int64)
        of = np.array([k for _, k in pairs], dtype=np.int64)
        priors = {"lp_landmark": rows, "lp_mean": self.map_xy[of], "lp_sqrt_info": sqrt_information(self.map_cov[of])}
        if len(self.map_joint) and len(of):
            priors["lp_joint"] = sqrt_information(joint_of(self.map_joint, of))
        return priors

    def landmark_indices(self, ids: Sequence[LandmarkId | None]) -> NDArray[np.int64]:
        """Indices of known landmarks (-1 for unknown ids, and for None)."""
        return np.array([self._landmark_index.get(i, -1) if i is not None else -1 for i in ids], dtype=np.int64)

    def add(self, step: Step) -> Array:
        """Record a step; return its initial pose value, shape (3,)."""
        if step.index != len(self.poses):
            raise ValueError(f"steps must arrive in order: expected {len(self.poses)}, got {step.index}")
        if step.odometry is None:
            assert step.prior is not None
            pose = np.array(step.prior, dtype=float)
            if self.poses:  # another robot begins
                self.starts[step.index] = (pose, step.prior_cov)
            else:
                self.prior = (pose, step.prior_cov)
        else:
            pose = compose(self.poses[self._newest.get(step.robot, -1)], step.odometry)
            if self.keep_factors:
                self._odo_delta.append(step.odometry)
                self._odo_cov.append(cast(Array, step.odometry_cov))  # a step with odometry has its covariance
        self.poses.append(pose)
        self.robots.append(step.robot)
        self._newest[step.robot] = step.index
        self.seen.add(step, self._newest)  # also without factors: the smoother's window reads the pairing
        self.extend(step, 0)
        return pose

    def extend(self, step: Step, start: int) -> None:
        """Record the newest step's observations ``start:`` (new landmarks placed from their first sight) and all
        its fixes."""
        if step.index != len(self.poses) - 1:
            raise ValueError(f"only the newest step can grow: {len(self.poses) - 1}, not {step.index}")
        if step.fixes and self.keep_factors:
            self.fixes[step.index] = fix_factors(step.fixes)
            self.fix_widening[step.index] = np.array([fix.widened for fix in step.fixes])
        ids_now = step.landmarks[start:]
        if not ids_now:
            return
        pose = self.poses[-1]
        ids = list(self.landmark_ids)
        if not self.use_ids:
            ids_now = (None,) * len(ids_now)
        for lid, z, model in zip(ids_now, step.z[start:], step.z_model[start:]):
            if lid is not None and lid not in self._landmark_index:
                self._landmark_index[lid] = len(ids)
                ids.append(lid)
                self._landmarks.append(landmark_from_sighting(pose, z, model))
        if len(ids) != len(self.landmark_ids):
            self.landmark_ids = tuple(ids)
        if not self.keep_factors:
            return
        self._obs_pose.append(np.full(len(ids_now), step.index))
        self._obs_landmark.append(self.landmark_indices(ids_now))
        self._obs_z.append(step.z[start:])
        self._obs_cov.append(step.z_cov[start:])
        self._obs_model.append(step.z_model[start:])

    def add_sightings(self, pose: int, ids: tuple[LandmarkId, ...], z: Array, cov: Array, model: Any) -> None:
        """Record sightings of known landmarks taken at an earlier pose (graphs order sightings by pose); ``model``
        tags them all, or each (k,)."""
        if not self.keep_factors:
            return
        self._obs_pose.append(np.full(len(ids), pose))
        self._obs_landmark.append(self.landmark_indices(ids))
        self._obs_z.append(np.asarray(z, dtype=float))
        self._obs_cov.append(np.asarray(cov, dtype=float))
        self._obs_model.append(tags(model, len(ids)))

    def __deepcopy__(self, memo: dict[int, Any]) -> ProblemLog:
        """A copy (:meth:`frozen`): its arrays are shared, which no one changes in place."""
        return self.frozen()

    def frozen(self) -> ProblemLog:
        """A copy that later steps do not change (the lists are copied; their arrays are never modified)."""
        values = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        lists: dict[str, Any] = {name: list(v) for name, v in values.items() if isinstance(v, list)}
        copy = replace(self, **lists, starts=dict(self.starts), seen=self.seen.frozen(), fixes=dict(self.fixes),
                       fix_widening=dict(self.fix_widening))  # fmt: skip
        copy._cached_obs, copy._cat_obs = self._cached_obs, self._cat_obs
        copy._cached_odo, copy._cat_odo = self._cached_odo, self._cat_odo
        return copy

    def sightings(self) -> tuple[NDArray[np.int64], NDArray[np.int64], Array, Array, NDArray[np.int8]]:
        """Every sighting recorded, in order: (pose, landmark index or -1 without id, z (k, 2), cov (k, 2, 2),
        model tag (k,))."""
        pose, landmark, z, cov, _, model = self._observation_arrays()
        return pose, landmark, z, cov, model

    def pair_again(
        self, poses: Array, landmarks: Array, bound: float, solver: SolverConfig, only: Index | None = None
    ) -> Pairing | None:
        """Every sighting recorded (``only``: these rows, (k,)) paired again from an estimate
        (:func:`~online_slam.solvers.pairing.repair`), in the order recorded; robot sightings and fixes far off the
        estimate (outliers, as it judged them) left out. None without factors, sightings or landmarks."""
        pose, _, z, _, sqrt_info, model = self._observation_arrays()
        if not self.keep_factors or not len(pose) or not len(landmarks):
            return None
        rows = np.arange(len(pose)) if only is None else only
        base = self.graph(labels=np.full(len(pose), -1, dtype=np.int64), n_landmarks=0, ids=())
        base = without_fixes(base, fix_gate_ratio(base, poses, self.fix_widenings()) > 1.0)  # as judged at the start
        base = without_robot_sightings(base, robot_sighting_chi2(base, poses) > bound)
        sightings = Sightings(pose[rows], z[rows], sqrt_info[rows], model[rows])
        return repair(base, sightings, poses, landmarks, bound, solver)

    def graph(
        self,
        labels: NDArray[np.int64] | None = None,
        n_landmarks: int | None = None,
        ids: Sequence[LandmarkId] | None = None,
    ) -> FactorGraph:
        """All factors recorded so far as one graph (start pose fixed, or a prior on it; the map's priors).

        Args:
            labels: Landmark index of every sighting (-1: left out) instead of the logged ids' indices.
            n_landmarks: Landmarks the labels index (with ``labels``).
            ids: The ids of the landmarks the labels index (with ``labels``; for the map's priors).
        """
        if not self.keep_factors:
            raise ValueError("this log keeps no factors")
        n = len(self.poses)
        fixed, prior_args = self._priors()
        obs_pose, obs_landmark, obs_z, _, obs_sqrt, obs_model = self._observation_arrays()
        odo_delta, odo_sqrt = self._odometry_arrays()
        if labels is not None:
            obs_landmark = np.asarray(labels, dtype=np.int64)
        used: NDArray[Any] = obs_landmark >= 0  # a mask, or the sightings' indices in pose order
        if len(obs_pose) > 1 and np.any(np.diff(obs_pose) < 0):  # sightings added at earlier poses: pose order
            used = np.flatnonzero(used)
            used = used[np.argsort(obs_pose[used], kind="stable")]
        base = FactorGraph.build(
            n, len(self.landmark_ids) if n_landmarks is None else n_landmarks, fixed_poses=fixed, **prior_args
        )
        odo_from, odo_to = self._chains()
        robot_factors: dict[str, Any] = self.seen.factors()
        graph = replace(
            base,
            odo_from=odo_from,
            odo_to=odo_to,
            odo_delta=odo_delta,
            odo_sqrt_info=odo_sqrt,
            obs_pose=obs_pose[used],
            obs_landmark=obs_landmark[used],
            obs_z=obs_z[used],
            obs_sqrt_info=obs_sqrt[used],
            obs_model=obs_model[used],
            **robot_factors,
            **self.map_priors(ids if labels is not None else None),
        )
        return with_fixes(graph, *self.fix_arrays())

    def fix_arrays(self) -> tuple[Index, Array, Array, Array]:
        """Every fix recorded, in pose order: (pose (f,), mean (f, 3), offset (f, 2), square-root information
        (f, 3, 3))."""
        poses = sorted(self.fixes)
        parts = [self.fixes[g] for g in poses]
        counts = [len(p[0]) for p in parts]
        if not parts:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3, 3))
        pose = np.repeat(np.array(poses, dtype=np.int64), counts)
        mean, offset, W = (np.concatenate([p[k] for p in parts]) for k in range(3))
        return pose, mean, offset, W

    def fix_widenings(self) -> Array:
        """Each fix's widening for correlation in time, in :meth:`fix_arrays` order, shape (f,)."""
        parts = [self.fix_widening.get(g, np.ones(len(self.fixes[g][0]))) for g in sorted(self.fixes)]
        return np.concatenate(parts) if parts else np.zeros(0)

    def _priors(self) -> tuple[list[int], dict[str, Any]]:
        """The start poses held fixed, and the prior factors of the others (keyword arguments of the graph)."""
        starts = ({} if self.prior is None else {0: self.prior}) | self.starts
        fixed = [i for i, (_, cov) in starts.items() if cov is None]
        free = [(i, mean, cov) for i, (mean, cov) in starts.items() if cov is not None]
        if not free:
            return fixed, {}
        return fixed, {
            "prior_pose": [i for i, _, _ in free],
            "prior_mean": np.array([mean for _, mean, _ in free]),
            "prior_cov": np.array([cov for _, _, cov in free]),
        }

    def _chains(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(earlier, later) pose of every odometry factor, in the order the increments came."""
        n = len(self.poses)
        if not self.starts:  # one robot: one chain
            return np.arange(n - 1, dtype=np.int64), np.arange(1, n, dtype=np.int64)
        newest: dict[RobotId | None, int] = {}
        pairs = []
        for k, robot in enumerate(self.robots):
            if k not in self.starts and k > 0:
                pairs.append((newest[robot], k))
            newest[robot] = k
        return cast(  # the two columns of the pairs
            "tuple[NDArray[np.int64], NDArray[np.int64]]",
            tuple(np.array(c, dtype=np.int64).reshape(-1) for c in zip(*pairs))
            if pairs
            else (np.zeros(0, np.int64),) * 2,
        )


class LoggedEstimator:
    """Protocol plumbing of an estimator whose state is a :class:`ProblemLog` (dead reckoning, batch).

    Its snapshots report the log's initial values: the newest composed pose, landmarks from their first sight.
    """

    name = "logged"
    several_robots = True
    log: ProblemLog

    def step(self, step: Step) -> Snapshot:
        """Record the step; report the newest pose's initial value."""
        self.log.add(step)
        return self.snapshot(step)

    def extend(self, step: Step, start: int) -> Snapshot:
        """More sightings of the newest pose: record them (new landmarks placed); the pose does not move."""
        self.log.extend(step, start)
        return self.snapshot(step)

    def snapshot(self, step: Step) -> Snapshot:
        """The newest pose's value and the landmarks placed so far."""
        pose = self.log.poses[-1]
        return Snapshot(self.name, step.index, step.t, pose, None, self.log.landmark_ids, self.log.landmarks)

    def trajectory(self) -> Array:
        """The composed trajectory so far (the initial values), shape (N, 3)."""
        return np.array(self.log.poses).reshape(-1, 3)

    def state_dict(self) -> Any:
        """Everything recorded: the log's state tree."""
        return self.log.state_dict()

    def load_state(self, state: Any) -> None:
        """Restore a :meth:`state_dict`."""
        self.log.load_state(state)
