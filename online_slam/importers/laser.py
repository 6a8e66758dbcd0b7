"""Landmarks from a 2D laser: a general detector of round objects (tree trunks, posts, reflectors) in one scan,
and the move of a sensor's sightings into the robot frame. Pure functions over arrays.

The detector follows ACFR's tree detector for Victoria Park: a landmark is a run of consecutive returns without
a jump in range. Its diameter is the arc the run subtends (``n`` beams of ``increment`` radians at the run's
mean range), its bearing the middle of the run, and its range the mean range plus half the diameter (the centre
lies a radius behind the face the laser sees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Detector:
    """The detector's settings; each bound is inclusive."""

    jump: float = 1.0
    """Two neighbouring returns further apart in range than this (m) belong to different objects."""
    min_range: float = 0.0
    """Landmarks nearer than this (m, the centre's range) are dropped."""
    max_range: float = math.inf
    """Landmarks farther than this (m) are dropped."""
    min_bearing: float = -math.inf
    """Landmarks at a smaller bearing (rad, in the scan's own angles) are dropped."""
    max_bearing: float = math.inf
    """Landmarks at a larger bearing (rad) are dropped."""
    min_diameter: float = 0.0
    """Objects thinner than this (m) are no landmark (clutter)."""
    max_diameter: float = math.inf
    """Objects wider than this (m) are no landmark (walls, vehicles)."""
    min_intensity: float | None = None
    """Returns weaker than this are no part of an object (reflectors); None: intensity is not read."""
    decimals: int | None = None
    """Round range, bearing and diameter to this many decimals (a log that printed them so), or None."""


def detect(
    ranges: Array, angle_min: float, increment: float, valid_range: tuple[float, float], detector: Detector,
    intensities: Array | None = None,
) -> tuple[Array, NDArray[np.bool_]]:  # fmt: skip
    """The landmarks of one scan: ``(range, bearing, diameter)`` of every object found (k, 3), and which pass the
    limits (k,).

    Args:
        ranges: The scan's ranges (n,), beam ``i`` at angle ``angle_min + i * increment``.
        angle_min, increment: The scan's first angle and its step, radians.
        valid_range: The scanner's ``(range_min, range_max)``: returns outside it are no returns.
        detector: The settings.
        intensities: The returns' intensities (n,), read when ``detector.min_intensity`` is set.
    """
    one = np.ones(1)
    found, keep, _ = detect_many(np.asarray(ranges, dtype=float)[None, :], angle_min * one, increment * one,
                                 valid_range[0] * one, valid_range[1] * one, detector,
                                 None if intensities is None else np.asarray(intensities)[None, :])  # fmt: skip
    return found, keep


def detect_many(
    ranges: Array, angle_min: Array, increment: Array, range_min: Array, range_max: Array, detector: Detector,
    intensities: Array | None = None,
) -> tuple[Array, NDArray[np.bool_], NDArray[np.intp]]:  # fmt: skip
    """:func:`detect` over m scans of n beams at once: ranges (m, n), each scan's angles and valid range (m,).

    Returns:
        Every object found (k, 3), which pass the limits (k,), and the scan each is of (k,), in scan order.
    """
    r = np.asarray(ranges, dtype=float)
    m, n = r.shape
    valid = np.isfinite(r) & (r >= range_min[:, None]) & (r <= range_max[:, None])
    if detector.min_intensity is not None and intensities is not None:
        valid &= np.asarray(intensities, dtype=float) >= detector.min_intensity
    flat = np.flatnonzero(valid)
    if len(flat) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=bool), np.zeros(0, dtype=np.intp)
    scan, beam = np.divmod(flat, n)
    rv = r.ravel()[flat]
    starts = np.empty(len(flat), dtype=bool)
    starts[0] = True
    np.logical_or(np.diff(flat) > 1, np.abs(np.diff(rv)) > detector.jump, out=starts[1:])
    starts[1:] |= np.diff(scan) != 0
    first = np.flatnonzero(starts)
    last = np.empty_like(first)
    last[:-1], last[-1] = first[1:] - 1, len(flat) - 1
    of = scan[first]
    count = (last - first + 1).astype(float)
    mean = np.add.reduceat(rv, first) / count
    diameter = count * increment[of] * mean
    found = np.empty((len(first), 3))
    found[:, 0], found[:, 2] = mean + diameter / 2.0, diameter
    found[:, 1] = angle_min[of] + 0.5 * (beam[first] + beam[last]) * increment[of]
    if detector.decimals is not None:
        found = np.round(found, detector.decimals)
    rng, bearing, d = found.T
    keep = (rng >= detector.min_range) & (rng <= detector.max_range)
    keep &= (bearing >= detector.min_bearing) & (bearing <= detector.max_bearing)
    keep &= (d >= detector.min_diameter) & (d <= detector.max_diameter)
    return found, keep, of


def to_robot_frame(z: Array, mount: tuple[float, float, float], sigma: tuple[float, float]) -> tuple[Array, Array]:
    """Range-bearing sightings of a sensor (k, 2) -> range and bearing from the robot's centre (k, 2), and their
    covariances (k, 2, 2): the sensor's ``sigma = (s_range, s_bearing)`` propagated to first order.

    ``mount`` is the sensor's ``(x, y, theta)`` in the robot frame.
    """
    r, b = z[:, 0], z[:, 1] + mount[2]
    px, py = r * np.cos(b) + mount[0], r * np.sin(b) + mount[1]
    rv = np.hypot(px, py)
    # Jacobian of (rv, bv) w.r.t. (r, b): through the point p = mount + r [cos b, sin b]
    dp = np.stack([np.stack([np.cos(b), -r * np.sin(b)], -1), np.stack([np.sin(b), r * np.cos(b)], -1)], -2)
    dz = np.stack([np.stack([px / rv, py / rv], -1), np.stack([-py / rv**2, px / rv**2], -1)], -2)
    J = dz @ dp
    R = np.diag([sigma[0] ** 2, sigma[1] ** 2])
    cov = J @ R @ np.swapaxes(J, 1, 2)
    return np.stack([rv, np.arctan2(py, px)], -1), 0.5 * (cov + np.swapaxes(cov, 1, 2))
