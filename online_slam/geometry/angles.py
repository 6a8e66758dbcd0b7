"""The one angle-wrapping function of the package."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

_PI, _TWO_PI = math.pi, 2.0 * math.pi


def wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to [-pi, pi).

    Args:
        angle: Angles in radians, any shape.

    Returns:
        Array of the same shape with every value in [-pi, pi) (a numpy float for a Python or numpy float).
    """
    if isinstance(angle, float):  # one number (numpy's float64 is a float): the same arithmetic, 15-25x cheaper
        w = (angle + _PI) % _TWO_PI - _PI  # Python's float % is numpy's remainder (fmod, then the divisor's sign)
        return np.float64(w - _TWO_PI if w >= _PI else w)
    a = np.asarray(angle, dtype=float)
    w = (a + np.pi) % (2.0 * np.pi) - np.pi
    # Floating point can round (a + pi) % 2pi up to exactly 2pi's neighbour and give +pi; fold it back.
    return np.where(w >= np.pi, w - 2.0 * np.pi, w)
