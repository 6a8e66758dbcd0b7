"""Scaling the noise a stream declares, as the front-end reads it (``--odometry-noise-scale``,
``--sensor-noise-scale``), and taking each sensor's bias off its sightings (``FrontEndConfig.sensor_bias``).

A scale S multiplies a covariance by S: a full ``cov`` is multiplied element by element, a ``sigma`` by sqrt(S)
(so that ``diag(sigma^2)`` is multiplied by S, to the last bits of rounding). Odometry scales every odometry
event's covariance; sensor scales every sighting's, of a landmark or of another robot (the engine API's scans too).
The start prior is left as it is. A scale of 1 leaves the event untouched (the same object), so a replay with both
scales at 1 is bit-identical to one without them.

A sensor's bias ``(range m, bearing rad)`` is subtracted from the range and bearing of each range-bearing landmark
sighting it took (bearing wrapped), so the estimators see ``z - bias``: the model of ``--noise self``
(:mod:`online_slam.evaluation.noise_self`), which measures the biases. Position sightings and sightings of robots are
left as they are: a robot is another kind of target (its marker is not at its centre), whose offset is not the
sensor's. A reading shorter than its range bias is put at :data:`MIN_RANGE`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, cast

from online_slam.geometry.angles import wrap
from online_slam.sources.events import Event, Heading, Matrix, Observation, Odometry, Position, Scan, Vector

SensorBias = tuple[str | None, float, float]
"""One sensor's bias: its name (None: the robot's centre), the range bias (m) and the bearing bias (rad)."""
MIN_RANGE = 1e-3
"""Metres: the least range a bias correction leaves (the validator's ``range > 0`` holds after it)."""


def check_scale(name: str, value: float) -> None:
    """Refuse a scale that is not a finite number > 0.

    Raises:
        ValueError: Naming the scale and the value.
    """
    if not (isinstance(value, (int, float)) and 0.0 < value < math.inf):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def scaled_event(event: Event | Scan, odometry: float, sensor: float) -> Event | Scan:
    """The event with its odometry or sighting covariance multiplied by its scale (the event itself at scale 1)."""
    if isinstance(event, Odometry) and odometry != 1.0:
        return dataclasses.replace(event, **_scaled_noise(event.sigma, event.cov, odometry))
    if isinstance(event, Observation) and sensor != 1.0:
        return dataclasses.replace(event, **_scaled_noise(event.sigma, event.cov, sensor))
    if isinstance(event, Scan) and sensor != 1.0:
        return dataclasses.replace(event, noise=tuple(_scaled_scan_noise(n, sensor) for n in event.noise))
    return event


def scaled_fix(fix: Position | Heading, scale: float) -> Position | Heading:
    """An absolute fix with its covariance multiplied by ``scale`` (a heading's sigma by its square root)."""
    if scale == 1.0:
        return fix
    if isinstance(fix, Heading):
        return dataclasses.replace(fix, sigma=math.sqrt(scale) * fix.sigma, widened=scale * fix.widened)
    return dataclasses.replace(fix, **_scaled_noise(fix.sigma, fix.cov, scale), widened=scale * fix.widened)


def _scaled_noise(sigma: Vector | None, cov: Matrix | None, scale: float) -> dict[str, Any]:
    """An event's ``sigma`` and ``cov`` fields, scaled (the one of them given)."""
    if cov is not None:
        return {"cov": tuple(tuple(scale * c for c in row) for row in cov)}
    root = math.sqrt(scale)
    return {"sigma": None if sigma is None else tuple(root * s for s in sigma)}


def _scaled_scan_noise(noise: tuple, scale: float) -> tuple:
    """One scan sighting's noise, a sigma ``(s_range, s_bearing)`` or a 2x2 covariance, scaled."""
    if isinstance(noise[0], (tuple, list)):
        return tuple(tuple(scale * c for c in row) for row in noise)
    root = math.sqrt(scale)
    return tuple(root * s for s in noise)


def check_biases(biases: tuple[SensorBias, ...]) -> None:
    """Refuse biases that are not ``(name or None, finite range bias, finite bearing bias)``, or name a sensor twice.

    Raises:
        ValueError: Naming the entry.
    """
    names = []
    for entry in biases:
        ok = isinstance(entry, tuple) and len(entry) == 3 and (entry[0] is None or isinstance(entry[0], str))
        if not ok or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in entry[1:]):
            raise ValueError(f"sensor_bias: expected (sensor or None, range m, bearing rad), got {entry!r}")
        names.append(entry[0])
    if len(set(names)) != len(names):
        raise ValueError(f"sensor_bias: a sensor named twice in {names!r}")


def unbiased_event(event: Event | Scan, biases: tuple[SensorBias, ...]) -> Event | Scan:
    """The event with its sensor's bias taken off its range and bearing (the event itself when none applies)."""
    if isinstance(event, Observation) and event.xy is None and event.robot_seen is None:
        bias = _bias_of(event.sensor, biases)
        if bias is None:
            return event
        r, b = _unbiased(cast(float, event.range), cast(float, event.bearing), bias)
        return dataclasses.replace(event, range=r, bearing=b)
    if isinstance(event, Scan) and event.xy is None and (bias := _bias_of(event.sensor, biases)) is not None:
        pairs = [_unbiased(r, b, bias) for r, b in zip(event.ranges, event.bearings)]
        return dataclasses.replace(event, ranges=tuple(p[0] for p in pairs), bearings=tuple(p[1] for p in pairs))
    return event


def _bias_of(sensor: str | None, biases: tuple[SensorBias, ...]) -> tuple[float, float] | None:
    """The (range, bearing) bias of a sensor, or None when it has none."""
    return next(((r, b) for name, r, b in biases if name == sensor), None)


def _unbiased(range_m: float, bearing: float, bias: tuple[float, float]) -> tuple[float, float]:
    """One sighting's range and bearing with the bias taken off (bearing wrapped, range at least MIN_RANGE)."""
    return max(range_m - bias[0], MIN_RANGE), float(wrap(bearing - bias[1]))
