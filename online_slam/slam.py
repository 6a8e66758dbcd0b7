"""``online_slam.Slam``: the engine as a library — push odometry and sightings, read the estimate at once.

Each ``add_*`` call (and :meth:`Slam.add`, which takes stream-v1 event objects or their ``dict`` records) is
validated by the same rules as a stream-v1 line (one of sigma/cov, range and bearing or a position ``xy``, finite
numbers, range > 0, bearings in radians, non-decreasing time, ``start`` first); bad input raises
:class:`~online_slam.errors.InputError` naming the field and changes nothing. A sighting at time ``t`` belongs
to the newest pose with time <= ``t``. :meth:`Slam.estimate` reflects every event added so far: sightings of
the newest pose are used before its successor's odometry arrives (see :mod:`online_slam.engine` for how, and why
a replay gives the same numbers).

Several robots share one map when every event names its ``robot`` (``start`` each robot first, then
``add_odometry(..., robot=...)``, ``add_observation(..., robot=...)`` and :meth:`Slam.add_robot_observation` for
a sighting of another robot), as on a stream of several robots. Their poses reach the estimator in the order
they began (one index over all robots): a pose waits until the earlier poses of the other robots are complete
(their robots moved on); a query shows the oldest waiting pose at once. :attr:`SlamEstimate.robots` gives each
robot's newest pose, its covariance and its trajectory. The EKF and the smoother take several robots (an
estimator that does sets ``several_robots`` and gives each robot's newest pose by ``robot_poses()``).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import sys
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import FrameType, MappingProxyType
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.checkpoint import read_checkpoint, write_checkpoint
from online_slam.engine import Engine, EngineCheckpoint
from online_slam.errors import ConfigError, InputError, LateInput, OnlineSlamError
from online_slam.estimators.ekf import EkfSlam
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.protocol import SlamEstimator, Snapshot
from online_slam.estimators.smoother import SlidingWindowSmoother, SmootherConfig
from online_slam.frontend.steps import TIME_TOLERANCE, FrontEndConfig, PendingStep, Step
from online_slam.models.motion import Increment, predict_pose
from online_slam.slam_config import ESTIMATORS, NOT_ONLINE, OPTIONS, configs, typed_configs
from online_slam.slam_estimate import (
    NewestPose,
    RobotEstimate,
    SlamEstimate,
    _read_only,
    empty_estimate,
)
from online_slam.sources.events import Event, LandmarkId, Observation, Odometry, RobotId, Start, Truth
from online_slam.sources.landmark_map import LandmarkMap, finite_joint, read_map, write_map
from online_slam.sources.validate import EventValidator, ValidatorState, plain

__all__ = [
    "ESTIMATORS",
    "NOT_ONLINE",
    "OPTIONS",
    "NewestPose",
    "RobotEstimate",
    "Slam",
    "SlamCheckpoint",
    "SlamEstimate",
]

Array = NDArray[np.float64]

_CHECKPOINT_KIND = "slam"


class Slam:
    """Online 2D landmark SLAM in a robot's loop: push events, query the estimate.

    Args:
        estimator: ``"smoother"`` (sliding-window least squares, default) or ``"ekf"``, in any case. The batch
            solver is no online estimator: run it with :func:`online_slam.replay`. With ``config``: taken from
            its type when not given.
        config: The estimator's whole configuration (:class:`~online_slam.estimators.ekf_config.EkfConfig` or
            :class:`~online_slam.estimators.smoother.SmootherConfig`): every field, flags or not.
        frontend: The front-end's (:class:`~online_slam.frontend.steps.FrontEndConfig`: keyframes, noise scales).
        map: Start from this map (a :class:`~online_slam.sources.landmark_map.LandmarkMap` or a map file): its
            landmarks as priors with their covariances; the first pose (``start``) must be in the map's frame.
        map_fixed: The map's landmarks are known (held), not priors.
        **options: Or settings named as the CLI's flags (see :data:`OPTIONS`), e.g. ``window=50``,
            ``robust="cauchy"``, ``gate_probability=0.999`` (not with ``config`` or ``frontend``).

    Raises:
        ConfigError: Unknown estimator or option, or a value out of range.

    Example:
        >>> slam = Slam("ekf")
        >>> slam.add_observation(0.0, landmark=7, range=2.0, bearing=0.5, sigma=[0.1, 0.01])
        >>> slam.add_odometry(1.0, delta=[1.0, 0.0, 0.0], sigma=[0.05, 0.05, 0.01])
        >>> slam.estimate().index
        1
    """

    def __init__(
        self,
        estimator: str | None = None,
        *,
        config: EkfConfig | SmootherConfig | None = None,
        frontend: FrontEndConfig | None = None,
        map: LandmarkMap | str | Path | None = None,  # noqa: A002 - the option's name
        map_fixed: bool = False,
        **options: Any,
    ) -> None:
        self.typed: tuple[EkfConfig | SmootherConfig | None, FrontEndConfig | None] = (None, None)
        """The configurations given (``config``, ``frontend``), or (None, None) for options by name."""
        if config is None and frontend is None:
            name = "smoother" if estimator is None else estimator
            name = name.strip().lower() if isinstance(name, str) else name  # a non-string is refused by name
            config, frontend = configs(name, options)
        else:
            if options:
                raise ConfigError(f"Slam: give options by name ({', '.join(options)}) or configs, not both")
            name, config, frontend = typed_configs(estimator, config, frontend)
            self.typed = (config, frontend)
        self.estimator_name = name
        self.options: dict[str, Any] = dict(options)
        self._estimator: SlamEstimator = (
            EkfSlam(config) if isinstance(config, EkfConfig) else SlidingWindowSmoother(config)
        )
        self._loaded = map if isinstance(map, LandmarkMap) or map is None else read_map(map)
        if self._loaded is not None:
            self._estimator.load_map(self._loaded, map_fixed)
        self._engine = Engine([self._estimator], frontend, records=False)
        self._validator = EventValidator("Slam", max_latency=frontend.max_latency or 0.0)
        self._validator.latency_name = "max_latency"
        self.late: int = 0
        """Lines skipped as later than ``max_latency`` (a warning the first time; never an error)."""

    # -- events --------------------------------------------------------------------------------------
    def start(self, t: float, pose: Any, sigma: Any = None, cov: Any = None, robot: RobotId | None = None) -> None:
        """The first pose (optional: by default the origin at the first event's time, held fixed), or a robot's.

        Args:
            t: Time, seconds.
            pose: ``[x, y, theta]``.
            sigma: Standard deviations ``[sx, sy, stheta]`` of a prior on it, or None.
            cov: Full 3x3 prior covariance, or None. With neither, the start pose is held fixed.
            robot: The robot starting here (an int or a non-empty string), once per robot and before any other
                event names it; None: the one unnamed robot.

        Raises:
            OnlineSlamError: A second robot for an estimator that takes one robot (nothing changes).
        """
        self._push("start", {"type": "start", "t": t, "pose": pose}, sigma, cov, robot)

    def add_odometry(
        self, t: float, delta: Any, sigma: Any = None, cov: Any = None, robot: RobotId | None = None
    ) -> None:
        """Motion since the previous pose (of ``robot``), in its frame; makes a new pose at ``t``.

        Args:
            t: Time of the new pose, seconds (never before the previous event).
            delta: ``[dx, dy, dtheta]``.
            sigma: Standard deviations ``[sx, sy, stheta]``, or None when ``cov`` is given.
            cov: Full 3x3 covariance, or None when ``sigma`` is given.
            robot: The robot that moved (required once robots are named), or None.
        """
        if robot is not None:
            self._push("add_odometry", {"type": "odometry", "t": t, "delta": delta}, sigma, cov, robot)
            return
        self._validator.name = "Slam.add_odometry"
        try:
            odometry = self._validator.parse_odometry(plain(t), plain(delta), plain(sigma), plain(cov))
        except LateInput as exc:
            self._skip_late(exc)
            return
        self._engine.push(odometry)

    def add_observation(
        self,
        t: float,
        landmark: LandmarkId | None,
        range: float | None = None,
        bearing: float | None = None,
        sigma: Any = None,
        cov: Any = None,
        xy: Any = None,
        robot: RobotId | None = None,
        sensor: str | None = None,
    ) -> None:
        """A sighting of a landmark, range and bearing or its position ``xy`` in the robot frame; it attaches to the
        newest pose (of ``robot``) with time <= ``t`` (a pose at ``t`` once the odometry spanning ``t`` arrives).

        Args:
            t: Time, seconds (never before the previous event).
            landmark: Landmark id (int or non-empty string; ``3`` and ``"3"`` differ), or None when unknown (the
                estimator associates it; with ``association="nn"``/``"jcbb"`` every id is ignored).
            range: Distance, metres (> 0); None with ``xy``.
            bearing: Angle from the heading, radians, within [-2 pi, 2 pi] (a larger one is refused as likely
                degrees); None with ``xy``.
            sigma: ``[s_range, s_bearing]`` (with ``xy``: ``[s_dx, s_dy]``), or None when ``cov`` is given.
            cov: Full 2x2 covariance, or None when ``sigma`` is given.
            xy: ``[dx, dy]``, the landmark in the robot frame (x ahead, y to the left), metres, instead of range and
                bearing.
            robot: The robot that took it (required once robots are named), or None.
            sensor: The sensor that took it (z in its frame): a name declared with :meth:`add` of a header record
            ``{"type": "header", "sensors": {name: {"pose": [x, y, theta]}}}`` first; None: the robot's centre.
        """
        record = {"type": "observation", "t": t, "landmark": landmark}
        measured = {"range": range, "bearing": bearing, "xy": xy, "sensor": sensor}
        record.update((key, value) for key, value in measured.items() if value is not None)
        self._push("add_observation", record, sigma, cov, robot)

    def add_robot_observation(
        self,
        t: float,
        robot_seen: RobotId,
        range: float,
        bearing: float,
        sigma: Any = None,
        cov: Any = None,
        robot: RobotId | None = None,
    ) -> None:
        """A sighting of another robot: range and bearing from ``robot``'s newest pose with time <= ``t`` to the
        position of ``robot_seen``'s newest pose with time <= ``t`` (a stream's ``robot_seen`` observation, checked
        by the same rules).

        Args:
            t: Time, seconds (never before the previous event).
            robot_seen: The robot sighted: a started robot other than ``robot``.
            range: Distance, metres (> 0).
            bearing: Angle from ``robot``'s heading, radians, within [-2 pi, 2 pi].
            sigma: ``[s_range, s_bearing]``, or None when ``cov`` is given.
            cov: Full 2x2 covariance, or None when ``sigma`` is given.
            robot: The robot that took it (required: robots are named once any is seen).

        Raises:
            InputError: As for a stream line (an unknown robot, a robot sighting itself, ...); also when the
                estimate of ``robot``'s pose was queried already (the estimator has that pose and no longer takes
                robot sightings of it: add them before querying). Nothing changes.
        """
        record = {"type": "observation", "t": t, "robot_seen": robot_seen, "range": range, "bearing": bearing}
        self._push("add_robot_observation", record, sigma, cov, robot)

    def add_observations(
        self,
        t: float,
        landmarks: Any,
        ranges: Any = None,
        bearings: Any = None,
        sigma: Any = None,
        cov: Any = None,
        xy: Any = None,
        sensor: str | None = None,
    ) -> None:
        """A scan: k sightings taken at one time, checked as a whole (all are added, or none); they attach to the
        newest pose with time <= ``t`` (a pose at ``t`` once the odometry spanning ``t`` arrives).

        Args:
            t: Time, seconds (never before the previous event).
            landmarks: k landmark ids (None for an unknown one), or None: all unknown.
            ranges: k distances, metres (> 0); None with ``xy``.
            bearings: k angles from the heading, radians, within [-2 pi, 2 pi]; None with ``xy``.
            sigma: Standard deviations of z shared by all (2,), or one per sighting (k, 2).
            cov: A 2x2 covariance shared by all, or one per sighting (k, 2, 2).
            xy: k positions ``[dx, dy]`` in the robot frame, shape (k, 2), instead of ranges and bearings.
            sensor: The sensor that took them (see :meth:`add_observation`), or None: the robot's centre.

        Raises:
            InputError: Naming the first bad sighting's field, e.g. ``range[3]``; nothing is added.
        """
        self._validator.name = "Slam.add_observations"
        measured = ranges if xy is None else xy
        if landmarks is None and isinstance(measured, (list, tuple, np.ndarray)):
            landmarks = [None] * len(measured)
        try:
            scan = self._validator.parse_scan(
                plain(t), plain(landmarks), plain(ranges), plain(bearings), plain(sigma), plain(cov), plain(xy), sensor
            )
        except LateInput as exc:
            self._skip_late(exc)
            return
        self._engine.push(scan)

    def add_position(
        self, t: float, xy: Any, sigma: Any = None, cov: Any = None, offset: Any = None, robot: RobotId | None = None
    ) -> None:
        """An absolute position fix (GPS): the robot-frame point ``offset`` is at ``xy`` in the map frame at ``t``;
        it belongs to the pose (of ``robot``) at ``t`` (one is made there, as for a sighting between poses).

        Args:
            t: Time, seconds (never before the previous event).
            xy: ``[x, y]`` of the fixed point in the map frame, metres.
            sigma: ``[sx, sy]``, or None when ``cov`` is given. cov: Full 2x2 covariance, or None.
            offset: ``[dx, dy]`` of the fixed point (an antenna) in the robot frame, or None: the robot's centre.
            robot: The robot fixed (required once robots are named), or None.
        """
        record = {"type": "position", "t": t, "xy": xy, **({"offset": offset} if offset is not None else {})}
        self._push("add_position", record, sigma, cov, robot)

    def add_heading(self, t: float, theta: float, sigma: float, robot: RobotId | None = None) -> None:
        """An absolute heading fix (a compass) of the pose (of ``robot``) at ``t``: ``theta`` in radians, within
        [-2 pi, 2 pi], with standard deviation ``sigma`` (radians)."""
        self._push("add_heading", {"type": "heading", "t": t, "theta": theta, "sigma": sigma}, None, None, robot)

    def add(self, event: Event | Mapping[str, Any]) -> None:
        """Add one stream-v1 event: an event object (e.g. from :func:`~online_slam.sources.stream.read_stream`)
        or its record, a ``dict`` as on a stream line (numpy arrays allowed for lists).

        An ``odometry`` event makes a new pose at its time; an ``observation`` attaches to the newest pose with
        time <= its ``t``; a ``start`` must come first. Truth events are kept apart for evaluation, as in a
        replay; no estimator sees them.

        Example:
            >>> slam = Slam("ekf")
            >>> slam.add({"type": "odometry", "t": 1.0, "delta": [1.0, 0.0, 0.0], "sigma": [0.05, 0.05, 0.01]})
            >>> slam.estimate().index
            1

        Raises:
            InputError: The record breaks a rule of the stream format (naming the field, e.g. ``delta``), or the
                item is neither an event nor a ``dict``; nothing changes.
        """
        if isinstance(event, Mapping):
            record = dict(event)
        elif callable(getattr(event, "to_record", None)):
            record = event.to_record()
        else:
            problem = f"expected an event or a stream-v1 record, got {type(event).__name__}"
            raise InputError("Slam.add", 0, "", problem)
        kind = record.get("type")
        self._push(f"add({kind})" if isinstance(kind, str) else "add", record, None, None)

    def _push(self, method: str, record: dict[str, Any], sigma: Any, cov: Any, robot: Any = None) -> None:
        record = {key: plain(value) for key, value in record.items()}
        if robot is not None:
            record["robot"] = plain(robot)
        if sigma is not None:
            record["sigma"] = plain(sigma)
        if cov is not None:
            record["cov"] = plain(cov)
        self._validator.name = f"Slam.{method}"
        before = self._validator.state
        try:
            event: Event = self._validator.parse_record(record)
        except LateInput as exc:
            self._skip_late(exc)
            return
        try:
            self._check_robots(event)
        except OnlineSlamError:
            self._validator.state = before
            raise
        self._engine.push(event)

    def flush(self) -> None:
        """Give the estimator every line ``max_latency`` holds back, now (the end of a run, or before a final
        query); a line older than those is late from then on (skipped and counted)."""
        self._engine.flush()
        state = self._validator.state
        state.floor = max(state.floor, state.last_t)

    def _skip_late(self, error: LateInput) -> None:
        """A line beyond ``max_latency``: skipped and counted in :attr:`late`, with one warning."""
        self.late += 1
        if self.late == 1:
            warnings.warn(f"{error}; skipped (Slam.late counts them)", stacklevel=_caller_level())

    def _check_robots(self, event: Event) -> None:
        """Refuse what the estimator could not take: a second robot for one of one robot, a robot sighting of a
        pose the estimator has already been shown (it takes no robot sightings of it any more)."""
        several = getattr(self._estimator, "several_robots", False)
        if isinstance(event, Start) and len(self._validator.state.robots) > 1 and not several:
            name = self.estimator_name
            raise OnlineSlamError(f"several robots: the {name} takes one robot at a time")
        if isinstance(event, Observation) and event.robot_seen is not None:
            frontend = self._engine.frontend
            pending = frontend.pending
            newest = [pose for pose in frontend.later if pose.robot == event.robot]
            if not newest and pending is not None and pending.sealed:
                shown = f"robot {event.robot!r}'s pose at t={pending.t}"
                message = f"the estimate of {shown} was queried already; add its robot sightings before querying"
                raise self._validator.fail(0, "robot_seen", message)

    # -- queries -------------------------------------------------------------------------------------
    def estimate(self, landmark_covs: bool = True, at: float | None = None, held: bool = True) -> SlamEstimate:
        """The current estimate, including every event added so far (sightings stamped after the newest pose wait
        for the odometry that spans their time).

        A query never creates a pose: with keyframing, odometry that may still merge into the pending keyframe
        stays out of the estimator, and the newest pose is predicted with it instead (as with odometry held back
        by ``max_latency``). So querying after every event gives the poses a replay gives.

        Args:
            landmark_covs: Also give each landmark's 2x2 marginal covariance (the smoother computes them on
                request: one linearization of its window; pass False to skip).
            at: Predict the pose to this time (seconds, not before the newest pose) from the newest pose with the
                odometry given so far, at constant twist past it; None: to the newest odometry's time.
            held: Also use the lines ``max_latency`` holds back (up to ``at``), each at its own time (a sighting
                between two poses gets a pose of its own there): a copy of the estimator takes them and answers, so
                the newest pose is the newest odometry's; the estimator itself takes them in time order once the
                budget has passed. False: what the estimator has taken, its newest pose predicted with the held
                odometry (no copy: cheaper, blind to held sightings).

        Returns:
            The estimate; before any event an empty one (``index`` -1, no trajectory, no landmarks).

        Raises:
            InputError: ``at`` before the newest pose, or ``at`` with several robots.
        """
        until = math.inf if at is None else at + TIME_TOLERANCE
        if held and any(not isinstance(line, Truth) for t, _, line in self._engine.frontend.held if t < until):
            return self._preview(until).estimate(landmark_covs, at, held=False)
        engine = self._engine
        pending = engine.frontend.pending
        name = self._estimator.name
        increments: list[Increment] = []
        frontend = engine.frontend
        if pending is not None and frontend.mergeable(pending) and not frontend.later and engine.state.times:
            snapshot = self._estimator.snapshot(_bare_step(engine))  # the pose before: the keyframe may still move
            increments.append(cast(Increment, (pending.t_begin, pending.t, pending.odometry, pending.odometry_cov)))
        else:
            found = engine.sync().get(name)
            if found is None:
                return empty_estimate(self._estimator.name, landmark_covs)
            snapshot = found
        if pending is not None:
            increments += self._held_increments(pending, increments[-1][1] if increments else snapshot.t)
        snapshot = self._predicted(snapshot, increments, at)
        covs = _read_only(self._estimator.landmark_marginals()) if landmark_covs else None
        frozen, tail = self._estimator.trajectory_parts()
        tail.flags.writeable = False
        times = engine.state.times + ([pending.t] if pending is not None and engine.state.given >= 0 else [])
        n = len(frozen) + len(tail)
        times_array = _read_only(np.array(times[:n], dtype=float))
        step_robots = self._pose_robots()
        return SlamEstimate(snapshot, covs, (frozen, tail), self._robot_poses(snapshot, step_robots), step_robots,
                            times_array)  # fmt: skip

    def _holds_sightings(self, until: float) -> bool:
        """Whether giving on the lines held back before ``until`` brings a sighting or fix to the estimator: one
        held, or one waiting (``ahead``) for odometry held."""
        frontend = self._engine.frontend
        held = [line for t, _, line in frontend.held if t < until]
        waiting = any(isinstance(line, Odometry) for line in held) and any(map(_sighting, frontend.ahead))
        return waiting or any(map(_sighting, held))

    def _preview(self, until: float) -> Slam:
        """A copy with the lines held back before ``until`` given on, for a query (:meth:`estimate`): what the copy
        shares, no one changes in place (the loaded map, the lines, the logs' arrays); the smoother's copy starts
        and hands over no global solve (``preview``) and solves its window once, when the query reads it (not at
        all when only odometry was held: poses at the end of a chain of odometry alone are its composition)."""
        frontend = self._engine.frontend
        shared = [self._loaded, *(line for _, _, line in frontend.held), *frontend.ahead]  # frozen, or never changed
        preview = copy.deepcopy(self, {id(obj): obj for obj in shared})
        smoother = preview._estimator if isinstance(preview._estimator, SlidingWindowSmoother) else None
        if smoother is not None:  # no global solve; the window solved once, when the query reads it
            smoother.preview, config = True, smoother.config
            smoother.config = dataclasses.replace(config, relinearize_every=sys.maxsize)
        news = self._holds_sightings(until)
        preview._engine.flush(until)
        if smoother is not None and news:  # odometry alone moves no pose it follows: its poses need no solve
            smoother.config = config
        return preview

    def _held_increments(self, pending: PendingStep, t: float) -> list[Increment]:
        """The odometry held back by ``max_latency`` after time ``t``, as increments (one robot)."""
        out: list[Increment] = []
        for odometry in self._engine.frontend.held_odometry(pending.robot):
            out.append((t, odometry.t, np.array(odometry.delta), odometry.covariance))
            t = odometry.t
        return out

    def _predicted(self, snapshot: Snapshot, increments: list[Increment], at: float | None) -> Snapshot:
        """The snapshot with its pose moved on by the increments, to ``at`` or to their end."""
        if at is None and not increments:
            return snapshot
        if at is not None:
            if len(self._validator.state.robots) > 1:
                raise InputError("Slam.estimate", 0, "at", "predicting to a time takes one robot")
            if not at >= snapshot.t - TIME_TOLERANCE:
                raise InputError("Slam.estimate", 0, "at", f"at={at} is before the newest pose (t={snapshot.t})")
        to = at if at is not None else increments[-1][1]
        motion = None
        pending = self._engine.frontend.pending
        if not increments and pending is not None and pending.odometry is not None:  # go on as the pose came
            motion = cast(Increment, (pending.t_begin, pending.t, pending.odometry, pending.odometry_cov))
        pose, cov = predict_pose(snapshot.pose, snapshot.pose_cov, snapshot.t, increments, to, motion)
        return dataclasses.replace(snapshot, t=float(to), pose=pose, pose_cov=cov)

    def _pose_robots(self) -> list[RobotId]:
        """The robot of every pose so far, in index order (empty when no line names one)."""
        if not self._validator.state.robots:  # one unnamed robot: no list to build at each query
            return []
        pending, later = self._engine.frontend.pending, self._engine.frontend.later
        robots = self._engine.state.robots + [pose.robot for pose in ([pending] if pending is not None else []) + later]
        return [] if all(robot is None for robot in robots) else cast("list[RobotId]", robots)

    def _robot_poses(self, snapshot: Snapshot, step_robots: list[RobotId]) -> Mapping[RobotId, NewestPose]:
        """Each named robot's newest pose: the snapshot's with one robot, the estimator's with several."""
        if not step_robots:
            return MappingProxyType({})
        if len(self._validator.state.robots) == 1:
            pose = snapshot.pose.copy()
            cov = snapshot.pose_cov.copy() if snapshot.pose_cov is not None else np.full((3, 3), np.nan)
            return MappingProxyType({step_robots[0]: (snapshot.index, snapshot.t, pose, cov)})
        newest: dict[RobotId | None, NewestPose] = self._estimator.robot_poses()
        return MappingProxyType({robot: newest[robot] for robot in self._validator.state.robots if robot in newest})

    @property
    def poses(self) -> int:
        """Poses so far, of all robots (0 before the first event)."""
        frontend = self._engine.frontend
        return self._engine.steps + (frontend.pending is not None) + len(frontend.later)

    def map(self) -> LandmarkMap:
        """The current map: every landmark's position, 2x2 marginal covariance and (EKF, smoother) their joint
        covariance (write it with :func:`~online_slam.sources.landmark_map.write_map`, or :meth:`save_map`);
        before the first pose, the map it started from. Lines ``max_latency`` holds back are in it, as in
        :meth:`estimate`."""
        source = self._preview(math.inf) if self._holds_sightings(math.inf) else self
        estimate = source.estimate(held=False)
        if estimate.index < 0 and self._loaded is not None:
            return self._loaded
        ids, joint = estimate.landmark_ids, getattr(source._estimator, "landmark_joint", lambda: None)()
        return LandmarkMap.of(
            ids, estimate.landmark_array, estimate.landmark_cov_array, "Slam", finite_joint(joint, len(ids))
        )

    def save_map(self, path: str | Path) -> None:
        """Write :meth:`map` as a map file."""
        write_map(path, self.map())

    # -- checkpoints ---------------------------------------------------------------------------------
    def save(self, path: str | Path) -> None:
        """Write the whole state to ``path`` atomically (data only; see :mod:`online_slam.checkpoint`)."""
        state = SlamCheckpoint(
            self.estimator_name,
            dict(self.options),
            self._validator.state,
            self._engine.checkpoint(),
            *self.typed,
            self.late,
        )
        write_checkpoint(path, _CHECKPOINT_KIND, state)

    @classmethod
    def load(cls, path: str | Path) -> Slam:
        """A :class:`Slam` continuing exactly where a saved one stopped.

        Raises:
            InputError: Missing, truncated, damaged or altered file, or one of another kind or version.
        """
        saved = read_checkpoint(path, _CHECKPOINT_KIND, SlamCheckpoint)
        try:
            typed = {} if saved.frontend is None else {"config": saved.config, "frontend": saved.frontend}
            slam = cls(saved.estimator, **typed, **saved.options)
            slam._validator.state = saved.validator
            slam._engine.restore(saved.engine)
            slam.late = saved.late
        except (KeyError, TypeError, ValueError, IndexError, ConfigError) as exc:
            raise InputError(str(path), 0, "", f"not a usable checkpoint: inconsistent state ({exc})") from None
        return slam


def _caller_level() -> int:
    """The ``stacklevel`` of the first frame outside this module, for a warning raised by its caller: the user's
    call, whichever ``add`` method led there."""
    frame: FrameType | None = sys._getframe(1)
    level = 1
    while frame is not None and frame.f_code.co_filename == __file__:
        frame, level = frame.f_back, level + 1
    return level


def _sighting(line: object) -> bool:
    """Whether a held or waiting line is a sighting or a fix (not odometry, not truth)."""
    return not isinstance(line, (Odometry, Truth))


def _bare_step(engine: Engine) -> Step:
    """The newest complete step's index and time (all a snapshot reads of it) without its data."""
    index, t = engine.state.steps - 1, engine.state.times[-1]
    return Step(index, t, None, None, (), np.zeros((0, 2)), np.zeros((0, 2, 2)))


@dataclass(eq=False)
class SlamCheckpoint:
    """What :meth:`Slam.save` writes."""

    estimator: str
    """The estimator's name."""
    options: dict[str, Any]
    """The options it was built with."""
    validator: ValidatorState
    """What the input checks remember (time, first pose)."""
    engine: EngineCheckpoint
    """The engine's, the front-end's and the estimator's state."""
    config: EkfConfig | SmootherConfig | None = None
    """The estimator's configuration when given as one (``Slam(config=...)``), else None."""
    frontend: FrontEndConfig | None = None
    """The front-end's configuration when given as one, else None."""
    late: int = 0
    """Lines skipped as later than ``max_latency`` so far."""
