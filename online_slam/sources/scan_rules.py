"""The scan checks of :class:`~online_slam.sources.validate.EventValidator`: k sightings taken at one time (the
library API's ``add_observations``), checked as a whole."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, cast

from online_slam.errors import InputError
from online_slam.sources.events import Matrix, Observation, Scan, Vector
from online_slam.sources.limits import MAX_BEARING, MAX_MAGNITUDE, MIN_RANGE, SIGMA_RANGE, nesting, show

if TYPE_CHECKING:
    from online_slam.sources.validate import ValidatorState


class ScanRules:
    """Scan checks; the validator provides ``fail``, ``state``, ``_pending``, ``time``, ``noise``,
    ``parse_record`` and ``max_latency``."""

    name: str
    state: ValidatorState
    _pending: ValidatorState
    max_latency: float

    def fail(self, line: int, field: str, message: str) -> InputError:
        raise NotImplementedError

    def time(self, record: dict[str, Any], line: int) -> float:
        raise NotImplementedError

    def noise(self, record: dict[str, Any], n: int, line: int, required: bool = True) -> tuple[Any, Any]:
        raise NotImplementedError

    def parse_record(self, record: Any, line: int = 0) -> Any:
        raise NotImplementedError

    def sensor(self, name: Any, declared: tuple[str, ...], line: int) -> str | None:
        raise NotImplementedError

    def parse_scan(
        self,
        t: Any,
        landmarks: Any,
        ranges: Any,
        bearings: Any,
        sigma: Any = None,
        cov: Any = None,
        xy: Any = None,
        sensor: Any = None,
    ) -> Scan:
        """Validate k sightings taken at one time as a whole: all are accepted, or none (state unchanged).

        Each sighting obeys the rules of an ``observation`` line: k ranges and k bearings, or k positions ``xy``
        (k, 2) in the robot frame (then ranges and bearings are None). ``sigma`` (2,) or ``cov`` (2, 2) is shared
        by all sightings, or given per sighting as (k, 2) / (k, 2, 2). Errors name the sighting: ``range[3]``.

        Raises:
            InputError: The first rule a sighting breaks.
        """
        if not isinstance(landmarks, (list, tuple)):
            raise self.fail(0, "landmarks", f"expected a list of ids, got {show(landmarks)}")
        k = len(landmarks)
        self._scan_shape(k, ranges, bearings, xy)
        noise_key, noise = ("cov", cov) if cov is not None else ("sigma", sigma)
        if sigma is not None and cov is not None:
            raise self.fail(0, "cov", "give either sigma or cov, not both")
        if noise is None:
            raise self.fail(0, "sigma", "missing noise: give sigma or cov")
        depth = 2 if noise_key == "cov" else 1  # nesting of one sighting's noise
        per_sighting = nesting(noise) > depth
        if per_sighting and (not isinstance(noise, list) or len(noise) != k):
            raise self.fail(0, noise_key, f"expected one {noise_key} shared by all sightings or one per sighting")
        self.sensor(sensor, self.state.sensors, 0)
        saved = self.state
        if saved.robots:
            raise self.fail(0, "robot", "a scan names no robot, and this stream's robots are named: add each sighting "
                            "as an observation record with its robot")  # fmt: skip
        fast = None if per_sighting else self._scan_fast(landmarks, ranges, bearings, xy)
        if (  # the commonest case: float time moving on, one plain sigma for all
            fast is not None
            and type(t) is float
            and saved.last_t <= t < math.inf
            and saved.first_pose_t is not None
            and t >= saved.first_pose_t
            and noise_key == "sigma"
            and type(noise) in (list, tuple)
            and len(noise) == 2
            and type(noise[0]) is float
            and type(noise[1]) is float
            and SIGMA_RANGE[0] <= noise[0] <= SIGMA_RANGE[1]
            and SIGMA_RANGE[0] <= noise[1] <= SIGMA_RANGE[1]
        ):
            self.state = type(saved)(t, saved.first_pose_t, True, sensors=saved.sensors, floor=saved.floor)
            one = tuple(noise)
            return Scan(t, tuple(landmarks), fast[0], fast[1], (one,) * k, fast[2], sensor)
        if fast is not None:  # the common case, checked at once
            self._pending = type(saved)(
                saved.last_t, saved.first_pose_t, saved.seen_content, sensors=saved.sensors, floor=saved.floor
            )
            t_value = self.time({"t": t}, 0)
            sigma_value, cov_value = self.noise({noise_key: noise}, 2, 0)
            # Cast: the record holds sigma or cov (noise is not None), so noise() returned one of them.
            shared = sigma_value if sigma_value is not None else cast(Matrix, cov_value)
            self.state = self._pending
            return Scan(t_value, tuple(landmarks), fast[0], fast[1], (shared,) * k, fast[2], sensor)
        return self._scan_one_by_one(t, landmarks, (ranges, bearings, xy), (noise_key, noise, per_sighting), sensor)

    def _scan_one_by_one(
        self, t: Any, landmarks: Any, measured: tuple[Any, Any, Any], noise_given: tuple[str, Any, bool], sensor: Any
    ) -> Scan:
        """A scan checked one sighting at a time on a trial validator: the exact error of the first bad one."""
        ranges, bearings, xy = measured
        noise_key, noise, per_sighting = noise_given
        saved, k = self.state, len(landmarks)
        trial = type(self)(  # type: ignore[call-arg]
            self.name,
            type(saved)(saved.last_t, saved.first_pose_t, saved.seen_content, sensors=saved.sensors, floor=saved.floor),
            self.max_latency,
        )
        trial._pending = type(saved)(
            saved.last_t, saved.first_pose_t, saved.seen_content, sensors=saved.sensors, floor=saved.floor
        )
        t_value = trial.time({"t": t}, 0)
        events: list[Observation] = []
        for i in range(k):
            record = {"type": "observation", "t": t, "landmark": landmarks[i]}
            record.update({"xy": xy[i]} if xy is not None else {"range": ranges[i], "bearing": bearings[i]})
            record[noise_key] = noise[i] if per_sighting else noise
            try:
                events.append(cast(Observation, trial.parse_record(record)))  # an observation record's event
            except InputError as exc:
                head, bracket, rest = exc.field.partition("[")
                field = (
                    f"{head}[{i}]{bracket}{rest}"
                    if head in ("landmark", "range", "bearing", "xy") or per_sighting
                    else exc.field
                )
                raise self.fail(0, field, exc.message) from None
        self.state = trial.state if events else trial._pending  # no sighting: the time check alone
        self.state.seen_content = True
        # Casts: a valid observation has sigma or cov, and either xy (two values) or range and bearing.
        noises = cast("tuple[Vector | Matrix, ...]", tuple(e.sigma if e.cov is None else e.cov for e in events))
        if xy is not None:
            positions = cast("tuple[tuple[float, float], ...]", tuple(e.xy for e in events))
            return Scan(t_value, tuple(landmarks), (), (), noises, positions, sensor)
        measured_ranges = cast("tuple[float, ...]", tuple(e.range for e in events))
        measured_bearings = cast("tuple[float, ...]", tuple(e.bearing for e in events))
        return Scan(t_value, tuple(landmarks), measured_ranges, measured_bearings, noises, sensor=sensor)

    def _scan_shape(self, k: int, ranges: Any, bearings: Any, xy: Any) -> None:
        """Check that a scan gives k ranges and k bearings, or k positions (and not both)."""
        if xy is not None:
            if ranges is not None or bearings is not None:
                raise self.fail(0, "xy", "give either ranges and bearings or xy, not both")
            if not isinstance(xy, (list, tuple)) or len(xy) != k:
                raise self.fail(0, "xy", f"expected a list of {k} [dx, dy] pairs (one per landmark), got {show(xy)}")
            return
        for key, values in (("ranges", ranges), ("bearings", bearings)):
            if not isinstance(values, (list, tuple)) or len(values) != k:
                message = f"expected a list of {k} numbers (one per landmark), or xy instead, got {show(values)}"
                raise self.fail(0, key, message)

    @staticmethod
    def _scan_fast(
        landmarks: Any, ranges: Any, bearings: Any, xy: Any
    ) -> tuple[tuple[float, ...], tuple[float, ...], tuple[tuple[float, float], ...] | None] | None:
        """Ranges, bearings and positions (None for range-bearing sightings) as float tuples when every sighting
        plainly passes, else None (check one by one)."""
        for lid in landmarks:
            if lid is not None and type(lid) is not int and (type(lid) is not str or lid == ""):
                return None
        if xy is not None:
            big = MAX_MAGNITUDE
            for pair in xy:  # NaN fails the comparisons
                if type(pair) not in (list, tuple) or len(pair) != 2:
                    return None
                a, b = pair
                if type(a) is not float or type(b) is not float or not (-big <= a <= big and -big <= b <= big):
                    return None
            return (), (), tuple(map(tuple, xy))
        low, high = MIN_RANGE, MAX_MAGNITUDE
        for r in ranges:  # NaN fails the comparisons
            if type(r) is not float or not low <= r <= high:
                return None
        for b in bearings:
            if type(b) is not float or not -MAX_BEARING <= b <= MAX_BEARING:
                return None
        return tuple(ranges), tuple(bearings), None
