"""MRCLAM's sightings: where each robot's camera puts what it sights, and the sigmas the stream gives a sighting,
widened for the errors it shares with the earlier sightings of its landmark (the model: :class:`MrclamNoise`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from online_slam.importers.mrclam.reader import MrclamNoise


@dataclass(frozen=True)
class Camera:
    """One robot's camera, calibrated on Vicon: where it puts what it sights, and how far it errs.

    A logged range ``d`` is, up to the camera's ``scale``, the barcode's depth along the camera's axis (a pinhole
    camera's distance from the barcode's image height), not its distance: with the logged bearing ``b``, the
    barcode sits at ``(forward_m + scale d, left_m + scale d tan(bearing_scale b))`` in the robot's frame
    (:func:`through_camera`). The stream carries that point's range and bearing from the robot's centre.
    """

    scale: float
    """Depth per unit of logged range."""
    forward_m: float
    """The camera's position ahead of the robot's centre, m (Dataset 6: 0.6-9 cm behind it)."""
    left_m: float
    """The camera's position to the left of the robot's centre, m."""
    bearing_scale: float
    """Angle off the camera's axis per unit of logged bearing."""
    range_sigma: float
    """Range standard deviation at zero range, m (the camera's own; the model's ``range_sigma`` is pooled)."""
    range_sigma_per_m: float
    """Growth of the range standard deviation per metre of range, m/m."""
    bearing_sigma: float
    """Bearing standard deviation, rad."""


CAMERAS = (
    Camera(0.9846, -0.04146, -0.004412, 1.014, 0.00213, 0.00707, 0.0137),
    Camera(0.9516, -0.005751, -0.01308, 0.9939, 0.0, 0.00697, 0.00963),
    Camera(0.9885, -0.0518, 0.006502, 0.9873, 0.0, 0.00642, 0.00856),
    Camera(0.9789, -0.09014, 0.06348, 0.9516, 0.0146, 0.00491, 0.0125),
    Camera(0.9787, -0.0399, 0.01482, 0.9857, 0.0, 0.0136, 0.00887),
)
"""The five robots' cameras (:attr:`MrclamNoise.cameras`), fitted on Dataset 6's Vicon by
:func:`~online_slam.importers.mrclam.noise.fit_camera`."""


def base_sigmas(noise: MrclamNoise, ranges: np.ndarray, camera: Camera | None = None) -> np.ndarray:
    """Range and bearing standard deviations (m, rad) of sightings at their ranges, errors independent: the
    camera's when there is one, else the model's. Shape (N, 2)."""
    sigmas = camera or noise
    ranges = np.asarray(ranges, dtype=float)
    return np.stack(
        [sigmas.range_sigma + sigmas.range_sigma_per_m * ranges, np.full(len(ranges), sigmas.bearing_sigma)], -1
    )


def sighting_sigma(noise: MrclamNoise, measured_range: float, camera: Camera | None = None) -> tuple[float, float]:
    """:func:`base_sigmas` of one sighting."""
    range_sigma, bearing_sigma = base_sigmas(noise, np.array([measured_range]), camera)[0]
    return float(range_sigma), float(bearing_sigma)


def correlation(terms: tuple[float, float, float, float], dt: np.ndarray) -> np.ndarray:
    """``c1 exp(-dt / tau1) + c2 exp(-dt / tau2)`` for ``terms = (c1, tau1, c2, tau2)``; 0 where dt is infinite."""
    c1, tau1, c2, tau2 = terms
    dt = np.asarray(dt, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        one = np.where(c1 > 0.0, c1 * np.exp(-dt / max(tau1, 1e-12)), 0.0)
        two = np.where(c2 > 0.0, c2 * np.exp(-dt / max(tau2, 1e-12)), 0.0)
    return np.nan_to_num(one + two, nan=0.0)


def sighting_sigmas(
    noise: MrclamNoise, times: np.ndarray, subjects: np.ndarray, ranges: np.ndarray, camera: Camera | None = None
) -> np.ndarray:
    """Range and bearing sigmas of one robot's sightings, widened for the errors they share with the earlier
    sightings of the same landmark.

    One landmark's errors stay alike for seconds (range errors 0.2 s apart correlate at about 0.55 on Dataset 6,
    20 s apart at 0.14), so counting each sighting as independent multiplies what a landmark seen for a while
    tells. Each sighting's variance is divided by the information it adds, beside the earlier ones of its
    landmark, about a constant seen through errors of :func:`correlation` (two Ornstein-Uhlenbeck processes and
    white noise): a Kalman filter on ``[constant, process 1, process 2]`` per landmark. A landmark's first
    sighting keeps its sigma; a long stare adds little once the slow process dominates; after a long gap a
    sighting counts almost whole again.

    Args:
        noise: The noise model.
        times: Sighting times, sorted, shape (N,).
        subjects: Landmark of each sighting, shape (N,).
        ranges: Measured ranges, shape (N,).
        camera: The robot's camera, whose sigmas replace the model's (:func:`base_sigmas`).

    Returns:
        Sigmas ``[range, bearing]``, shape (N, 2).
    """
    return base_sigmas(noise, ranges, camera) * np.sqrt(sighting_widening(noise, times, subjects))


def sighting_widening(noise: MrclamNoise, times: np.ndarray, subjects: np.ndarray) -> np.ndarray:
    """The factors :func:`sighting_sigmas` widens each sighting's range and bearing variance by
    (:func:`information_factors`), shape (N, 2), each >= 1: what a stream's ``widened`` carries."""
    terms = (noise.range_correlation, noise.bearing_correlation)
    return np.stack([information_factors(times, subjects, t) for t in terms], -1)


def widened_field(factors: np.ndarray) -> tuple[float, float] | None:
    """A sighting's ``widened`` from its row of :func:`sighting_widening` (None where it widens by nothing)."""
    return None if (factors == 1.0).all() else (float(factors[0]), float(factors[1]))


DIFFUSE = 1e8
"""Prior variance of the constant in :func:`information_factors` (unit-variance errors): no prior."""


def information_factors(
    times: np.ndarray, subjects: np.ndarray, terms: tuple[float, float, float, float]
) -> np.ndarray:
    """Per sighting, one over the information it adds about a constant its landmark's sightings share, for errors
    of unit variance correlated as :func:`correlation` with ``terms`` (the rest white): the factor its variance
    is widened by, 1 for a landmark's first sighting and for independent errors.

    Vectorised over landmarks: one Kalman step per sighting rank.

    Args:
        times: Sighting times, shape (N,).
        subjects: Landmark of each sighting, shape (N,).
        terms: ``(c1, tau1, c2, tau2)``.

    Returns:
        Factors >= 1, shape (N,).
    """
    c1, tau1, c2, tau2 = terms
    out = np.ones(len(times))
    if len(times) == 0 or c1 + c2 <= 0.0:
        return out
    white = max(1.0 - c1 - c2, 1e-9)
    order = np.lexsort((times, subjects))
    ordered, at = subjects[order], times[order]
    starts = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    lengths = np.diff(np.r_[starts, len(at)])
    P = np.zeros((len(starts), 3, 3))
    P[:, 0, 0], P[:, 1, 1], P[:, 2, 2] = DIFFUSE, c1, c2
    information = np.full(len(starts), 1.0 / DIFFUSE)
    last = at[starts].copy()
    for rank in range(int(lengths.max())):
        live = np.flatnonzero(lengths > rank)
        rows = starts[live] + rank
        gap = at[rows] - last[live]
        a, b = np.exp(-gap / max(tau1, 1e-12)), np.exp(-gap / max(tau2, 1e-12))
        decay = np.stack([np.ones_like(a), a, b], -1)
        p = P[live] * decay[:, :, None] * decay[:, None, :]
        p[:, 1, 1] += c1 * (1.0 - a**2)
        p[:, 2, 2] += c2 * (1.0 - b**2)
        ph = p.sum(axis=2)  # P H^T with H = [1, 1, 1]
        p = p - ph[:, :, None] * ph[:, None, :] / (ph.sum(axis=1) + white)[:, None, None]
        now = 1.0 / p[:, 0, 0]
        out[order[rows]] = 1.0 / np.maximum(now - information[live], 1e-9)
        P[live], information[live], last[live] = p, now, at[rows]
    return np.maximum(out, 1.0)


def camera_of(noise: MrclamNoise, robot: int) -> Camera | None:
    """The robot's camera in the model (:attr:`MrclamNoise.cameras`), or None when the model has none."""
    return noise.cameras[robot - 1] if len(noise.cameras) >= robot else None


def camera_point(
    placement: tuple[float, float, float, float], logged: np.ndarray, bearing: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where a camera ``(scale, forward_m, left_m, bearing_scale)`` puts sightings of logged range and bearing:
    ``x, y`` in the robot's frame, each shaped as the input (:class:`Camera`)."""
    scale, forward, left, bearing_scale = placement
    depth = scale * logged
    return depth + forward, depth * np.tan(bearing_scale * bearing) + left


def mounting(camera: Camera) -> list[float]:
    """The camera's pose in the robot frame ``[x, y, theta]`` (its axis along the robot's heading), as a stream's
    header declares a sensor."""
    return [float(camera.forward_m), float(camera.left_m), 0.0]


def through_camera(rows: np.ndarray, camera: Camera | None, mounted: bool = False) -> np.ndarray:
    """Sighting rows ``(t, barcode, range, bearing)`` as logged -> the range and bearing of the point the camera
    puts the barcode at (:class:`Camera`), from the robot's centre, or with ``mounted`` from the camera itself
    (:func:`mounting`); unchanged without a camera. Shape (N, 4)."""
    if camera is None:
        return rows
    placement = (camera.scale, 0.0 if mounted else camera.forward_m, 0.0 if mounted else camera.left_m,
                 camera.bearing_scale)  # fmt: skip
    x, y = camera_point(placement, rows[:, 2], rows[:, 3])
    out = np.array(rows, dtype=float)
    out[:, 2], out[:, 3] = np.hypot(x, y), np.arctan2(y, x)
    return out


def camera_sightings(
    noise: MrclamNoise,
    robot: int,
    rows: np.ndarray,
    subjects: np.ndarray,
    range_offset: float = 0.0,
    mounted: bool = False,
) -> tuple[Camera | None, np.ndarray, np.ndarray, np.ndarray]:
    """One robot's sightings as the stream carries them: its camera (None without one), the rows
    ``(t, barcode, range, bearing)`` placed by it (:func:`through_camera`; from the camera itself with
    ``mounted``), their range less ``range_offset``, their widened sigmas (:func:`sighting_sigmas`, ``subjects``
    grouping them; from the ranges to the robot's centre either way) and the variance factors they are widened by
    (:func:`sighting_widening`), shapes (N, 4), (N, 2) and (N, 2)."""
    camera = camera_of(noise, robot)
    centred = np.array(through_camera(rows, camera), dtype=float)
    centred[:, 2] -= range_offset
    widening = sighting_widening(noise, centred[:, 0], subjects)
    sigmas = base_sigmas(noise, centred[:, 2], camera) * np.sqrt(widening)
    if not mounted or camera is None:
        return camera, centred, sigmas, widening
    placed = np.array(through_camera(rows, camera, mounted=True), dtype=float)
    placed[:, 2] -= range_offset
    return camera, placed, sigmas, widening
