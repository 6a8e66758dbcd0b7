"""Validation of stream-v1 records: one rule set for the file reader and the engine API.

:class:`EventValidator` turns one JSON object (a ``dict``) into an event, or raises
:class:`~online_slam.errors.InputError` naming the source, the line, the field and what was expected. Cross-line
rules (non-decreasing time, ``start`` before any timed event, the header first) use a little state, which is
changed only once a record has passed every check: a rejected record leaves the validator as it was, so a
caller may skip it and go on.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Literal, cast, overload

import numpy as np

from online_slam.errors import InputError, LateInput
from online_slam.sources.events import (
    OUTLIER_KINDS,
    End,
    Event,
    Header,
    Heading,
    LandmarkId,
    LandmarkTruth,
    Observation,
    Odometry,
    Position,
    RobotId,
    Start,
    Truth,
    Vector,
)
from online_slam.sources.limits import (
    MAX_BEARING,
    MAX_MAGNITUDE,
    MIN_RANGE,
    SIGMA_RANGE,
    finite,
    show,
)
from online_slam.sources.robot_rules import ROBOT_FIELDS, RobotRules
from online_slam.sources.scan_rules import ScanRules

FORMAT = "online-slam"
VERSION = 1


FIELDS: dict[str, set[str]] = {
    "header": {"type"},  # free-form: every other field is metadata
    "start": {"type", "t", "pose", "sigma", "cov"} | ROBOT_FIELDS["start"],
    "odometry": {"type", "t", "delta", "sigma", "cov"} | ROBOT_FIELDS["odometry"],
    "observation": {
        "type",
        "t",
        "landmark",
        "range",
        "bearing",
        "xy",
        "sigma",
        "cov",
        "truth_outlier",
        "truth_landmark",
        "sensor",
        "widened",
    }
    | ROBOT_FIELDS["observation"],
    "truth": {"type", "t", "pose", "position", "offset"} | ROBOT_FIELDS["truth"],
    "landmark_truth": {"type", "landmark", "position"},
    "end": {"type"},
    "position": {"type", "t", "xy", "sigma", "cov", "offset"} | ROBOT_FIELDS["position"],
    "heading": {"type", "t", "theta", "sigma"} | ROBOT_FIELDS["heading"],
}
"""Allowed fields of each event type."""


def _plain_floats(delta: Any, sigma: Any) -> bool:
    """True when ``delta`` and ``sigma`` are 3 floats each that plainly pass (NaN fails the comparisons)."""
    if type(delta) not in (list, tuple) or type(sigma) not in (list, tuple) or len(delta) != 3 or len(sigma) != 3:
        return False
    big, (low, high) = MAX_MAGNITUDE, SIGMA_RANGE
    a, b, c = delta
    u, v, w = sigma
    return (
        type(a) is float and type(b) is float and type(c) is float
        and type(u) is float and type(v) is float and type(w) is float
        and -big <= a <= big and -big <= b <= big and -MAX_BEARING <= c <= MAX_BEARING
        and low <= u <= high and low <= v <= high and low <= w <= high
    )  # fmt: skip


@dataclass(slots=True)
class ValidatorState:
    """What the cross-line rules remember (saved in checkpoints)."""

    last_t: float = -math.inf
    """Newest time seen, seconds."""
    first_pose_t: float | None = None
    """Time of the first timed event (the first pose), or None before it."""
    seen_content: bool = False
    """True once any event was accepted (a header must come first)."""
    robots: tuple[RobotId, ...] = ()
    """Robots named by a ``start`` so far, in order; empty for a stream of one unnamed robot."""
    sensors: tuple[str, ...] = ()
    """Sensors the header declares (their names), which observations may name."""
    floor: float = -math.inf
    """Lines before this time are late whatever the latency budget (a flush gave on every line before it)."""


class EventValidator(ScanRules, RobotRules):
    """Checks one record at a time; a record that fails changes nothing.

    Args:
        name: Source name used in error messages (a file name, ``<stdin>``, or an API method).
    """

    def __init__(self, name: str, state: ValidatorState | None = None, max_latency: float = 0.0) -> None:
        self.name = name
        self.max_latency = max_latency
        """Seconds a line may be older than the newest one (a reorder buffer holds it); 0: time never goes back."""
        self.latency_name = "--max-latency"
        """How messages name the latency budget (the library's ``max_latency``)."""
        self.state = state or ValidatorState()
        self._pending = ValidatorState()
        self._parsers = {kind: getattr(self, f"_{kind}") for kind in FIELDS}

    def fail(self, line: int, field: str, message: str) -> InputError:
        return InputError(self.name, line, field, message)

    def parse_line(self, text: str, line: int) -> Event:
        """Validate one JSON line (a JSON object)."""
        try:
            record = json.loads(text)
        except json.JSONDecodeError as exc:
            # the line's own column: past its end (its newline kept, the parser's next line) is its length + 1
            column = exc.colno if exc.lineno == 1 else len(text.split("\n", 1)[0].rstrip("\r")) + 1
            raise self.fail(line, "", f"invalid JSON ({exc.msg} at column {column})") from None
        except RecursionError:
            raise self.fail(line, "", "invalid JSON (nested too deeply)") from None
        return self.parse_record(record, line)

    def parse_record(self, record: Any, line: int = 0) -> Event:
        """Validate one decoded record; on success the cross-line state moves on.

        Args:
            record: A decoded JSON value (should be an object).
            line: Line number for messages (0: not tied to a line).

        Returns:
            The event.

        Raises:
            InputError: The first rule the record breaks; the validator's state is unchanged.
        """
        if not isinstance(record, dict):
            raise self.fail(line, "", "expected a JSON object")
        kind = record.get("type")
        if not isinstance(kind, str) or kind not in FIELDS:
            expected = ", ".join(sorted(FIELDS))
            shown = show(kind)
            raise self.fail(line, "type", f"unknown event type {shown}; expected one of {expected}")
        if kind != "header":
            unknown = record.keys() - FIELDS[kind]
            if unknown:
                article = "an" if kind[0] in "aeiou" else "a"
                raise self.fail(line, str(sorted(map(str, unknown))[0]), f"unknown field for {article} {kind} event")
        state = self.state
        self._pending = ValidatorState(
            state.last_t, state.first_pose_t, state.seen_content, state.robots, state.sensors, state.floor
        )
        event = self._parsers[kind](record, line)
        self.state = self._pending
        return event

    def parse_odometry(self, t: Any, delta: Any, sigma: Any = None, cov: Any = None) -> Odometry:
        """Validate one odometry reading given as arguments (the library API's path; same rules as a line).

        Raises:
            InputError: The first rule it breaks; the validator's state is unchanged.
        """
        state = self.state
        fast = cov is None and not state.robots and type(t) is float and state.last_t <= t < math.inf
        if fast and _plain_floats(delta, sigma):
            first = state.first_pose_t
            if first is None or t >= first:  # the common case, checked at once
                self.state = ValidatorState(
                    t, t if first is None else first, True, sensors=state.sensors, floor=state.floor
                )
                return Odometry(t=t, delta=tuple(delta), sigma=tuple(sigma), cov=None)
        record: dict[str, Any] = {"type": "odometry", "t": t, "delta": delta}
        if sigma is not None:
            record["sigma"] = sigma
        if cov is not None:
            record["cov"] = cov
        return cast(Odometry, self.parse_record(record))  # an odometry record's event

    # -- field helpers -------------------------------------------------------------------------
    def radians(self, value: float, field: str, line: int) -> float:
        """An angle within [-2 pi, 2 pi]; a larger one is refused as likely degrees."""
        if not -MAX_BEARING <= value <= MAX_BEARING:
            message = f"expected radians within [-2 pi, 2 pi], got {value} (in degrees? convert them)"
            raise self.fail(line, field, message)
        return value

    def number(self, record: dict[str, Any], key: str, line: int) -> float:
        value = record.get(key)
        if type(value) is float and -MAX_MAGNITUDE <= value <= MAX_MAGNITUDE:  # the common case (NaN fails)
            return value
        if key not in record:
            raise self.fail(line, key, "missing required field")
        value = record[key]
        ok = finite(value)
        if ok is None:
            raise self.fail(line, key, f"expected a number, got {show(value)}")
        if not ok:
            raise self.fail(line, key, f"expected a finite number, got {show(value)}")
        if key != "t" and abs(value) > MAX_MAGNITUDE:
            raise self.fail(line, key, f"expected a magnitude <= {MAX_MAGNITUDE:g}, got {show(value)}")
        return float(value)

    def vector(self, record: dict[str, Any], key: str, n: int, line: int) -> tuple[float, ...]:
        if key not in record:
            raise self.fail(line, key, "missing required field")
        value = record[key]
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(line, key, f"expected a list of {n} numbers, got {show(value)}")
        for v in value:  # the common case first: finite floats in range (NaN fails the comparison)
            if type(v) is not float or not -MAX_MAGNITUDE <= v <= MAX_MAGNITUDE:
                break
        else:
            return tuple(value)
        out = []
        for i, item in enumerate(value):
            ok = finite(item)
            if ok is None:
                raise self.fail(line, f"{key}[{i}]", f"expected a number, got {show(item)}")
            if not ok:
                raise self.fail(line, f"{key}[{i}]", f"expected a finite number, got {show(item)}")
            if abs(item) > MAX_MAGNITUDE:
                raise self.fail(line, f"{key}[{i}]", f"expected a magnitude <= {MAX_MAGNITUDE:g}, got {show(item)}")
            out.append(float(item))
        return tuple(out)

    def noise(
        self, record: dict[str, Any], n: int, line: int, required: bool = True
    ) -> tuple[tuple[float, ...] | None, tuple[tuple[float, ...], ...] | None]:
        has_sigma, has_cov = "sigma" in record, "cov" in record
        if has_sigma and has_cov:
            raise self.fail(line, "cov", "give either sigma or cov, not both")
        if has_sigma:
            sigma = self.vector(record, "sigma", n, line)
            for i, s in enumerate(sigma):
                if not SIGMA_RANGE[0] <= s <= SIGMA_RANGE[1]:
                    low, high = SIGMA_RANGE
                    expected = f"expected a standard deviation > 0 within [{low:g}, {high:g}]"
                    raise self.fail(line, f"sigma[{i}]", f"{expected}, got {s}")
            return sigma, None
        if has_cov:
            value = record["cov"]
            if not isinstance(value, list) or len(value) != n or not all(isinstance(r, list) for r in value):
                raise self.fail(line, "cov", f"expected a {n}x{n} list of lists, got {show(value)}")
            rows = tuple(self.vector({"cov": row}, "cov", n, line) for row in value)
            matrix = np.array(rows)
            scale = max(float(np.max(np.abs(matrix))), 1e-300)
            if not np.allclose(matrix, matrix.T, rtol=0.0, atol=1e-9 * scale):
                raise self.fail(line, "cov", "expected a symmetric matrix")
            try:
                np.linalg.cholesky(matrix)
            except np.linalg.LinAlgError:
                raise self.fail(line, "cov", "expected a positive definite covariance") from None
            eigenvalues = np.linalg.eigvalsh(0.5 * (matrix + matrix.T))
            low, high = SIGMA_RANGE[0] ** 2, SIGMA_RANGE[1] ** 2
            if eigenvalues[0] < low or eigenvalues[-1] > high:
                raise self.fail(line, "cov", f"expected eigenvalues in [{low:g}, {high:g}] (variances)")
            return None, rows
        if required:
            raise self.fail(line, "sigma", "missing noise: give sigma or cov")
        return None, None

    def time(self, record: dict[str, Any], line: int) -> float:
        t = self.number(record, "t", line)
        last = self._pending.last_t
        if t < last and not t >= max(last - self.max_latency, self._pending.floor):
            if self.max_latency > 0.0:
                budget = f"{self.latency_name} {self.max_latency:g} s"
                message = f"late by {last - t:.9g} s (at {t:.15g} after {last:.15g}): beyond {budget}"
                raise LateInput(self.name, line, "t", message)
            everyone = " over all robots (one clock)" if self._pending.robots else ""
            message = f"time goes backwards ({t:.15g} after {last:.15g}); expected non-decreasing{everyone}"
            raise self.fail(line, "t", f"{message} (for late lines give a latency budget: --max-latency, max_latency)")
        self._pending.last_t = max(t, last)
        if self._pending.first_pose_t is None:
            self._pending.first_pose_t = t
        elif t < self._pending.first_pose_t:
            raise self.fail(line, "t", f"no pose exists at t={t}: the first pose is at t={self._pending.first_pose_t}")
        self._pending.seen_content = True
        return t

    @overload
    def landmark(
        self, record: dict[str, Any], line: int, optional: Literal[False] = False, key: str = "landmark"
    ) -> LandmarkId: ...
    @overload
    def landmark(
        self, record: dict[str, Any], line: int, optional: bool, key: str = "landmark"
    ) -> LandmarkId | None: ...
    def landmark(
        self, record: dict[str, Any], line: int, optional: bool = False, key: str = "landmark"
    ) -> LandmarkId | None:
        """The landmark id under ``key`` (``landmark``, or ``truth_landmark``: the same rules)."""
        if key not in record or (optional and record[key] is None):
            if optional:
                return None
            raise self.fail(line, key, "missing required field")
        value = record[key]
        if isinstance(value, bool) or not isinstance(value, (int, str)) or value == "":
            raise self.fail(line, key, f"expected an integer or a non-empty string id, got {show(value)}")
        return value

    # -- one method per event type -------------------------------------------------------------
    def _header(self, record: dict[str, Any], line: int) -> Header:
        if self._pending.seen_content:
            raise self.fail(line, "type", "a header must be the first line")
        if record.get("format", FORMAT) != FORMAT:
            raise self.fail(line, "format", f"expected {FORMAT!r}, got {show(record.get('format'))}")
        version = record.get("version", VERSION)
        if version != VERSION or isinstance(version, bool):
            raise self.fail(line, "version", f"unsupported version {show(version)}; this reader knows 1")
        name = record.get("name")
        if name is not None and not isinstance(name, str):
            raise self.fail(line, "name", f"expected a string, got {show(name)}")
        meta = {k: v for k, v in record.items() if k not in {"type", "format", "version", "name"}}
        if "sensors" in meta:
            meta["sensors"] = self._sensors(meta["sensors"], line)
            self._pending.sensors = tuple(meta["sensors"])
        tau = meta.get("fix_correlation_s")
        if "fix_correlation_s" in meta and (isinstance(tau, bool) or not isinstance(tau, (int, float))
                                            or not 0.0 <= tau < math.inf):  # fmt: skip
            raise self.fail(line, "fix_correlation_s", f"expected seconds >= 0 (a finite number), got {show(tau)}")
        if "sightings_own_scale" in meta:
            self._own_scale(meta["sightings_own_scale"], line)
        bias = meta.get("odometry_bias")
        if "odometry_bias" in meta and not (isinstance(bias, list) and len(bias) == 2
                                            and all(finite(v) and v >= 0.0 for v in bias)):  # fmt: skip
            raise self.fail(line, "odometry_bias", f"expected [S, W], prior sigmas >= 0, got {show(bias)}")
        self._pending.seen_content = True
        return Header(name=name, meta=meta, version=VERSION)

    def _own_scale(self, own: Any, line: int) -> None:
        """The header's ``sightings_own_scale``: ``{"range": [low, high], "spread": S}``, 0 < low <= high, S >= 1,
        all finite."""
        name = "sightings_own_scale"
        if not isinstance(own, dict) or set(own) != {"range", "spread"}:
            raise self.fail(line, name, f'expected {{"range": [low, high], "spread": S}}, got {show(own)}')
        span, spread = own["range"], own["spread"]
        if not (isinstance(span, list) and len(span) == 2 and all(finite(v) for v in span)
                and 0.0 < span[0] <= span[1]):  # fmt: skip
            raise self.fail(line, f"{name}.range", f"expected [low, high] with 0 < low <= high, got {show(span)}")
        if not (finite(spread) and spread >= 1.0):
            raise self.fail(line, f"{name}.spread", f"expected a finite number >= 1, got {show(spread)}")

    def _sensors(self, sensors: Any, line: int) -> dict[str, dict[str, list[float]]]:
        """The header's ``sensors``: ``{name: {"pose": [x, y, theta]}}``, each pose the sensor's in the robot frame."""
        if not isinstance(sensors, dict) or not sensors:
            raise self.fail(line, "sensors", f'expected {{name: {{"pose": [x, y, theta]}}}}, got {show(sensors)}')
        out = {}
        for name, spec in sensors.items():
            where = f"sensors.{name}"
            if not isinstance(spec, dict) or set(spec) != {"pose"}:
                raise self.fail(line, where, f'expected {{"pose": [x, y, theta]}} (robot frame), got {show(spec)}')
            pose = self.vector(spec, "pose", 3, line)
            self.radians(pose[2], f"{where}.pose[2]", line)
            out[str(name)] = {"pose": list(pose)}
        return out

    def sensor(self, name: Any, declared: tuple[str, ...], line: int) -> str | None:
        """A sighting's ``sensor``: None, or a name the header declares (``declared``)."""
        if name is not None and (not isinstance(name, str) or name not in declared):
            listed = ", ".join(declared) or "none: declare them in the header's sensors"
            raise self.fail(line, "sensor", f"unknown sensor {show(name)}; declared: {listed}")
        return name

    def _start(self, record: dict[str, Any], line: int) -> Start:
        robot = self.new_robot(record, line)
        if robot is None and self._pending.first_pose_t is not None:
            raise self.fail(line, "type", "start must come before every timed event")
        t = self.time(record, line)
        pose = self.vector(record, "pose", 3, line)
        self.radians(pose[2], "pose[2]", line)
        sigma, cov = self.noise(record, 3, line, required=False)
        return Start(t=t, pose=pose, sigma=sigma, cov=cov, robot=robot)

    def _odometry(self, record: dict[str, Any], line: int) -> Odometry:
        t = self.time(record, line)
        robot = self.robot(record, line)
        delta = self.vector(record, "delta", 3, line)
        self.radians(delta[2], "delta[2]", line)
        sigma, cov = self.noise(record, 3, line)
        return Odometry(t=t, delta=delta, sigma=sigma, cov=cov, robot=robot)

    def _observation(self, record: dict[str, Any], line: int) -> Observation:
        t = self.time(record, line)
        robot = self.robot(record, line)
        seen = self.sighted_robot(record, line, robot)
        landmark = self.landmark(record, line, optional=True)
        rng, bearing, xy = self._sighting(record, line)
        sigma, cov = self.noise(record, 2, line)
        mark = record.get("truth_outlier")
        if mark is not None and mark not in OUTLIER_KINDS:
            raise self.fail(line, "truth_outlier", f"expected one of {', '.join(OUTLIER_KINDS)}, got {show(mark)}")
        true_id = self.landmark(record, line, optional=True, key="truth_landmark")
        sensor = self.sensor(record.get("sensor"), self._pending.sensors, line)
        if sensor is not None and seen is not None:
            raise self.fail(line, "sensor", "a sighting of a robot is taken at the robot's centre (no sensor)")
        widened = None if "widened" not in record else self.widening(record, line)
        return Observation(
            t,
            landmark,
            rng,
            bearing,
            sigma,
            cov,
            truth_outlier=mark,
            truth_landmark=true_id,
            robot=robot,
            robot_seen=seen,
            xy=xy,
            sensor=sensor,
            widened=widened,
        )

    def widening(self, record: dict[str, Any], line: int) -> Vector:
        """An observation's ``widened``: two variance factors >= 1 (and, as every number, <= ``MAX_MAGNITUDE``)."""
        factors = self.vector(record, "widened", 2, line)
        for i, f in enumerate(factors):
            if not f >= 1.0:
                raise self.fail(line, f"widened[{i}]", f"expected a variance factor >= 1 (given over own), got {f}")
        return factors

    def _sighting(self, record: dict[str, Any], line: int) -> tuple[float | None, float | None, Vector | None]:
        """An observation's measurement: (range, bearing, None), or (None, None, xy) for a position sighting."""
        if "xy" in record:
            if "range" in record or "bearing" in record:
                given = "range" if "range" in record else "bearing"
                raise self.fail(line, "xy", f"give either range and bearing or xy, not both (got xy and {given})")
            return None, None, self.vector(record, "xy", 2, line)
        if "range" not in record and "bearing" not in record:
            raise self.fail(line, "range", "missing measurement: give range and bearing, or xy (robot frame)")
        rng = self.number(record, "range", line)
        if rng < MIN_RANGE:
            raise self.fail(line, "range", f"expected a range > 0 (at least {MIN_RANGE:g} m), got {rng}")
        return rng, self.radians(self.number(record, "bearing", line), "bearing", line), None

    def _truth(self, record: dict[str, Any], line: int) -> Truth:
        t = self.time(record, line)
        robot = self.robot(record, line)
        if "pose" not in record and "position" in record:  # position-only truth (e.g. GPS): heading unknown
            x, y = self.vector(record, "position", 2, line)
            offset = self.vector(record, "offset", 2, line) if "offset" in record else None
            return Truth(t=t, pose=(x, y, math.nan), robot=robot, offset=offset)
        if "offset" in record:
            raise self.fail(line, "offset", "an offset goes with position-only truth (position), not with a pose")
        return Truth(t=t, pose=self.vector(record, "pose", 3, line), robot=robot)

    def _position(self, record: dict[str, Any], line: int) -> Position:
        t = self.time(record, line)
        robot = self.robot(record, line)
        xy = self.vector(record, "xy", 2, line)
        sigma, cov = self.noise(record, 2, line)
        offset = self.vector(record, "offset", 2, line) if "offset" in record else None
        return Position(t=t, xy=xy, sigma=sigma, cov=cov, offset=offset, robot=robot)

    def _heading(self, record: dict[str, Any], line: int) -> Heading:
        t = self.time(record, line)
        robot = self.robot(record, line)
        theta = self.radians(self.number(record, "theta", line), "theta", line)
        sigma = self.number(record, "sigma", line)
        low, high = SIGMA_RANGE
        if not low <= sigma <= high:
            raise self.fail(line, "sigma", f"expected a standard deviation > 0 within [{low:g}, {high:g}], got {sigma}")
        return Heading(t=t, theta=theta, sigma=sigma, robot=robot)

    def _landmark_truth(self, record: dict[str, Any], line: int) -> LandmarkTruth:
        landmark = self.landmark(record, line)
        self._pending.seen_content = True
        return LandmarkTruth(landmark=landmark, position=self.vector(record, "position", 2, line))

    def _end(self, record: dict[str, Any], line: int) -> End:
        return End()


_SCALARS = frozenset({float, int, str, bool, type(None)})


def plain(value: Any) -> Any:
    """numpy arrays and scalars, and tuples, as the JSON-like values the validator checks."""
    kind = type(value)
    if kind in _SCALARS:
        return value
    if (kind is tuple or kind is list) and (not value or type(value[0]) in _SCALARS):
        return value if kind is list else list(value)  # flat: the validator checks every element
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def validate_events(
    items: Iterable[Any],
    on_error: Callable[[InputError], None] | None = None,
    name: str = "<events>",
    max_latency: float = 0.0,
) -> Iterator[Event]:
    """Events given as objects (or as decoded stream-v1 records), checked one at a time by the stream's rules.

    Args:
        items: Event objects (anything with ``to_record()``) or ``dict`` records, in stream order.
        on_error: None: the first bad item raises. Otherwise each bad item is given to this function and skipped.
        name: Source name for messages; an item's 1-based position stands for its line.
        max_latency: Seconds an item may be older than the newest (see :class:`EventValidator`).

    Yields:
        The validated events, up to an ``end`` (not given on: the stream ends there).
    """
    validator = EventValidator(name, max_latency=max_latency)

    def parse(item: Any, position: int) -> Event:
        if isinstance(item, Mapping):
            record = item
        elif callable(getattr(item, "to_record", None)):
            record = item.to_record()
        else:
            raise validator.fail(position, "", f"expected an event or a stream-v1 record, got {type(item).__name__}")
        return validator.parse_record({key: plain(value) for key, value in record.items()}, position)

    return until_end(parse, items, on_error)


def until_end(
    parse: Callable[[Any, int], Event | None], items: Iterable[Any], on_error: Callable[[InputError], None] | None
) -> Iterator[Event]:
    """Each item parsed (with its 1-based position) into an event, up to an ``end``; ``parse`` giving None skips an
    item (a blank line). A bad item raises, or with ``on_error`` is given to it and skipped."""
    for position, item in enumerate(items, 1):
        try:
            event = parse(item, position)
        except InputError as exc:
            if on_error is None:
                raise
            on_error(exc)
            continue
        if event is None:
            continue
        if type(event) is End:
            return
        yield event
