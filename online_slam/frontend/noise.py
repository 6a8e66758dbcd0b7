"""Scaling the noise a stream declares, as the front-end reads it (``--odometry-noise-scale``,
``--sensor-noise-scale``).

A scale S multiplies a covariance by S: a full ``cov`` is multiplied element by element, a ``sigma`` by sqrt(S)
(so that ``diag(sigma^2)`` is multiplied by S, to the last bits of rounding). Odometry scales every odometry
event's covariance; sensor scales every sighting's, of a landmark or of another robot (the engine API's scans too).
The start prior is left as it is. A scale of 1 leaves the event untouched (the same object), so a replay with both
scales at 1 is bit-identical to one without them.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from online_slam.sources.events import Event, Matrix, Observation, Odometry, Scan, Vector


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
