"""Fitting a stream's noise to its truth: how much its declared covariances should be scaled (``--noise fit``).

Any stream with truth poses (and, for sightings, landmark truth) can be checked: the front-end turns it into
steps as a replay would (every scale at 1), and

- each odometry increment between two poses with truth is compared with the increment between the true poses
  (the estimators' residual ``between(a, b) - delta``, angle wrapped). Its squared Mahalanobis distance ``q``
  under the declared covariance has mean 3 if the covariances are right; the maximum-likelihood scale of the
  covariances is ``mean(q) / 3``. Over ``n`` increments composed (covariances propagated) the same figure
  tells whether errors add up as independent ones do: it grows with ``n`` when they are correlated (a bias, slip
  that lasts), which no scale of the per-step covariances models;
- each landmark sighting from a pose with truth, of a landmark with truth, is compared with the range and
  bearing of the true landmark from the true pose. The scale is robust, ``median(q) / (2 ln 2)`` (the median of
  a chi-square of 2 dof): a few sightings carry another landmark's id and would dominate a mean, and the
  estimators' gates reject them anyway. The per-landmark bias (root mean square over landmarks of each one's
  median residual) shows errors that repeated sightings do not average out.

Per component the fit gives the residuals' spread (a standard deviation for odometry, 1.4826 x the median
absolute deviation for sightings), their median (a bias) and the declared standard deviation (root mean square),
so that a user sees which component is off. Truth only calibrates here; no estimator sees it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.frontend.steps import GroundTruth, Step
from online_slam.geometry.angles import wrap
from online_slam.models.motion import compose_increments, odometry_residual_with_jacobians
from online_slam.models.range_bearing import range_bearing

Array = NDArray[np.float64]

MAD_TO_SIGMA = 1.4826
"""Ratio of a Gaussian's standard deviation to its median absolute deviation."""
HORIZONS = (1, 10, 100)
"""Numbers of increments composed for the odometry scale (1: per step, the scale applied)."""
ODOMETRY_AXES = (("x", "m"), ("y", "m"), ("theta", "rad"))
SIGHTING_AXES = (("range", "m"), ("bearing", "rad"))


@dataclass(frozen=True)
class ComponentFit:
    """One component's residuals against truth."""

    name: str
    """``x``, ``y``, ``theta``, ``range`` or ``bearing``."""
    unit: str
    """``m`` or ``rad``."""
    sigma: float
    """Spread of the residuals (odometry: standard deviation; sightings: 1.4826 x median absolute deviation)."""
    declared: float
    """Root mean square of the declared standard deviations."""
    bias: float
    """Median residual (measured minus true)."""


@dataclass(frozen=True)
class NoiseFit:
    """A stream's noise against its truth, and the scales that fit it."""

    increments: int
    """Odometry increments with truth at both ends."""
    sightings: int
    """Landmark sightings from a pose with truth, of a landmark with truth."""
    odometry: tuple[ComponentFit, ...]
    """x, y, theta of the increments (empty without increments)."""
    sensor: tuple[ComponentFit, ...]
    """Range, bearing of the sightings (empty without sightings)."""
    odometry_scale: float
    """Maximum-likelihood scale of the odometry covariances, per increment (1 without increments)."""
    horizon_scales: dict[int, float]
    """The same over n increments composed, by n (the horizons the stream is long enough for)."""
    sensor_scale: float
    """Robust scale of the sighting covariances (1 without sightings)."""
    landmark_bias: tuple[float, float]
    """Root mean square over landmarks of each one's median range and bearing residual (m, rad)."""
    sightings_correlated: bool = False
    """The source declares (header ``sightings_correlated``) that its sighting sigmas allow for the correlation of
    repeated sightings, so they are wider than one sighting's spread on purpose: the sensor scale is measured and
    shown, not applied."""

    @property
    def applied_sensor_scale(self) -> float:
        """The sensor scale a replay applies: :attr:`sensor_scale`, or 1 for correlated sightings."""
        return 1.0 if self.sightings_correlated else self.sensor_scale

    def flags(self) -> str:
        """The options that replay with these scales."""
        return f"--odometry-noise-scale {self.odometry_scale:.4g} --sensor-noise-scale {self.applied_sensor_scale:.4g}"


def fit_noise(steps: Iterable[Step], truth: GroundTruth) -> NoiseFit:
    """Fit the scales of a stream's covariances to its truth.

    Args:
        steps: The stream's steps (a front-end's, all scales at 1), in order; consumed.
        truth: The truth the front-end gathered from them (complete once ``steps`` is).

    Raises:
        OnlineSlamError: The stream has neither an increment nor a sighting with truth to compare.
    """
    steps = list(steps)
    chains = _chains(steps)
    known = truth.poses
    increments = [(a, b) for chain in chains for a, b in zip(chain, chain[1:]) if a.index in known and b.index in known]
    sightings = _sighting_residuals(steps, truth)
    if not increments and not len(sightings[0]):
        raise OnlineSlamError(
            "--noise fit: the source has no truth to fit to (truth poses at two consecutive poses, or a truth "
            "pose and the landmark truth of a sighting)"
        )
    odometry, odometry_scale = _odometry_fit(increments, truth) if increments else ((), 1.0)
    horizons = {n: scale for n in HORIZONS[1:] if (scale := _horizon_scale(chains, truth, n)) is not None}
    sensor, sensor_scale, landmark_bias = _sensor_fit(*sightings) if len(sightings[0]) else ((), 1.0, (0.0, 0.0))
    return NoiseFit(
        increments=len(increments),
        sightings=len(sightings[0]),
        odometry=odometry,
        sensor=sensor,
        odometry_scale=odometry_scale,
        horizon_scales={1: odometry_scale, **horizons} if increments else {},
        sensor_scale=sensor_scale,
        landmark_bias=landmark_bias,
    )


def _chains(steps: list[Step]) -> list[list[Step]]:
    """Each robot's steps in order (one chain for a stream of one robot): an increment joins a step to the previous
    step of its robot, not to the previous index."""
    chains: dict[object, list[Step]] = {}
    for step in steps:
        chains.setdefault(step.robot, []).append(step)
    return list(chains.values())


def _odometry_fit(pairs: list[tuple[Step, Step]], truth: GroundTruth) -> tuple[tuple[ComponentFit, ...], float]:
    """Per-component figures of the increments (a robot's step and its next) with truth at both ends, and their
    maximum-likelihood scale."""
    before = np.array([truth.poses[a.index] for a, _ in pairs])
    after = np.array([truth.poses[b.index] for _, b in pairs])
    delta = np.array([b.odometry for _, b in pairs])
    cov = np.array([b.odometry_cov for _, b in pairs])
    errors = odometry_residual_with_jacobians(before, after, delta)[0]
    q = np.einsum("ki,ki->k", errors, np.linalg.solve(cov, errors[..., None])[..., 0])
    variances = np.diagonal(cov, axis1=1, axis2=2)
    components = tuple(
        ComponentFit(
            name, unit, float(np.std(errors[:, j])), _rms_sigma(variances[:, j]), float(np.median(errors[:, j]))
        )
        for j, (name, unit) in enumerate(ODOMETRY_AXES)
    )
    return components, float(np.mean(q)) / 3.0


def _horizon_scale(chains: list[list[Step]], truth: GroundTruth, n: int) -> float | None:
    """The odometry scale over n increments of one robot composed (windows that do not overlap); None for fewer
    than 3."""
    q = []
    for steps in chains:
        for first in range(0, len(steps) - n, n):
            a, b = steps[first].index, steps[first + n].index
            if a not in truth.poses or b not in truth.poses:
                continue
            delta, cov = _increment(steps[first + 1])
            for step in steps[first + 2 : first + n + 1]:
                delta, cov = compose_increments(delta, cov, *_increment(step))
            error = odometry_residual_with_jacobians(truth.poses[a], truth.poses[b], delta)[0]
            q.append(float(error @ np.linalg.solve(cov, error)))
    return float(np.mean(q)) / 3.0 if len(q) >= 3 else None


def _increment(step: Step) -> tuple[Array, Array]:
    """A step's odometry increment and its covariance (cast: every step after the first has them)."""
    return cast(Array, step.odometry), cast(Array, step.odometry_cov)


def _sighting_residuals(steps: list[Step], truth: GroundTruth) -> tuple[Array, Array, list]:
    """Residuals (measured - true, bearing wrapped) of the sightings with truth, their covariances, landmarks."""
    errors, covs, ids = [], [], []
    for step in steps:
        pose = truth.poses.get(step.index)
        if pose is None or not np.isfinite(pose[2]):
            continue
        for landmark, z, cov in zip(step.landmarks, step.z, step.z_cov):
            position = truth.landmarks.get(landmark) if landmark is not None else None
            if position is None:
                continue
            error = z - range_bearing(pose, position)
            errors.append((error[0], wrap(error[1])))
            covs.append(cov)
            ids.append(landmark)
    return np.array(errors, dtype=float).reshape(-1, 2), np.array(covs, dtype=float).reshape(-1, 2, 2), ids


def _sensor_fit(errors: Array, covs: Array, ids: list) -> tuple[tuple[ComponentFit, ...], float, tuple[float, float]]:
    """Per-component figures of the sightings, their robust scale and the per-landmark bias."""
    q = np.einsum("ki,ki->k", errors, np.linalg.solve(covs, errors[..., None])[..., 0])
    variances = np.diagonal(covs, axis1=1, axis2=2)
    bias = np.median(errors, axis=0)
    spread = MAD_TO_SIGMA * np.median(np.abs(errors - bias), axis=0)
    components = tuple(
        ComponentFit(name, unit, float(spread[j]), _rms_sigma(variances[:, j]), float(bias[j]))
        for j, (name, unit) in enumerate(SIGHTING_AXES)
    )
    labels = np.array([repr(i) for i in ids])
    medians = np.array([np.median(errors[labels == label], axis=0) for label in np.unique(labels)])
    per_landmark = np.sqrt(np.mean(medians**2, axis=0))
    return components, float(np.median(q)) / (2.0 * math.log(2.0)), (float(per_landmark[0]), float(per_landmark[1]))


def _rms_sigma(variances: Array) -> float:
    """Root mean square of standard deviations given as variances."""
    return float(np.sqrt(np.mean(variances)))


def describe(fit: NoiseFit) -> str:
    """The fit as a user reads it: per-component figures, the scales and the options that apply them."""
    lines = [f"noise fit against truth: {fit.increments} odometry increments, {fit.sightings} landmark sightings"]
    rows = [("", "residual sigma", "declared sigma", "bias")]
    for c in (*fit.odometry, *fit.sensor):
        rows.append((c.name, f"{c.sigma:.4g} {c.unit}", f"{c.declared:.4g} {c.unit}", f"{c.bias:+.3g} {c.unit}"))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    lines += ["  " + "  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
    if fit.horizon_scales:
        over = ", ".join(f"{scale:.3g} over {n}" for n, scale in fit.horizon_scales.items() if n > 1)
        lines.append(
            f"  odometry scale {fit.odometry_scale:.3g} per increment" + (f" ({over} composed)" if over else "")
        )
    if fit.sensor:
        bias_r, bias_b = fit.landmark_bias
        lines.append(
            f"  sensor scale {fit.sensor_scale:.3g} (robust); per-landmark bias {bias_r:.3g} m, {bias_b:.3g} rad"
        )
        if fit.sightings_correlated:
            lines.append(
                "  sensor scale not applied: the source's header says sightings_correlated (its sigmas are widened "
                "on purpose for the correlation of repeated sightings)"
            )
    lines.append(f"replaying with {fit.flags()}")
    return "\n".join(lines)
