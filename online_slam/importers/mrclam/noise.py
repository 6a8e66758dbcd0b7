"""Choosing the MRCLAM noise model from data: maximum-likelihood fits against the Vicon ground truth.

The conversion (:mod:`online_slam.importers.mrclam`) models the data in four parts, each fitted here over every
robot of a dataset folder:

- **the commands' calibration**: motion follows a command ``command_lag_s`` after its timestamp (the lag that
  minimizes the heading error of 1 s windows), and covers ``speed_scale`` and ``turn_scale`` of the commanded
  distance and turn (least squares over 5 s windows, long enough that the lag hardly matters), the speed slowed
  by turning (``speed_per_turn``, the loss that leaves the least forward error);
- **the increments' noise**: per increment, forward and lateral variances ``x_per_s dt + x_per_m2 s^2`` (and
  ``y_...``) along the axes of the pose it reaches, and heading variance ``theta_per_s dt + theta_per_rad |turn|``
  accrued along its commands (each piece's heading noise turning the rest of its path), ``floor`` added to each
  and not fitted; the six terms by maximum likelihood of the full 3x3 covariances (``scipy.optimize.minimize``
  over their logarithms) against the Vicon increments and, beside them, windows of 5-40 s (:data:`WINDOWS_S`):
  the errors are correlated, so a model right for the sub-second increments is too sure over a long stretch
  without sightings, which the conversion turns into one increment;
- **each robot's camera** (:func:`fit_camera`): where it puts a sighting (a logged range is a depth), and its range
  and bearing sigmas as a Gaussian beside a uniform share of outliers (a few rows carry another landmark's
  barcode), the range's growing with the range;
- **robot sightings** (``--robot all``): how much farther a seen robot reads than its Vicon centre
  (:func:`fit_robot_barcode`);
- **the sightings' correlation**: of one landmark's errors with time apart, each residual divided by its camera's
  sigma (two exponentials fitted to the binned products of residual pairs); and sigmas pooled over the robots,
  for a robot without a camera.

Ground truth is used here to *calibrate* the model once; the conversion itself never uses it to clean data.
:mod:`online_slam.evaluation.noise_fit` then checks any stream, this one included, against its truth and scales
its covariances (``--refit`` runs this fit, ``--noise fit`` that check).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import curve_fit, least_squares, minimize

from online_slam.evaluation.noise_fit import MAD_TO_SIGMA
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers._lines import table
from online_slam.importers.mrclam.reader import (
    MrclamNoise,
    RobotData,
    _dead_reckoning,
    _interpolate_truth,
    calibrated,
    levers_of,
    load_robot,
    model_covariances,
    pieces,
    sampled,
)
from online_slam.importers.mrclam.sightings import Camera, base_sigmas, camera_point, correlation, through_camera

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MrclamNoiseFit:
    """A fitted MRCLAM noise model and the evidence behind it."""

    noise: MrclamNoise
    """The fitted model (floor and start sigma kept from the defaults)."""
    increments: int
    """Odometry increments used (both ends covered by Vicon)."""
    measurements: int
    """Landmark measurements used (Vicon covers the time, the landmark is surveyed)."""
    range_bias_m: float
    """Median range residual (measured - true), metres."""
    bearing_bias_rad: float
    """Median bearing residual (measured - true), radians."""
    log_likelihood: float
    """Log-likelihood of the used increments' errors under the fitted odometry model."""


LAGS = np.arange(0.0, 0.505, 0.01)
"""Command lags tried, seconds."""
AS_COMMANDED = MrclamNoise(command_lag_s=0.0, speed_scale=1.0, turn_scale=1.0, speed_per_turn=0.0)
"""A model whose :func:`~online_slam.importers.mrclam.reader.calibrated` leaves the commands as logged."""
SPEED_PER_TURN = np.arange(0.0, 2.001, 0.05)
"""Speed losses per rad/s of turn tried, s/rad."""
WINDOWS_S = (5.0, 10.0, 20.0, 40.0)
"""Lengths of the consecutive, non-overlapping Vicon windows the increments' noise is also fitted on, seconds.
The errors are correlated for tens of seconds (a heading drift), so a model fitted on the sighting increments
alone (most under a second) makes long stretches too certain: under it the mean squared heading error in sigmas
grows from 0.9 over 5 s windows to 1.8 over 40 s, and the pose's squared Mahalanobis distance is 4.6-5.2 (3 if
consistent)."""
WINDOWS_SHARE = 0.5
"""Share of the fit's summed log-likelihood weight on the windows of :data:`WINDOWS_S`, split evenly between the
window lengths whatever their counts (each window's log-likelihood scaled to match); the sighting increments carry
the rest."""
CORRELATION_BINS = np.array([0.0, 0.3, 0.6, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0, 30.0, 50.0, 100.0])
"""Edges (seconds apart) of the bins over which residual pairs are averaged to fit the correlation."""


def _window_times(data: RobotData, commands: np.ndarray, width: float) -> Array:
    """Ends of consecutive windows of ``width`` seconds over the time Vicon and the commands cover."""
    return np.arange(max(data.truth[0, 0], commands[0, 0]) + 1.0, data.truth[-1, 0] - 1.0, width)


def _windows(data: RobotData, commands: np.ndarray, width: float, lag: float) -> tuple[Array, Array]:
    """Commanded and Vicon increments over consecutive windows of ``width`` seconds that Vicon covers."""
    t = _window_times(data, commands, width)
    poses, _, _ = _dead_reckoning(commands, t - lag)
    commanded = between(poses[:-1], poses[1:])
    truth, covered = _interpolate_truth(data.truth, t)
    actual = between(truth[:-1], truth[1:])
    actual[:, 2] = wrap(actual[:, 2])
    both = covered[:-1] & covered[1:]
    return commanded[both], actual[both]


def fit_command_calibration(datas: list[RobotData]) -> tuple[float, float, float, float]:
    """``(command_lag_s, speed_scale, turn_scale, speed_per_turn)`` of the robots' commands against Vicon.

    The lag minimizes the RMS heading error of 1 s windows over :data:`LAGS`. Over 5 s windows at that lag, the
    turn scale is the least-squares ratio of Vicon's turn to the commanded one; the speed's loss per rad/s turned
    minimizes, over :data:`SPEED_PER_TURN`, the RMS forward error left by the least-squares speed scale. Both
    searches are coarse to fine (:func:`_grid_minimum`).
    """

    def heading_rms(lag: float) -> float:
        parts = [_windows(d, d.odometry, 1.0, lag) for d in datas]
        error = np.concatenate([actual[:, 2] - commanded[:, 2] for commanded, actual in parts])
        return float(np.sqrt(np.mean(error**2)))

    lag = _grid_minimum(LAGS, heading_rms)[0]

    def forward_fit(loss: float) -> tuple[float, float, float]:
        slowed = [calibrated(d.odometry, replace(AS_COMMANDED, speed_per_turn=loss)) for d in datas]
        commanded, actual = (np.concatenate(a) for a in zip(*[_windows(d, c, 5.0, lag) for d, c in zip(datas, slowed)]))
        speed = float(commanded[:, 0] @ actual[:, 0] / (commanded[:, 0] @ commanded[:, 0]))
        error = float(np.sqrt(np.mean((actual[:, 0] - speed * commanded[:, 0]) ** 2)))
        turn = float(commanded[:, 2] @ actual[:, 2] / (commanded[:, 2] @ commanded[:, 2]))
        return error, speed, turn

    loss, (_, speed, turn) = _grid_minimum(SPEED_PER_TURN, forward_fit)
    return lag, speed, turn, loss


def _grid_minimum(grid: Array, cost: Callable[[float], Any], stride: int = 5) -> tuple[float, Any]:
    """The point of ``grid`` where ``cost`` is least (compared as given: a tuple by its first item, and so on),
    and its cost: every ``stride``-th point first, then every point around the best of those. The same point as
    the whole grid where the cost has one minimum, for about a third of the evaluations."""
    costs = {i: cost(float(grid[i])) for i in range(0, len(grid), stride)}
    best = min(costs, key=costs.__getitem__)
    for i in range(max(best - stride + 1, 0), min(best + stride, len(grid))):
        if i not in costs:
            costs[i] = cost(float(grid[i]))
    best = min(costs, key=costs.__getitem__)
    return float(grid[best]), costs[best]


@dataclass(frozen=True)
class IncrementErrors:
    """Odometry increments whose two ends Vicon covers, with what the noise model needs of each (K of them)."""

    errors: Array
    """Commanded minus Vicon increment ``[dx, dy, dtheta]`` (earlier pose's frame), shape (K, 3)."""
    commanded: Array
    """Commanded increments, shape (K, 3)."""
    dt: Array
    """Seconds spanned, shape (K,)."""
    path: Array
    """Commanded path length, m, shape (K,)."""
    turn: Array
    """Commanded turn, summed in absolute value, rad, shape (K,)."""
    per_s: Array
    """Covariance of unit heading variance per second accrued along the commands, shape (K, 3, 3)."""
    per_rad: Array
    """The same per radian turned, shape (K, 3, 3)."""

    @classmethod
    def pooled(cls, parts: list[IncrementErrors]) -> IncrementErrors:
        """Several robots' increments as one set."""
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in cls.__dataclass_fields__))


def increment_errors(data: RobotData, commands: Array) -> IncrementErrors:
    """One robot's increments between its pose times from the given (calibrated) commands, against Vicon."""
    times = data.times
    p = pieces(commands, times)
    poses, path, turn = sampled(p)
    commanded = between(poses[:-1], poses[1:])
    truth, covered = _interpolate_truth(data.truth, times)
    errors = commanded - between(truth[:-1], truth[1:])
    errors[:, 2] = wrap(errors[:, 2])
    both = covered[:-1] & covered[1:]
    per_s, per_rad = levers_of(p)
    return IncrementErrors(
        errors[both],
        commanded[both],
        np.diff(times)[both],
        np.diff(path)[both],
        np.diff(turn)[both],
        per_s[both],
        per_rad[both],
    )


def window_errors(data: RobotData, commands: Array, width: float) -> IncrementErrors:
    """:func:`increment_errors` of consecutive, non-overlapping windows of ``width`` seconds instead of the pose
    times, from 1 s after Vicon and the commands start to 1 s before Vicon ends; a window Vicon does not cover at
    both ends is left out."""
    return increment_errors(replace(data, times=_window_times(data, commands, width)), commands)


TERMS = ("x_per_s", "x_per_m2", "y_per_s", "y_per_m2", "theta_per_s", "theta_per_rad")
"""The odometry model's terms that the fit estimates (the others are zero in it)."""


def increment_log_likelihood(noise: MrclamNoise, e: IncrementErrors) -> float:
    """Log-likelihood (up to a constant) of the increments' errors under the noise model's covariances."""
    cov = model_covariances(noise, e.commanded, (e.dt, e.path, e.turn), (e.per_s, e.per_rad))
    _, log_det = np.linalg.slogdet(cov)
    chi2 = np.einsum("ki,ki->k", e.errors, np.linalg.solve(cov, e.errors[..., None])[..., 0])
    return -0.5 * float(np.sum(log_det + chi2))


def fit_increment_terms(e: IncrementErrors, start: MrclamNoise, windows: Sequence[IncrementErrors] = ()) -> MrclamNoise:
    """Maximum-likelihood :data:`TERMS` (the others zero), from ``start``'s values, bounded to ``[e^-40, e^10]``.

    With ``windows`` (increments over longer spans, :func:`window_errors`), a composite likelihood: they carry
    :data:`WINDOWS_SHARE` of the weight, split evenly between them, and ``e`` the rest.
    """
    zero: dict[str, Any] = {"x_per_m": 0.0, "y_per_m": 0.0, "theta_per_rad2": 0.0}
    weights = [1.0] + [WINDOWS_SHARE / (1.0 - WINDOWS_SHARE) * len(e.dt) / (len(w.dt) * len(windows)) for w in windows]

    def model(log_terms: Array) -> MrclamNoise:
        fitted: dict[str, Any] = dict(zip(TERMS, map(float, np.exp(log_terms))))
        return replace(start, **zero, **fitted)

    def cost(log_terms: Array) -> float:
        noise = model(log_terms)
        return -sum(w * increment_log_likelihood(noise, part) for w, part in zip(weights, (e, *windows)))

    first = np.log([max(getattr(start, name), 1e-12) for name in TERMS])
    return model(minimize(cost, first, method="L-BFGS-B", bounds=[(-40.0, 10.0)] * 6).x)


def fit_sighting_correlation(times: Array, subjects: Array, residuals: Array) -> tuple[float, float, float, float]:
    """``(c1, tau1, c2, tau2)`` of ``rho(dt) = c1 exp(-dt / tau1) + c2 exp(-dt / tau2)``, the correlation of
    one landmark's residuals ``dt`` apart (one robot's sightings; concatenate robots with their times offset by
    more than the last bin so that no pair spans two). Pairs up to 100 s apart are averaged in
    :data:`CORRELATION_BINS` and the curve is fitted to the bins' means at their pairs' mean time apart, every
    bin weighted alike (pairs from one stretch are far from independent, so their count is no weight).

    Args:
        times: Sighting times, shape (N,).
        subjects: Landmark of each sighting, shape (N,).
        residuals: Residuals against the truth with the bias removed, shape (N,).
    """
    edges = CORRELATION_BINS
    sums, counts, spans = np.zeros(len(edges) - 1), np.zeros(len(edges) - 1), np.zeros(len(edges) - 1)
    for subject in np.unique(subjects):
        at = np.flatnonzero(subjects == subject)
        t, r = times[at], residuals[at]
        apart = t[None, :] - t[:, None]
        i, j = np.nonzero((apart > 0.0) & (apart < edges[-1]))
        k = np.searchsorted(edges, apart[i, j], side="right") - 1
        np.add.at(sums, k, r[i] * r[j])
        np.add.at(counts, k, 1.0)
        np.add.at(spans, k, apart[i, j])
    used = counts > 0
    mid = spans[used] / counts[used]
    rho = sums[used] / counts[used] / float(np.mean(residuals**2))

    def curve(dt: Array, c1: float, tau1: float, c2: float, tau2: float) -> Array:
        return correlation((c1, tau1, c2, tau2), dt)

    (c1, tau1, c2, tau2), _ = curve_fit(
        curve,
        mid,
        rho,
        p0=(0.5, 2.0, 0.3, 30.0),
        bounds=([0.0, 0.05, 0.0, 5.0], [1.0, 5.0, 1.0, 500.0]),
    )
    return float(c1), float(tau1), float(c2), float(tau2)


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


def _figure(value: float) -> float:
    """A fitted sigma to 3 significant digits; 0 below a nanometre (the fit's floor)."""
    return float(f"{value:.3g}") if value > 1e-9 else 0.0


def fit_camera(data: RobotData, landmark_xy: dict[int, Array]) -> Camera:
    """One robot's camera (:class:`~online_slam.importers.mrclam.sightings.Camera`).

    Where it puts a sighting: the least-squares fit, with a soft-L1 loss (0.1 m scale: a few rows carry another
    landmark's barcode), of the surveyed landmarks' positions in the robot's Vicon frame. How far it errs: the
    sigmas of :func:`fit_sighting_sigma` over the residuals of the sightings so placed.

    Args:
        data: The robot's tables as logged.
        landmark_xy: Surveyed landmark positions by subject.
    """
    rows = data.measurements
    use, pose, xy = _covered(data, landmark_xy)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    seen = np.stack([c * xy[:, 0] + s * xy[:, 1], -s * xy[:, 0] + c * xy[:, 1]], -1)
    logged, bearing = rows[use, 2], rows[use, 3]

    def misfit(q: Array) -> Array:
        x, y = camera_point(tuple(q), logged, bearing)
        return np.concatenate([x - seen[:, 0], y - seen[:, 1]])

    scale, forward, left, bearing_scale = (
        float(f"{v:.4g}") for v in least_squares(misfit, [1.0, 0.0, 0.0, 1.0], loss="soft_l1", f_scale=0.1).x
    )
    placed = Camera(scale, forward, left, bearing_scale, 0.0, 0.0, 0.0)
    _, _, range_residuals, bearing_residuals, ranges = _sighting_residuals(
        replace(data, measurements=through_camera(rows, placed)), landmark_xy
    )
    range_sigma, per_m = fit_sighting_sigma(range_residuals - np.median(range_residuals), ranges)
    bearing_sigma, _ = fit_sighting_sigma(bearing_residuals - np.median(bearing_residuals))
    return replace(
        placed,
        range_sigma=_figure(range_sigma),
        range_sigma_per_m=_figure(per_m),
        bearing_sigma=_figure(bearing_sigma),
    )


def _covered(data: RobotData, landmark_xy: dict[int, Array]) -> tuple[Array, Array, Array]:
    """The sightings of surveyed landmarks at times Vicon covers: their mask (N,), the robot's Vicon pose at each
    (M, 3), and the landmark's offset from it in the world frame (M, 2)."""
    rows, subjects = data.measurements, data.subjects
    at, inside = _interpolate_truth(data.truth, rows[:, 0])
    use = inside & np.array([int(s) in landmark_xy for s in subjects], dtype=bool)
    pose = at[use]
    xy = np.array([landmark_xy[int(s)] for s in subjects[use]]).reshape(-1, 2)
    return use, pose, xy - pose[:, :2]


def _sighting_residuals(data: RobotData, landmark_xy: dict[int, Array]) -> tuple[Array, ...]:
    """Times, subjects, range and bearing residuals and measured ranges of the sightings Vicon covers."""
    use, pose, d = _covered(data, landmark_xy)
    kept, subjects = data.measurements[use], data.subjects[use]
    range_residuals = kept[:, 2] - np.hypot(d[:, 0], d[:, 1])
    bearing_residuals = wrap(kept[:, 3] - (np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2]))
    return kept[:, 0], subjects, range_residuals, bearing_residuals, kept[:, 2]


def fit_robot_barcode(datas: dict[int, RobotData], cameras: dict[int, Camera]) -> float:
    """How much farther a robot reads than its Vicon centre when another robot sights it, m: the median range
    residual of the robots' sightings of each other (placed by the observer's camera) against the two robots'
    Vicon centres, over the pairs whose data are given and the times Vicon covers both; 0 without any."""
    residuals = []
    for robot, data in datas.items():
        rows = through_camera(data.robot_rows, cameras[robot])
        here, inside = _interpolate_truth(data.truth, rows[:, 0])
        for seen in sorted(set(data.robots_seen.tolist()) & datas.keys()):
            mask = data.robots_seen == seen
            there, covered = _interpolate_truth(datas[seen].truth, rows[mask, 0])
            both = inside[mask] & covered
            offset = there[both, :2] - here[mask][both, :2]
            residuals.append(rows[mask][both, 2] - np.hypot(offset[:, 0], offset[:, 1]))
    found = np.concatenate(residuals) if residuals else np.zeros(0)
    return float(np.median(found)) if len(found) else 0.0


def _landmark_xy(root: Path) -> dict[int, Array]:
    landmarks = table(root / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std"))
    return {int(row[0]): row[1:3] for row in landmarks}


def fit_camera_on(folder: str | Path, robot: int, span: tuple[float, float] | None = None) -> Camera:
    """One robot's camera (:func:`fit_camera`) fitted on ``span`` of the recording only (None: all of it)."""
    root = Path(folder)
    return fit_camera(load_robot(root, robot, span), _landmark_xy(root))


def with_camera(noise: MrclamNoise, robot: int, camera: Camera) -> MrclamNoise:
    """The model with ``robot``'s camera replaced."""
    cameras = list(noise.cameras or MrclamNoise().cameras)
    cameras[robot - 1] = camera
    return replace(noise, cameras=tuple(cameras))


def fit_mrclam_noise(
    folder: str | Path, robots: tuple[int, ...] = (1, 2, 3, 4, 5), span: tuple[float, float] | None = None
) -> MrclamNoiseFit:
    """Fit the MRCLAM model (calibration, increments' noise, sightings' noise) against Vicon over the given robots.

    Args:
        folder: The dataset folder (as for :func:`online_slam.importers.mrclam.reader.read_mrclam`).
        robots: Robots whose data enter the fit.
        span: Only this part of the recording, ``(start, end)`` s (e.g. a half:
            :func:`~online_slam.importers.mrclam.reader.half_span`); None: all of it.

    Returns:
        The fitted model with the number of increments and measurements used.
    """
    root = Path(folder)
    defaults = MrclamNoise()
    landmark_xy = _landmark_xy(root)
    datas = [load_robot(root, r, span) for r in robots]
    lag, speed, turn, loss = fit_command_calibration(datas)
    noise = replace(defaults, command_lag_s=lag, speed_scale=speed, turn_scale=turn, speed_per_turn=loss)
    commands = [calibrated(d.odometry, noise) for d in datas]
    errors = IncrementErrors.pooled([increment_errors(d, c) for d, c in zip(datas, commands)])
    windows = [IncrementErrors.pooled([window_errors(d, c, w) for d, c in zip(datas, commands)]) for w in WINDOWS_S]
    noise = fit_increment_terms(errors, noise, windows)
    fitted = [fit_camera(d, landmark_xy) for d in datas]
    cameras = list(defaults.cameras)  # a robot left out of the fit keeps its default camera
    for robot, camera in zip(robots, fitted):
        cameras[robot - 1] = camera
    barcode = fit_robot_barcode(dict(zip(robots, datas)), dict(zip(robots, fitted)))
    noise = replace(noise, cameras=tuple(cameras), robot_barcode_m=round(barcode, 4))
    seen = [replace(d, measurements=through_camera(d.measurements, c)) for d, c in zip(datas, fitted)]
    sightings = [_sighting_residuals(d, landmark_xy) for d in seen]
    # one time line for all robots, 1000 s apart, so that no residual pair spans two robots
    offset = np.cumsum([0.0] + [float(np.ptp(s[0])) + 1000.0 for s in sightings[:-1]])
    times = np.concatenate([s[0] - s[0][0] + o for s, o in zip(sightings, offset)])
    subjects, range_residuals, bearing_residuals, ranges = (
        np.concatenate([s[k] for s in sightings]) for k in (1, 2, 3, 4)
    )
    range_bias, bearing_bias = float(np.median(range_residuals)), float(np.median(bearing_residuals))
    range_sigma, range_sigma_per_m = fit_sighting_sigma(range_residuals - range_bias, ranges)
    bearing_sigma, _ = fit_sighting_sigma(bearing_residuals - bearing_bias)
    # correlations of the inliers (a few rows carry another landmark's barcode), in each camera's sigmas, each
    # robot's own bias removed
    normalized = []
    for (_, _, r, b, at), camera in zip(sightings, fitted):
        sigma = base_sigmas(noise, at, camera)
        normalized.append(((r - np.median(r)) / sigma[:, 0], (b - np.median(b)) / sigma[:, 1]))
    r_c, b_c = (np.concatenate([n[k] for n in normalized]) for k in (0, 1))
    inlier = (np.abs(r_c) < 5.0) & (np.abs(b_c) < 5.0)
    noise = replace(
        noise,
        range_sigma=range_sigma,
        range_sigma_per_m=range_sigma_per_m,
        bearing_sigma=bearing_sigma,
        range_correlation=fit_sighting_correlation(times[inlier], subjects[inlier], r_c[inlier]),
        bearing_correlation=fit_sighting_correlation(times[inlier], subjects[inlier], b_c[inlier]),
    )
    return MrclamNoiseFit(
        noise, len(errors.dt), len(range_residuals), range_bias, bearing_bias, increment_log_likelihood(noise, errors)
    )
