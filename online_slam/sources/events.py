"""Events of stream format v1: immutable records, one per JSON line.

Numbers are stored as Python floats in tuples so that events compare and round-trip exactly; ``covariance``
gives the numpy matrix. Noise is given either as ``sigma`` (standard deviations, a diagonal covariance) or as a
full ``cov``; exactly one of the two is set (for ``Start`` neither means a fixed start pose).

Several robots share a stream by naming theirs on every ``start``, ``odometry``, ``observation`` and ``truth``
(``robot``); without it the stream has one robot, as every stream before robots had. A sighting of another
robot is an ``Observation`` with ``robot_seen`` instead of ``landmark``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.models.observation import POSITION, RANGE_BEARING

OUTLIER_KINDS = ("wrong_id", "spike", "clutter")
"""Marks a simulator may put on a corrupted sighting (``Observation.truth_outlier``), for evaluation only."""


@dataclass(frozen=True, order=True)
class GeneratedId:
    """The id an estimator gives a landmark it made from sightings without one.

    It equals no int or string, so it never stands for a stream's landmark, whatever that one is called; it is
    shown as ``new-<number>``.
    """

    number: int
    """0, 1, ... in the order the estimator gave them out."""

    def __str__(self) -> str:
        return f"new-{self.number}"

    def to_tree(self) -> tuple[str, int]:
        """Its checkpoint form (a tagged pair: never an int or a string)."""
        return ("new", self.number)

    @classmethod
    def from_tree(cls, tree: Any) -> GeneratedId:
        """The id of a :meth:`to_tree` form."""
        if not isinstance(tree, (tuple, list)) or len(tree) != 2 or tree[0] != "new" or type(tree[1]) is not int:
            raise TypeError(f"expected a generated landmark id, got {tree!r}")
        return cls(tree[1])


LandmarkId = int | str | GeneratedId
"""Landmark identifiers: a stream's are integers or strings (``3`` and ``"3"`` are different landmarks); a
landmark an estimator made from sightings without an id has a :class:`GeneratedId`, equal to neither."""

RobotId = int | str
"""Robot identifiers: integers or strings, as landmark ids (``1`` and ``"1"`` are different robots)."""

Vector = tuple[float, ...]
Matrix = tuple[tuple[float, ...], ...]


def _covariance(sigma: Vector | None, cov: Matrix | None, n: int) -> NDArray[np.float64]:
    if cov is not None:
        return np.array(cov, dtype=float)
    if sigma is not None:
        return np.diag(np.square(np.array(sigma, dtype=float)))
    return np.zeros((n, n))


def _robot_record(robot: RobotId | None) -> dict[str, Any]:
    return {} if robot is None else {"robot": robot}


def _noise_record(sigma: Vector | None, cov: Matrix | None) -> dict[str, Any]:
    if cov is not None:
        return {"cov": [list(row) for row in cov]}
    if sigma is not None:
        return {"sigma": list(sigma)}
    return {}


@dataclass(frozen=True)
class Header:
    """Optional first line: names the stream and carries free-form metadata."""

    name: str | None = None
    """Human-readable name of the data set or run."""
    meta: dict[str, Any] = field(default_factory=dict)
    """Any further header fields (generator, seed, units, notes...), kept as read."""
    version: int = 1
    """Stream format version; only 1 exists."""

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        record: dict[str, Any] = {"type": "header", "format": "online-slam", "version": self.version}
        if self.name is not None:
            record["name"] = self.name
        record.update(self.meta)
        return record


@dataclass(frozen=True)
class Start:
    """The first pose: its time, value and (optional) uncertainty; without noise it is held fixed."""

    t: float
    """Time of the first pose, seconds."""
    pose: Vector
    """``[x, y, theta]`` of the first pose in the world frame."""
    sigma: Vector | None = None
    """Standard deviations ``[sx, sy, stheta]`` of a prior on the first pose, or None."""
    cov: Matrix | None = None
    """Full 3x3 prior covariance, or None."""
    robot: RobotId | None = None
    """The robot this first pose is of, or None: the stream's one robot (then no event names a robot)."""

    @property
    def fixed(self) -> bool:
        """True when the first pose is held fixed (no prior noise given)."""
        return self.sigma is None and self.cov is None

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Prior covariance, shape (3, 3); zeros when fixed."""
        return _covariance(self.sigma, self.cov, 3)

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        record = {"type": "start", "t": self.t, "pose": list(self.pose), **_noise_record(self.sigma, self.cov)}
        return {**record, **_robot_record(self.robot)}


@dataclass(frozen=True)
class Odometry:
    """Motion since the previous pose, expressed in the previous pose's frame; makes a new pose at ``t``."""

    t: float
    """Time of the new pose, seconds."""
    delta: Vector
    """``[dx, dy, dtheta]`` in the previous pose's frame."""
    sigma: Vector | None = None
    """Standard deviations of the increment, or None when ``cov`` is given."""
    cov: Matrix | None = None
    """Full 3x3 covariance of the increment, or None when ``sigma`` is given."""
    robot: RobotId | None = None
    """The robot that moved (its previous pose), or None in a stream of one unnamed robot."""

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Covariance of the increment, shape (3, 3)."""
        return _covariance(self.sigma, self.cov, 3)

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        return {
            "type": "odometry",
            "t": self.t,
            "delta": list(self.delta),
            **_noise_record(self.sigma, self.cov),
            **_robot_record(self.robot),
        }


@dataclass(frozen=True)
class Observation:
    """A sighting taken at time ``t``: the range and bearing (from the robot's heading) to a landmark or to another
    robot, or a landmark's position ``xy`` in the robot frame (then ``range`` and ``bearing`` are None)."""

    t: float
    """Time of the observation; it belongs to the newest pose with time <= t (of its ``robot``)."""
    landmark: LandmarkId | None
    """Identifier of the observed landmark (known data association), or None: unknown (absent from the line),
    for the estimators to associate; always None for a sighting of a robot (``robot_seen``)."""
    range: float | None = None
    """Distance to the landmark (or to the seen robot's position), metres (> 0); None for a position sighting."""
    bearing: float | None = None
    """Angle to the landmark (or to the seen robot's position) from the robot's heading, radians; None for a
    position sighting."""
    sigma: Vector | None = None
    """Standard deviations of z (``[s_range, s_bearing]`` or ``[s_dx, s_dy]``), or None when ``cov`` is given."""
    cov: Matrix | None = None
    """Full 2x2 covariance of z, or None when ``sigma`` is given."""
    truth_outlier: str | None = None
    """Evaluation only: how a simulator corrupted this sighting (``wrong_id``, ``spike``, ``clutter``), or None.
    The front-end keeps it with the truth; no estimator sees it."""
    truth_landmark: LandmarkId | None = None
    """Evaluation only: the true landmark of this sighting (hidden truth, e.g. of a stream written without ids),
    or None. It scores the estimators' data association; the front-end keeps it with the truth and no estimator
    sees it."""
    robot: RobotId | None = None
    """The robot that took the sighting, or None in a stream of one unnamed robot."""
    robot_seen: RobotId | None = None
    """The robot sighted (another started robot; then ``landmark`` is None), or None: a landmark sighting. It
    relates the sighting robot's newest pose with time <= t to the seen robot's newest pose with time <= t."""
    xy: Vector | None = None
    """Position ``[dx, dy]`` of the landmark in the robot frame (x ahead, y to the left), metres, instead of
    range and bearing; None for a range-bearing sighting."""
    sensor: str | None = None
    """The sensor that took it (a name the header's ``sensors`` declares with its pose in the robot frame; z is
    then in the sensor's frame), or None: a sensor at the robot's centre."""
    widened: Vector | None = None
    """How many times each component's variance in ``sigma`` / ``cov`` exceeds the sighting's own (each >= 1): the
    source widened it for errors this sighting shares with earlier ones (MRCLAM's converter), which its
    innovation does not show; None: not widened. The estimators use the covariance given; noise adaptation judges
    innovations by the sighting's own."""

    @property
    def z(self) -> tuple[float, float]:
        """The measurement: ``(range, bearing)``, or ``(dx, dy)`` for a position sighting."""
        # Cast: the validator sets both range and bearing when xy is None, and gives xy two values.
        return cast("tuple[float, float]", (self.range, self.bearing) if self.xy is None else self.xy)

    @property
    def model(self) -> int:
        """Tag of the sighting's model: ``RANGE_BEARING`` or ``POSITION`` (:mod:`online_slam.models.observation`)."""
        return RANGE_BEARING if self.xy is None else POSITION

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Covariance of z, shape (2, 2)."""
        return _covariance(self.sigma, self.cov, 2)

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        measured = {"range": self.range, "bearing": self.bearing} if self.xy is None else {"xy": list(self.xy)}
        record = {
            "type": "observation",
            "t": self.t,
            "landmark": self.landmark,
            **measured,
            **_noise_record(self.sigma, self.cov),
        }
        if self.landmark is None:
            del record["landmark"]
        if self.truth_outlier is not None:
            record["truth_outlier"] = self.truth_outlier
        if self.truth_landmark is not None:
            record["truth_landmark"] = self.truth_landmark
        if self.robot_seen is not None:
            record["robot_seen"] = self.robot_seen
        if self.robot is not None:
            record["robot"] = self.robot
        if self.sensor is not None:
            record["sensor"] = self.sensor
        if self.widened is not None:
            record["widened"] = list(self.widened)
        return record


@dataclass(frozen=True)
class Truth:
    """True pose at time ``t`` (evaluation only; no estimator sees it)."""

    t: float
    """Time, seconds; it applies to the pose whose time equals t."""
    pose: Vector
    """True ``[x, y, theta]``; theta is NaN for position-only truth (a ``position: [x, y]`` line, e.g. GPS)."""
    robot: RobotId | None = None
    """The robot whose pose this is, or None in a stream of one unnamed robot."""
    offset: Vector | None = None
    """Position-only truth: ``[dx, dy]`` of the robot-frame point it is the position of (a GPS antenna), or None:
    the robot's centre. Scoring compares that point of the estimated pose with it."""

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        if self.pose[2] != self.pose[2]:  # NaN heading: position only
            offset = {"offset": list(self.offset)} if self.offset is not None else {}
            return {
                "type": "truth",
                "t": self.t,
                "position": list(self.pose[:2]),
                **offset,
                **_robot_record(self.robot),
            }
        return {"type": "truth", "t": self.t, "pose": list(self.pose), **_robot_record(self.robot)}


@dataclass(frozen=True)
class LandmarkTruth:
    """True landmark position (evaluation only; no estimator sees it)."""

    landmark: LandmarkId
    """Identifier of the landmark."""
    position: Vector
    """True ``[x, y]``."""

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        return {"type": "landmark_truth", "landmark": self.landmark, "position": list(self.position)}


@dataclass(frozen=True)
class Position:
    """An absolute position fix (GPS, a surveyed point): the point ``offset`` of the robot frame (an antenna) is at
    ``xy`` in the map frame at time ``t``."""

    t: float
    """Time of the fix, seconds; it belongs to the robot's pose at that time, as a sighting does."""
    xy: Vector
    """``[x, y]`` of the fixed point in the map frame, metres."""
    sigma: Vector | None = None
    """Standard deviations ``[sx, sy]``, or None when ``cov`` is given."""
    cov: Matrix | None = None
    """Full 2x2 covariance of ``xy``, or None when ``sigma`` is given."""
    offset: Vector | None = None
    """``[dx, dy]`` of the fixed point (an antenna) in the robot frame, or None: the robot's centre."""
    robot: RobotId | None = None
    """The robot fixed, or None in a stream of one unnamed robot."""
    widened: float = 1.0
    """Never in a record: how much the front-end widened the covariance given, for the fixes' correlation in time
    (``fix_correlation``); the gates judge a fix by its own covariance, this much narrower."""

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Covariance of ``xy``, shape (2, 2)."""
        return _covariance(self.sigma, self.cov, 2)

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        record = {"type": "position", "t": self.t, "xy": list(self.xy), **_noise_record(self.sigma, self.cov)}
        if self.offset is not None:
            record["offset"] = list(self.offset)
        return {**record, **_robot_record(self.robot)}


@dataclass(frozen=True)
class Heading:
    """An absolute heading fix (a compass, a surveyed direction): the robot's heading in the map frame at ``t``."""

    t: float
    """Time of the fix, seconds; it belongs to the robot's pose at that time."""
    theta: float
    """Heading in the map frame, radians."""
    sigma: float
    """Its standard deviation, radians (> 0)."""
    robot: RobotId | None = None
    """The robot fixed, or None in a stream of one unnamed robot."""
    widened: float = 1.0
    """Never in a record: how much the front-end widened the covariance given, for the fixes' correlation in time
    (``fix_correlation``); the gates judge a fix by its own covariance, this much narrower."""

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        record = {"type": "heading", "t": self.t, "theta": self.theta, "sigma": self.sigma}
        return {**record, **_robot_record(self.robot)}


@dataclass(frozen=True)
class End:
    """The end of a stream (``{"type": "end"}``): a live source stops there and the run ends with its results; a
    file may carry it too (its lines after it are not read)."""

    def to_record(self) -> dict[str, Any]:
        """The JSON object of this event."""
        return {"type": "end"}


@dataclass(frozen=True)
class Scan:
    """Several observations taken at one time (the engine API's ``add_observations``; not a stream-v1 line)."""

    t: float
    """Time of the observations."""
    landmarks: tuple[LandmarkId | None, ...]
    """Identifiers of the observed landmarks (None: unknown), length k."""
    ranges: tuple[float, ...]
    """Distances, metres (> 0), length k."""
    bearings: tuple[float, ...]
    """Angles from the heading, radians, length k."""
    noise: tuple[Vector | Matrix, ...]
    """Per observation, its sigma (2 values) or its 2x2 covariance (nested tuples), length k."""
    xy: tuple[tuple[float, float], ...] | None = None
    """Positions ``(dx, dy)`` in the robot frame, length k, for a scan of position sightings (then ``ranges``
    and ``bearings`` are empty); None for range-bearing sightings."""
    sensor: str | None = None
    """The sensor that took them (declared in the header), or None: at the robot's centre."""

    def to_record(self) -> dict[str, Any]:
        """Not a stream-v1 line: a scan exists only between the engine API and the front-end."""
        raise TypeError("a scan is not a stream-v1 line; write its sightings as observation lines")


Event = Header | Start | Odometry | Observation | Truth | LandmarkTruth | Position | Heading | End
"""Any event of stream format v1."""
