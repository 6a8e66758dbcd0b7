"""The one angle-wrapping function of the package."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to [-pi, pi).

    Args:
        angle: Angles in radians, any shape.

    Returns:
        Array of the same shape with every value in [-pi, pi).
    """
    a = np.asarray(angle, dtype=float)
    w = (a + np.pi) % (2.0 * np.pi) - np.pi
    # Floating point can round (a + pi) % 2pi up to exactly 2pi's neighbour and give +pi; fold it back.
    return np.where(w >= np.pi, w - 2.0 * np.pi, w)
