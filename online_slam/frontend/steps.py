"""Events -> steps.

Step 0 is the start pose; each odometry event makes a new pose; an observation at time t belongs to the pose at
time t: the newest pose when t is its time (lines of one time in any order), else a pose of its own made by
splitting the odometry increment that spans t (see :class:`FrontEnd`). A step is complete when the next pose
begins, or at the end of the stream; until then it is pending (the engine may show it to the estimators early,
so that queries see every sighting at once).
A ``position`` or ``heading`` fix belongs to its pose as a sighting does (a pose of its own between odometry ticks)
and reaches the estimators in ``Step.fixes``. Truth events never reach a step: they are collected in
:class:`GroundTruth` for evaluation only.

With several robots (``robot`` on its lines) a step is one robot's pose: poses are indexed in the order they
begin (one index sequence over all robots, so in time order), a line belongs to its robot's newest pose, and a
pose is complete when its robot's next pose begins. Steps leave in index order: a complete pose waits for the
earlier poses of other robots (``later`` holds them), one step per event, the rest at :meth:`FrontEnd.close`.
A step carries its robot (None: the stream names none) and its sightings of other robots (``robots_seen``, from
the lines' ``robot_seen``) apart from its landmark sightings, so that no estimator mistakes a robot for a landmark.

Optional keyframing merges consecutive odometry events with no observation in between into one step (the
increments composed and their covariance propagated), up to distance, angle and time limits.
"""

from __future__ import annotations

import dataclasses
import heapq
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np
from numpy.typing import NDArray

from online_slam.frontend.noise import (
    SensorBias,
    check_biases,
    check_scale,
    scaled_event,
    scaled_fix,
    unbiased_event,
)
from online_slam.frontend.pose import GroundTruth, PendingStep, Step
from online_slam.models.fix import correlated_widening
from online_slam.models.motion import compose_increments, split_increment
from online_slam.models.observation import POSITION, RANGE_BEARING
from online_slam.sources.events import (
    Event,
    Header,
    Heading,
    LandmarkId,
    LandmarkTruth,
    Observation,
    Odometry,
    Position,
    RobotId,
    Scan,
    Start,
    Truth,
    Vector,
)

__all__ = [
    "STDIN_LATENCY",
    "TIME_TOLERANCE",
    "FrontEnd",
    "FrontEndConfig",
    "GroundTruth",
    "KeyframeConfig",
    "PendingStep",
    "Step",
]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class KeyframeConfig:
    """Limits for merging observation-free odometry steps; a merged step never exceeds any of them."""

    max_distance: float = 0.5
    """Largest translation of a merged increment, metres."""
    max_angle: float = 0.35
    """Largest absolute rotation of a merged increment, radians."""
    max_time: float = math.inf
    """Largest time span of a merged increment, seconds."""

    def __post_init__(self) -> None:
        if not (self.max_distance >= 0.0 and self.max_angle >= 0.0 and self.max_time >= 0.0):  # NaN fails too
            raise ValueError("keyframe limits (distance, angle, time) must be >= 0")


@dataclass(frozen=True)
class FrontEndConfig:
    """How events become steps."""

    keyframing: KeyframeConfig | None = None
    """Merge observation-free odometry steps within these limits; None (default) keeps every pose."""
    first_observation_only: bool = False
    """Keep only the first observation of each landmark (the article's ablation)."""
    odometry_noise_scale: float = 1.0
    """Multiply every odometry covariance by this (see :mod:`online_slam.frontend.noise`); 1 leaves it."""
    sensor_noise_scale: float = 1.0
    """Multiply every sighting's covariance by this; 1 leaves it."""
    sensor_bias: tuple[SensorBias, ...] = ()
    """Per sensor ``(name, range bias m, bearing bias rad)``, name None for the robot's centre: subtracted from its
    range-bearing landmark sightings before any estimator sees them (see :mod:`online_slam.frontend.noise`; ``--noise
    self`` measures them). Empty: none. A sensor the stream does not have is never met."""
    max_latency: float | None = None
    """Lines may arrive up to this many seconds older than the newest line's time: they are held back (a reorder
    buffer) and given on in time order; older ones are skipped and counted. 0: no buffer (time going back is an
    input error). None: 0, but :data:`STDIN_LATENCY` for a replay of a live source (standard input, TCP)."""
    fix_correlation: float | None = None
    """Seconds: the time constant of the absolute fixes' errors (a GPS's multipath wanders for seconds to minutes),
    taken as first-order Markov: each fix's covariance is widened by what its correlation with the robot's previous
    fix of its kind takes from it (:func:`~online_slam.models.fix.correlated_widening`), so that a fix every second
    counts for what its errors are worth, not each as news. 0: fixes independent. None: the stream header's
    ``fix_correlation_s``, else 0."""

    odometry_bias_scale: float | None = None
    """The prior standard deviation of the share of each logged distance that is not real, a bias the EKF
    estimates with the state (:mod:`~online_slam.estimators.ekf_bias`); 0: none. None: the stream header's
    ``odometry_bias`` (``[scale, rate]``), else 0."""
    odometry_bias_rate: float | None = None
    """The same of the heading rate (rad/s) each robot's odometry adds to its turns."""

    def __post_init__(self) -> None:
        check_scale("odometry_noise_scale", self.odometry_noise_scale)
        for name in ("odometry_bias_scale", "odometry_bias_rate"):
            value = getattr(self, name)
            if value is not None and not 0.0 <= value < math.inf:
                raise ValueError(f"{name} must be a finite number >= 0")
        check_scale("sensor_noise_scale", self.sensor_noise_scale)
        check_biases(self.sensor_bias)
        if self.max_latency is not None and not 0.0 <= self.max_latency < math.inf:  # NaN fails too
            raise ValueError("max_latency must be a finite number of seconds >= 0")
        if self.fix_correlation is not None and not 0.0 <= self.fix_correlation < math.inf:
            raise ValueError("fix_correlation must be a finite number of seconds >= 0")


Held = Odometry | Observation | Scan | Truth | Start | Position | Heading
"""A timed line the front-end may hold back: in the reorder buffer, or ahead of its robot's newest pose."""
Ahead = Observation | Scan | Truth | Position | Heading
"""A line stamped after its robot's newest pose: it waits for the odometry that spans its time."""
TIMED = (Odometry, Observation, Scan, Truth, Start, Position, Heading)
"""The types of :data:`Held` lines."""

STDIN_LATENCY = 0.5
"""Seconds a line of a live source (standard input, TCP) may arrive late (``--max-latency`` not given): a camera
and its detector lag the odometry by tens to a few hundred milliseconds; half a second holds them with a margin and
delays a replay's steps (``--emit`` lines, recordings) by as much; ``Slam.estimate`` answers at once from a copy
that takes the held lines."""

TIME_TOLERANCE = 1e-6
"""Seconds within which two times are the same pose's: a sighting this close to a pose attaches to it, a later one
gets a pose at its own time (a split increment far shorter would carry a near-zero covariance)."""


@dataclass(eq=False)
class FrontEnd:
    """Turns events into steps, one event at a time; collects header, truth and counts on the way.

    :meth:`push` takes one validated event and returns the oldest step now complete, if any (an odometry event
    completes the newest pose); :meth:`next_complete` gives the others one by one (a split increment completes
    several); :attr:`pending` is the newest pose, still open for observations; :meth:`close` completes it at the
    end of the stream. :meth:`steps` wraps them for an iterable of events. Its fields set by ``__init__`` are its
    whole state (a checkpoint holds them).

    Sightings between odometry ticks: a sighting stamped after its robot's newest pose waits (``ahead``) for the
    odometry that spans its time; that increment is then split at each such time (constant twist,
    :func:`~online_slam.models.motion.split_increment`), so the sighting gets a pose at its own time. Lines of one
    time attach to the pose at that time in any order. With ``max_latency`` > 0, lines first wait in a reorder
    buffer (``held``) until they are that much older than the newest line, and leave it in time order.
    """

    config: FrontEndConfig | None = None
    """Keyframing and the first-observation-only ablation (None: the defaults)."""
    header: Header | None = None
    """The stream's header, if it had one."""
    truth: GroundTruth = field(default_factory=GroundTruth)
    """Ground truth met so far."""
    counts: dict[str, int] = field(default_factory=dict)
    """Events seen by type, and observations dropped by ``first_observation_only``."""
    pending: PendingStep | None = None
    """The oldest pose not yet given out (None before the first event): with one robot, the newest pose;
    ``pending.sealed`` once an estimator has seen it."""
    later: list[PendingStep] = field(default_factory=list)
    """Poses begun after ``pending`` (several robots, or a split increment), in index order."""
    sightings: int = 0
    """Sightings put into steps so far (their numbers, in step order, are 0 .. sightings - 1)."""
    ahead: list[Ahead] = field(default_factory=list)
    """Sightings and truth stamped after their robot's newest pose, in time order, until its next odometry."""
    held: list[tuple[float, int, Held]] = field(default_factory=list)
    """The reorder buffer: a heap of (time, arrival number, line), with ``max_latency`` > 0."""
    arrivals: int = 0
    """Lines put into the reorder buffer so far."""
    newest_t: float = -math.inf
    """Newest time of a line so far (with ``max_latency`` > 0)."""
    sensors: dict[str, tuple[float, ...]] = field(default_factory=dict)
    """Each sensor the header declares: its pose ``[x, y, theta]`` in the robot frame."""
    last_fix: dict[str, float] = field(default_factory=dict)
    """The time of each robot's newest fix of each kind (``"position <robot>"``, ``"heading <robot>"``)."""
    _seen: set[LandmarkId | None] = field(default_factory=set)
    """Landmarks sighted so far (kept for ``first_observation_only``)."""
    _sigma_covariance: tuple[tuple[float, ...], Array] | None = field(default=None, init=False, repr=False)
    """The odometry covariance of the last sigma, shared while the sigma stays the same."""

    def __post_init__(self) -> None:
        self.config = self.config or FrontEndConfig()

    def _count(self, key: str, n: int = 1) -> None:
        self.counts[key] = self.counts.get(key, 0) + n

    def steps(self, events: Iterable[Event]) -> Iterator[Step]:
        """Turn events into steps.

        Args:
            events: Validated stream-v1 events in stream order.

        Yields:
            Steps in index order, each once it is complete.
        """
        for event in events:
            step = self.push(event)
            while step is not None:
                yield step
                step = self.next_complete()
        while (last := self.close()) is not None:
            yield last

    def push(self, event: Event | Scan) -> Step | None:
        """Consume one event.

        Args:
            event: The next validated event.

        Returns:
            The oldest step now complete (the previous pose, when an odometry event starts a new one), or None;
            :meth:`next_complete` gives the others.
        """
        config = cast(FrontEndConfig, self.config)  # never None after __post_init__
        if config.odometry_noise_scale != 1.0 or config.sensor_noise_scale != 1.0:
            event = scaled_event(event, config.odometry_noise_scale, config.sensor_noise_scale)
        if config.sensor_bias:
            event = unbiased_event(event, config.sensor_bias)
        first = isinstance(event, Start) and not self.held and self.pending is None  # the start: nothing to wait for
        if config.max_latency and isinstance(event, TIMED) and not first:
            self.newest_t = max(self.newest_t, event.t)
            heapq.heappush(self.held, (event.t, self.arrivals, event))
            self.arrivals += 1
            self._release(self.newest_t - config.max_latency)
        else:
            self._take(event)
        return self._give_out()

    def flush(self, until: float = math.inf) -> Step | None:
        """Give on every line held by the reorder buffer now (the end of a live run, or a pause), or those older
        than ``until``; returns the oldest step now complete, as :meth:`push` does. Lines older than those given
        on are late from then on."""
        self._release(until)
        return self._give_out()

    def _release(self, due: float) -> None:
        """Take the held lines older than ``due``, in time order (then arrival)."""
        while self.held and self.held[0][0] < due:
            self._take(heapq.heappop(self.held)[2])

    def next_complete(self) -> Step | None:
        """The next complete step not yet given out, or None (call after :meth:`push` until it gives None)."""
        return self._give_out()

    def held_odometry(self, robot: RobotId | None = None) -> list[Odometry]:
        """Odometry of ``robot`` not yet in a step: in the reorder buffer, in time order."""
        return [e for _, _, e in sorted(self.held, key=lambda h: (h[0], h[1])) if isinstance(e, Odometry)
                and e.robot == robot]  # fmt: skip

    def _take(self, event: Event | Scan) -> None:
        """Put one event (in time order) into the poses."""
        if isinstance(event, Odometry):
            self._count("odometry")
            self._odometry(event)
        elif isinstance(event, (Observation, Scan, Truth, Position, Heading)):
            if isinstance(event, (Position, Heading)):
                event = self._decorrelated(event)
            if isinstance(event, Scan):
                self._count("observation", len(event.landmarks))
            elif isinstance(event, Observation):
                self._count("robot_observation" if event.robot_seen is not None else "observation")
            else:
                self._count(event.to_record()["type"])
            pose = self._newest(_robot_of(event), event.t)
            if event.t > pose.t + TIME_TOLERANCE:
                self.ahead.append(event)
            else:
                self._attach(event, pose)
        elif isinstance(event, Start):
            self._start_pose(event, event.t)
        elif isinstance(event, LandmarkTruth):
            self._count("landmark_truth")
            self.truth.landmarks[event.landmark] = np.array(event.position)
        elif isinstance(event, Header):
            self.header = event
            declared = event.meta.get("sensors") or {}
            self.sensors = {name: tuple(float(v) for v in spec["pose"]) for name, spec in declared.items()}

    @property
    def sightings_correlated(self) -> bool:
        """The header (so far) says the sightings' covariances are widened for errors correlated in time."""
        return self.header is not None and bool(self.header.meta.get("sightings_correlated"))

    @property
    def sightings_own_scale(self) -> tuple[float, float, float] | None:
        """The header's ``sightings_own_scale`` as ``(low, high, spread)``: the sensor scales streams declared right
        read against their sightings' own covariances, and the factor beyond them that still says nothing; None:
        none."""
        own = None if self.header is None else self.header.meta.get("sightings_own_scale")
        return None if own is None else (float(own["range"][0]), float(own["range"][1]), float(own["spread"]))

    @property
    def odometry_bias(self) -> Array | None:
        """The odometry bias prior sigmas ``[scale, rate]`` (2,) a robot's first step carries (the configuration's,
        else the header's), or None: not modelled (both 0)."""
        config = cast(FrontEndConfig, self.config)
        declared = (None if self.header is None else self.header.meta.get("odometry_bias")) or (0.0, 0.0)
        given = (config.odometry_bias_scale, config.odometry_bias_rate)
        sigmas = np.array([float(d if g is None else g) for g, d in zip(given, declared)])
        return sigmas if sigmas.any() else None

    def _decorrelated(self, fix: Position | Heading) -> Position | Heading:
        """The fix with its covariance widened for its correlation with the robot's previous one of its kind
        (``fix_correlation``; the fix itself when that is 0)."""
        tau = cast(FrontEndConfig, self.config).fix_correlation
        if tau is None:
            tau = float((self.header.meta.get("fix_correlation_s") or 0.0) if self.header is not None else 0.0)
        key = f"{type(fix).__name__.lower()} {fix.robot}"
        previous, self.last_fix[key] = self.last_fix.get(key), fix.t
        if not tau or previous is None:
            return fix
        return scaled_fix(fix, correlated_widening(fix.t - previous, tau))

    def _attach(self, event: Ahead, pending: PendingStep) -> None:
        """Attach a sighting (or a truth) to the pose at its time."""
        config = cast(FrontEndConfig, self.config)
        if isinstance(event, Truth):
            if abs(event.t - pending.t) <= TIME_TOLERANCE:
                self.truth.poses[pending.index] = np.array(event.pose)
                if event.offset is not None:
                    self.truth.offsets[pending.index] = np.array(event.offset, dtype=float)
        elif isinstance(event, (Position, Heading)):
            pending.fixes.append(event)
        elif isinstance(event, Observation) and event.robot_seen is not None:
            pending.robots_seen.append(event.robot_seen)
            # Cast: a sighting of a robot gives range and bearing (the validator refuses xy).
            pending.z_robots.append(cast("tuple[float, float]", (event.range, event.bearing)))
            pending.z_robots_cov.append(event.covariance)
        elif isinstance(event, Observation):
            if config.first_observation_only:
                if event.landmark in self._seen:
                    self._count("dropped_repeat_observation")
                    return
                self._seen.add(event.landmark)
            if event.truth_outlier is not None:
                self.truth.outliers[self.sightings] = event.truth_outlier
            if event.truth_landmark is not None:
                self.truth.sighting_landmarks[self.sightings] = event.truth_landmark
            self.sightings += 1
            pending.landmarks.append(event.landmark)
            pending.z.append(event.z)
            pending.z_model.append(event.model)
            pending.z_noise.append(event.sigma if event.cov is None else event.cov)
            pending.z_widening.append(event.widened)
            if event.cov is not None:
                pending.full_covariance = True
            if pending.mounted:
                pending.z_mount.append(self._mount(event.sensor))
                pending.z_sensor.append(event.sensor)
        else:
            self._attach_scan(event, pending)

    def _attach_scan(self, event: Scan, pending: PendingStep) -> None:
        keep: Sequence[int] = range(len(event.landmarks))
        if cast(FrontEndConfig, self.config).first_observation_only:
            keep = self._first_sightings(event.landmarks)
            self._count("dropped_repeat_observation", len(event.landmarks) - len(keep))
        self.sightings += len(keep)
        z: Iterable[tuple[float, float]] = zip(event.ranges, event.bearings) if event.xy is None else event.xy
        pending.z_model.extend([RANGE_BEARING if event.xy is None else POSITION] * len(keep))
        if pending.mounted:
            pending.z_mount.extend([self._mount(event.sensor)] * len(keep))
            pending.z_sensor.extend([event.sensor] * len(keep))
        if len(keep) == len(event.landmarks):
            pending.landmarks.extend(event.landmarks)
            pending.z.extend(z)
            pending.z_noise.extend(event.noise)
        else:
            z_list = list(z)
            pending.landmarks.extend(event.landmarks[i] for i in keep)
            pending.z.extend(z_list[i] for i in keep)
            pending.z_noise.extend(event.noise[i] for i in keep)
        pending.z_widening.extend([None] * len(keep))
        if event.noise and isinstance(event.noise[0][0], tuple):
            pending.full_covariance = True

    def _odometry(self, event: Odometry) -> None:
        """A new pose at the event's time (or the event merged into the newest pose by keyframing); the sightings
        waiting between the two poses get poses of their own on the split increment."""
        pending = self._newest(event.robot, event.t)
        waiting = [e for e in self.ahead if _robot_of(e) == event.robot]
        if waiting:
            self.ahead = [e for e in self.ahead if _robot_of(e) != event.robot]
        cut = event.t - TIME_TOLERANCE
        splits: list[float] = []
        for e in waiting:
            if not isinstance(e, Truth) and e.t < cut and (not splits or e.t > splits[-1] + TIME_TOLERANCE):
                splits.append(e.t)
        delta, cov = np.array(event.delta), self._odometry_covariance(event)
        poses = []
        if splits:
            t_begin = pending.t
            pending.closed = True
            for t_split in splits:
                part, part_cov, delta, cov = split_increment(delta, cov, (t_split - t_begin) / (event.t - t_begin))
                poses.append(self._begin(t_split, t_begin, part, part_cov, pending.robot, closed=True))
                t_begin = t_split
            poses.append(self._begin(event.t, t_begin, delta, cov, pending.robot))
        elif pending is not self._tail() or not self._merge(pending, event):
            pending.closed = True
            poses.append(self._begin(event.t, pending.t, delta, cov, pending.robot))
        else:
            poses.append(pending)
        for e in waiting:
            at = [pose for pose in poses if pose.t <= e.t + TIME_TOLERANCE]
            if not at or e.t - at[-1].t > TIME_TOLERANCE:  # a truth between poses, or a line past this odometry
                if e.t > cut:
                    self.ahead.append(e)
                continue
            self._attach(e, at[-1])

    def _mount(self, sensor: str | None) -> tuple[float, ...]:
        """A sensor's pose in the robot frame (the centre's for None)."""
        return (0.0, 0.0, 0.0) if sensor is None else self.sensors[sensor]

    def _begin(
        self, t: float, t_begin: float, delta: Array, cov: Array, robot: RobotId | None, closed: bool = False
    ) -> PendingStep:
        """Begin a pose after the newest of all robots."""
        pose = PendingStep(index=self._tail().index + 1, t=t, t_begin=t_begin, odometry=delta, odometry_cov=cov,
                           robot=robot, closed=closed, mounted=bool(self.sensors),
                           widened=self.sightings_correlated)  # fmt: skip
        self.later.append(pose)
        return pose

    def _first_sightings(self, landmarks: Iterable[LandmarkId | None]) -> list[int]:
        """Which sightings are of landmarks not sighted before, by position (those landmarks count as sighted now)."""
        keep = []
        for i, lid in enumerate(landmarks):
            if lid not in self._seen:
                self._seen.add(lid)
                keep.append(i)
        return keep

    def _newest(self, robot: RobotId | None, t: float) -> PendingStep:
        """The newest pose of ``robot`` (a first pose at the origin when the stream begins without a start)."""
        if self.pending is None:
            return self._start_pose(None, t)
        for pose in reversed(self.later):
            if pose.robot == robot:
                return pose
        return self.pending

    def _tail(self) -> PendingStep:
        """The newest pose of all robots (there is one)."""
        return self.later[-1] if self.later else cast(PendingStep, self.pending)  # called once a pose began

    def _give_out(self) -> Step | None:
        """The oldest pose if it is complete (it leaves the front-end), else None."""
        pending = self.pending
        if pending is None or not pending.closed:
            return None
        self.pending = self.later.pop(0) if self.later else None
        return pending.freeze()

    def _odometry_covariance(self, event: Odometry) -> Array:
        """The event's covariance; one shared read-only matrix while the odometry's sigma stays the same."""
        if event.cov is not None:
            return event.covariance
        cached = self._sigma_covariance
        sigma = cast(Vector, event.sigma)  # no cov: the validator set sigma
        if cached is None or cached[0] != sigma:
            matrix = event.covariance
            matrix.flags.writeable = False
            cached = self._sigma_covariance = (sigma, matrix)
        return cached[1]

    def close(self) -> Step | None:
        """End of stream: the oldest pose not yet given out, complete (None when none is left); call it until it
        gives None (with one robot, once more after the newest pose).

        Lines still in the reorder buffer are taken first; sightings stamped after their robot's last odometry
        attach to its newest pose (no odometry spans their time), counted as ``after_last_odometry``.
        """
        self._release(math.inf)
        waiting, self.ahead = self.ahead, []
        for event in waiting:
            pose = self._newest(_robot_of(event), event.t)
            if not isinstance(event, Truth):
                self._count("after_last_odometry", len(event.landmarks) if isinstance(event, Scan) else 1)
                event = dataclasses.replace(event, t=pose.t)
            self._attach(event, pose)
        pending = self.pending
        if pending is not None:
            pending.closed = True
            for pose in self.later:  # no line can reach any pose any more
                pose.closed = True
        return self._give_out()

    def _start_pose(self, start: Start | None, t: float) -> PendingStep:
        prior_cov = None if start is None or start.fixed else start.covariance
        pose = np.zeros(3) if start is None else np.array(start.pose)
        robot = None if start is None else start.robot
        index = 0 if self.pending is None else self._tail().index + 1
        begun = PendingStep(
            index=index,
            t=t,
            t_begin=t,
            odometry=None,
            odometry_cov=None,
            prior=pose,
            prior_cov=prior_cov,
            odometry_bias=self.odometry_bias,
            robot=robot,
            mounted=bool(self.sensors),
            widened=self.sightings_correlated,
        )
        if self.pending is None:
            self.pending = begun
        else:
            self.later.append(begun)
        self.truth.starts[index] = pose
        return begun

    def mergeable(self, pending: PendingStep) -> bool:
        """Whether keyframing may still fold odometry into this pose: on, an odometry pose without sightings that
        no estimator has seen."""
        return (
            cast(FrontEndConfig, self.config).keyframing is not None  # never None after __post_init__
            and pending.odometry is not None
            and pending.odometry_cov is not None  # never None with odometry
            and not pending.landmarks
            and not pending.robots_seen
            and not pending.fixes
            and not pending.sealed
        )

    def _merge(self, pending: PendingStep, event: Odometry) -> bool:
        """Fold the odometry event into the pending step if keyframing allows it."""
        if not self.mergeable(pending):
            return False
        limits = cast(KeyframeConfig, cast(FrontEndConfig, self.config).keyframing)  # mergeable: keyframing is on
        before, before_cov = cast(Array, pending.odometry), cast(Array, pending.odometry_cov)  # mergeable: both set
        delta, cov = compose_increments(before, before_cov, np.array(event.delta), event.covariance)
        if (
            math.hypot(delta[0], delta[1]) > limits.max_distance
            or abs(delta[2]) > limits.max_angle
            or event.t - pending.t_begin > limits.max_time
        ):
            return False
        pending.odometry, pending.odometry_cov = delta, cov
        pending.t = event.t
        pending.merged += 1
        # The pose moved on in time: a truth recorded for its earlier time no longer applies.
        self.truth.poses.pop(pending.index, None)
        self.truth.offsets.pop(pending.index, None)
        return True


def _robot_of(event: Ahead) -> RobotId | None:
    """The robot a line is of (a scan names none)."""
    return None if isinstance(event, Scan) else event.robot
