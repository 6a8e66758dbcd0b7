"""The limits of stream-v1 values and the small helpers of the validators' messages (no state)."""

from __future__ import annotations

import json
import math
from typing import Any

MAX_MAGNITUDE = 1e9
"""Largest magnitude of any number but a time (metres, radians): larger ones overflow the estimators."""
MIN_RANGE = 1e-6
"""Smallest range, metres: the range-bearing Jacobian divides by it (a landmark at the sensor has no bearing)."""
SIGMA_RANGE = (1e-8, 1e8)
"""Allowed standard deviations (and square roots of covariance eigenvalues)."""
MAX_BEARING = 2 * math.pi
"""Largest magnitude of an angle (a bearing, an odometry turn, a start heading), radians: a larger one is most
likely in degrees (45.0 for pi/4), so refused."""


def show(value: Any, limit: int = 60) -> str:
    """A short JSON-like rendering of an offending value for messages."""
    try:
        text = json.dumps(value, default=repr)
    except (TypeError, ValueError, RecursionError):
        text = repr(type(value).__name__)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def nesting(value: Any) -> int:
    """How deeply lists nest at the front of a value (0 for a scalar)."""
    depth = 0
    while isinstance(value, (list, tuple)) and len(value):
        value, depth = value[0], depth + 1
    return depth


def finite(value: Any) -> bool | None:
    """True for a finite real number, False for NaN/inf or a number too large for a float, None for a non-number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False
