"""Choosing the MRCLAM noise model from data: a maximum-likelihood fit against the Vicon ground truth.

The conversion (:mod:`online_slam.importers.mrclam`) models each odometry increment's error as independent
Gaussians per axis with variance ``a * dt + b * |s| + c * s^2 + floor`` (dt elapsed seconds, s the commanded
path length or turned angle). This module measures, for every robot of a dataset folder, the error of each commanded
increment against the increment between the interpolated Vicon poses at the same two times (in the frame the
commanded increment reaches, as the conversion models it), and fits ``a``, ``b`` and
``c`` per axis by maximum likelihood (``scipy.optimize.minimize`` over the logarithms, so both stay positive).
Range and bearing sigmas are maximum-likelihood fits of the measurement residuals against the Vicon pose and
the surveyed landmark positions, as a Gaussian beside a uniform share of outliers (a few rows carry another
landmark's barcode and would dominate a plain standard deviation); the range's sigma grows linearly with the
measured range (it does: about 0.06 m at 1 m, 0.19 m at 4 m on Dataset 6).

Ground truth is used here to *calibrate* the model once; the conversion itself never uses it to clean data. This fit
builds the conversion's model from the raw commands (elapsed time, path, turn); :mod:`online_slam.evaluation.noise_fit`
then checks any stream, this one included, against its truth and scales its covariances (``--noise fit`` does both).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from online_slam.evaluation.noise_fit import MAD_TO_SIGMA
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers.mrclam import MrclamNoise, _dead_reckoning, _interpolate_truth, _table, load_robot

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MrclamNoiseFit:
    """A fitted MRCLAM noise model and the evidence behind it."""

    noise: MrclamNoise
    """The fitted coefficients (floor and start sigma kept from the defaults)."""
    increments: int
    """Odometry increments used (both ends covered by Vicon)."""
    measurements: int
    """Landmark measurements used (Vicon covers the time, the landmark is surveyed)."""
    range_bias_m: float
    """Median range residual (measured - true), metres."""
    bearing_bias_rad: float
    """Median bearing residual (measured - true), radians."""


def fit_variance(errors: Array, dt: Array, size: Array, floor: float) -> tuple[float, float, float]:
    """Maximum-likelihood ``(a, b, c)`` of ``errors ~ N(0, a * dt + b * |size| + c * size^2 + floor)``.

    Args:
        errors: Increment errors of one axis, shape (N,).
        dt: Elapsed seconds per increment, shape (N,).
        size: Commanded path length (m) or turned angle (rad) per increment, shape (N,).
        floor: Variance added to every increment.

    Returns:
        The coefficients (a per second, b per unit of size, c per squared unit of size); a term the data do not
        support comes out near zero (the lower bound, e^-40).
    """
    e2 = errors**2
    features = np.stack([dt, np.abs(size), size**2], -1)  # (N, 3)

    def negative_log_likelihood(log_abc: Array) -> tuple[float, Array]:
        coefficients = np.exp(log_abc)
        var = features @ coefficients + floor
        value = 0.5 * float(np.sum(np.log(var) + e2 / var))
        d_var = 0.5 * (1.0 / var - e2 / var**2)
        return value, coefficients * (d_var @ features)

    mean_e2 = float(np.mean(e2))
    scale = np.maximum(features.mean(axis=0), 1e-9)
    start = np.log(np.maximum(mean_e2 / (3.0 * scale), 1e-12))
    result = minimize(negative_log_likelihood, start, jac=True, method="L-BFGS-B", bounds=[(-40.0, 10.0)] * 3)
    a, b, c = np.exp(result.x)
    return float(a), float(b), float(c)


def _robot_residuals(root: Path, robot: int, landmark_xy: dict[int, Array]):
    """Odometry increment errors (with dt, path, turn) and measurement residuals of one robot."""
    data = load_robot(root, robot)
    times, kept, kept_subjects = data.times, data.measurements, data.subjects
    poses, path, turn = _dead_reckoning(data.odometry, times)
    commanded = between(poses[:-1], poses[1:])
    true_poses, covered = _interpolate_truth(data.truth, times)
    actual = between(true_poses[:-1], true_poses[1:])
    both = covered[:-1] & covered[1:]
    errors = actual - commanded
    errors[:, 2] = wrap(errors[:, 2])
    # in the frame the commanded increment reaches (the conversion's model: d = d_commanded * Exp(e))
    c, s = np.cos(commanded[:, 2]), np.sin(commanded[:, 2])
    errors[:, 0], errors[:, 1] = c * errors[:, 0] + s * errors[:, 1], -s * errors[:, 0] + c * errors[:, 1]
    odo = (errors[both], np.diff(times)[both], np.diff(path)[both], np.diff(turn)[both])
    # measurement residuals at covered times, surveyed landmarks only
    at, inside = _interpolate_truth(data.truth, kept[:, 0])
    known = np.array([int(s) in landmark_xy for s in kept_subjects], dtype=bool)
    use = inside & known
    pose = at[use]
    xy = np.array([landmark_xy[int(s)] for s in kept_subjects[use]]).reshape(-1, 2)
    d = xy - pose[:, :2]
    true_range = np.hypot(d[:, 0], d[:, 1])
    true_bearing = np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2]
    rows = kept[use]
    return odo, rows[:, 2] - true_range, wrap(rows[:, 3] - true_bearing), rows[:, 2]


def fit_sighting_sigma(residuals: Array, ranges: Array | None = None) -> tuple[float, float]:
    """Maximum-likelihood sigma of sighting residuals, ``sigma = a + b * range`` (``b = 0`` without ranges).

    The residuals are modelled as a mixture: Gaussian ``N(0, sigma^2)`` with probability ``1 - w``, uniform over
    their span with probability ``w`` (a few rows carry another landmark's barcode; without the uniform part they
    would widen the Gaussian). ``a``, ``b`` (and ``w``) are fitted over their logarithms (logit), so they stay
    positive.

    Args:
        residuals: Residuals against the truth, bias removed, shape (N,).
        ranges: Measured ranges, shape (N,), or None for a constant sigma.

    Returns:
        ``(a, b)``: the sigma at zero range and its growth per metre of range.
    """
    span = float(np.ptp(residuals)) or 1.0
    r = np.zeros_like(residuals) if ranges is None else ranges
    spread = MAD_TO_SIGMA * float(np.median(np.abs(residuals)))

    def cost(log_a: float, log_b: float, logit_w: float) -> float:
        sigma = np.exp(log_a) + np.exp(log_b) * r
        w = 1.0 / (1.0 + np.exp(-logit_w))
        gauss = np.exp(-0.5 * (residuals / sigma) ** 2) / (np.sqrt(2.0 * np.pi) * sigma)
        return -float(np.sum(np.log((1.0 - w) * gauss + w / span)))

    if ranges is None:
        best = minimize(lambda q: cost(q[0], -np.inf, q[1]), [np.log(spread / 2.0), -3.0], method="Nelder-Mead")
        return float(np.exp(best.x[0])), 0.0
    start = [np.log(spread / 2.0), np.log(spread / 4.0), -3.0]
    options = {"maxiter": 4000, "xatol": 1e-6, "fatol": 1e-6}
    best = minimize(lambda q: cost(*q), start, method="Nelder-Mead", options=options)
    return float(np.exp(best.x[0])), float(np.exp(best.x[1]))


def fit_mrclam_noise(folder: str | Path, robots: tuple[int, ...] = (1, 2, 3, 4, 5)) -> MrclamNoiseFit:
    """Fit the MRCLAM noise model against Vicon over the given robots of a dataset folder.

    Args:
        folder: The dataset folder (as for :func:`online_slam.importers.mrclam.read_mrclam`).
        robots: Robots whose data enter the fit.

    Returns:
        The fitted model with the number of increments and measurements used.
    """
    root = Path(folder)
    defaults = MrclamNoise()
    landmarks = _table(root / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std"))
    landmark_xy = {int(row[0]): row[1:3] for row in landmarks}
    parts = [_robot_residuals(root, r, landmark_xy) for r in robots]
    errors = np.concatenate([p[0][0] for p in parts])
    dt, path, turn = (np.concatenate([p[0][k] for p in parts]) for k in (1, 2, 3))
    range_residuals = np.concatenate([p[1] for p in parts])
    bearing_residuals = np.concatenate([p[2] for p in parts])
    ranges = np.concatenate([p[3] for p in parts])
    floor = defaults.floor
    x_a, x_b, x_c = fit_variance(errors[:, 0], dt, path, floor)
    y_a, y_b, y_c = fit_variance(errors[:, 1], dt, path, floor)
    t_a, t_b, t_c = fit_variance(errors[:, 2], dt, turn, floor)
    range_bias, bearing_bias = float(np.median(range_residuals)), float(np.median(bearing_residuals))
    range_sigma, range_sigma_per_m = fit_sighting_sigma(range_residuals - range_bias, ranges)
    bearing_sigma, _ = fit_sighting_sigma(bearing_residuals - bearing_bias)
    noise = MrclamNoise(
        x_per_s=x_a,
        x_per_m=x_b,
        x_per_m2=x_c,
        y_per_s=y_a,
        y_per_m=y_b,
        y_per_m2=y_c,
        theta_per_s=t_a,
        theta_per_rad=t_b,
        theta_per_rad2=t_c,
        floor=floor,
        range_sigma=range_sigma,
        range_sigma_per_m=range_sigma_per_m,
        bearing_sigma=bearing_sigma,
        start_sigma=defaults.start_sigma,
    )
    return MrclamNoiseFit(noise, len(errors), len(range_residuals), range_bias, bearing_bias)
