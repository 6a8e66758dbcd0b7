"""Scoring estimates against truth: final and online errors, NEES and its chi-square bounds, latency.

One run's mean NEES is tested against a band that counts the correlation of consecutive steps (a pose's error
drifts slowly, so 1,000 steps hold far fewer independent ones): see :func:`nees_band`.

Everything a table, a JSON file, a plot or a Rerun recording reports is computed here, once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from online_slam.errors import OnlineSlamError
from online_slam.estimators.protocol import Estimate
from online_slam.evaluation.metrics import (
    align_se2,
    anchor_transform,
    apply_transform,
    endpoint_gap,
    landmark_rmse,
    pose_nees,
    position_rmse,
    transform_pose_covariance,
)
from online_slam.evaluation.results import LandmarkCoverage, Latency, NeesBand, OutlierReport, Series
from online_slam.frontend.steps import GroundTruth
from online_slam.models.fix import fixed_point
from online_slam.sources.events import LandmarkId

Array = NDArray[np.float64]
NEES_DOF = 3
"""Pose NEES has 3 degrees of freedom."""


@dataclass(frozen=True)
class Errors:
    """Errors of one trajectory against truth."""

    rmse_m: float | None
    """Position RMSE over poses with truth (None without truth)."""
    landmark_rmse_m: float | None
    """Landmark RMSE over landmarks with truth (None without)."""
    endpoint_gap_m: float
    """Last-to-first position distance of the estimate (needs no truth)."""
    transform: Array | None = None
    """The rigid motion ``[x, y, theta]`` that put the estimate in the truth's frame (None without truth)."""
    indices: NDArray[np.int64] | None = None
    """Poses that had truth."""
    landmarks: LandmarkCoverage | None = None
    """Which landmarks the landmark RMSE covers (None without landmark truth)."""


def evaluate(estimate: Estimate, truth: GroundTruth, alignment: str = "anchor") -> Errors:
    """Compare an estimate with the truth gathered by the front-end.

    Args:
        estimate: A final (or online) estimate.
        truth: Ground truth by step index and landmark id.
        alignment: ``anchor`` (first pose with truth) or ``se2`` (least-squares rigid alignment).

    Returns:
        The errors; RMSEs are None where there is no truth to compare with.
    """
    if alignment not in ("anchor", "se2"):
        raise OnlineSlamError(f"unknown alignment {alignment!r}; expected anchor or se2")
    gap = endpoint_gap(estimate.poses) if len(estimate.poses) else float("nan")
    indices = np.array(sorted(i for i in truth.poses if i < len(estimate.poses)), dtype=np.int64)
    if len(indices) == 0:
        return Errors(None, None, gap)
    true_poses = np.array([truth.poses[i] for i in indices])
    scored = scored_poses(estimate.poses, truth, indices)
    if (alignment == "se2" or np.isnan(true_poses[:, 2]).any()) and len(indices) >= 2:  # no heading: rigid fit
        T = align_se2(scored, true_poses)
    else:
        T = anchor_transform(anchored_pose(scored[0], truth, int(indices[0])), true_poses[0])
    rmse = position_rmse(apply_transform(T, scored), true_poses)
    common = [(k, lid) for k, lid in enumerate(estimate.landmark_ids) if lid in truth.landmarks]
    lm_rmse = None
    if common:
        est = apply_transform(T, estimate.landmarks[[k for k, _ in common]])
        lm_rmse = landmark_rmse(est, np.array([truth.landmarks[lid] for _, lid in common]))
    return Errors(rmse, lm_rmse, gap, T, indices, landmark_coverage(estimate.landmark_ids, truth))


def anchored_pose(scored: Array, truth: GroundTruth, index: int) -> Array:
    """The pose that ``anchor`` puts on the truth of step ``index``: the stream's start prior where it gives that
    step one (the frame every estimator was given), else the estimate's own pose ``scored``.

    Anchoring at the estimate's own first pose scored an estimator that revises it (a smoother, the batch) in a
    frame turned by the revision: on MRCLAM's five robots with 0.1 start priors the batch read 0.110 m anchored
    there against 0.030 m in the start's frame (benchmarks/RESULTS.md, "Errors in the frame the start gives").
    (An antenna's truth has no heading: :func:`evaluate` aligns such streams by SE(2), never here.)"""
    start = truth.starts.get(index)
    return scored if start is None else np.asarray(start, dtype=float)


def scored_poses(poses: Array, truth: GroundTruth, indices: NDArray[np.int64]) -> Array:
    """The estimated poses ``poses[indices]`` as truth compares them: where a truth is of a robot-frame point (a
    GPS antenna, :attr:`GroundTruth.offsets`), that point of the pose with the pose's heading; shape (k, 3)."""
    out = np.array(poses[indices], dtype=float)
    if truth.offsets:
        at = np.array([i in truth.offsets for i in indices.tolist()], dtype=bool)
        if at.any():
            offsets = np.array([truth.offsets[i] for i in indices[at].tolist()])
            out[at, :2] = fixed_point(out[at], offsets)
    return out


def landmark_coverage(ids: Sequence[LandmarkId], truth: GroundTruth) -> LandmarkCoverage | None:
    """Which of an estimate's landmarks (``ids``) have truth, and which true landmarks it lacks (None without
    landmark truth)."""
    if not truth.landmarks:
        return None
    held = set(ids)
    without = tuple(lid for lid in ids if lid not in truth.landmarks)
    missing = tuple(lid for lid in truth.landmarks if lid not in held)
    return LandmarkCoverage(len(ids) - len(without), without, missing)


@dataclass(frozen=True)
class OnlineFigures:
    """What an estimator with real-time estimates is scored on, besides its final estimate."""

    rmse_m: float | None
    """RMSE of each pose as estimated when it was the newest (None without truth)."""
    nees_mean: float | None
    """Mean pose NEES over steps with truth and a covariance (None where there is none)."""
    latency: Latency
    """Wall time per step."""
    series: Series
    """Per-step figures (time, pose, error, sigma, NEES, NIS, step time)."""


def online_figures(
    final: Estimate,
    poses: Array,
    covariances: list[Array | None],
    times: Array,
    nis: Array,
    seconds: Array,
    truth: GroundTruth,
    alignment: str,
) -> OnlineFigures:
    """Score the online estimates of one estimator (N steps).

    Args:
        final: Its final estimate (for landmark ids and values).
        poses: The newest pose after each step, shape (N, 3).
        covariances: Its covariance after each step, (3, 3) or None, length N.
        times: Step times, shape (N,).
        nis: Mean NIS of each step's observations (NaN where none), shape (N,).
        seconds: Wall time of each step, shape (N,).
        truth: Ground truth.
        alignment: ``anchor`` or ``se2``, as for the final estimate.
    """
    online = Estimate(final.estimator, poses, final.landmark_ids, final.landmarks)
    errors = evaluate(online, truth, alignment)
    n = len(poses)
    error_m, nees = np.full(n, np.nan), np.full(n, np.nan)
    sigma = np.array([np.sqrt(np.trace(c[:2, :2])) if c is not None else np.nan for c in covariances])
    nees_mean = None
    if errors.indices is not None and errors.transform is not None:
        idx = errors.indices
        true_poses = np.array([truth.poses[i] for i in idx])
        moved = apply_transform(errors.transform, scored_poses(poses, truth, idx))
        error_m[idx] = np.hypot(*(moved[:, :2] - true_poses[:, :2]).T)
        if all(covariances[i] is not None for i in idx):
            covs = transform_pose_covariance(errors.transform, np.array([covariances[i] for i in idx]))
            nees[idx] = pose_nees(moved, covs, true_poses)
            nees_mean = float(np.nanmean(nees)) if np.isfinite(nees).any() else None
    ms = np.asarray(seconds, dtype=float) * 1e3
    latency = Latency(float(np.median(ms)), float(np.percentile(ms, 95)), float(ms.max()))
    position_cov = np.array([c[:2, :2] if c is not None else np.full((2, 2), np.nan) for c in covariances])
    series = Series(
        t=np.asarray(times, dtype=float),
        poses=poses,
        position_error_m=error_m,
        position_sigma_m=sigma,
        position_cov=position_cov.reshape(n, 2, 2),
        nees=nees,
        nis=np.asarray(nis, dtype=float),
        step_ms=ms,
    )
    return OnlineFigures(errors.rmse_m, nees_mean, latency, series)


def position_errors(
    poses: Array,
    truth_poses: Array | None,
    alignment: str,
    offsets: dict[int, Array] | None = None,
    starts: dict[int, Array] | None = None,
) -> Array:
    """Distance of each pose to its true position, after the alignment the table's RMSE uses (:func:`evaluate`).

    Args:
        poses: Estimated poses by step, in the estimator's frame, shape (N, 3).
        truth_poses: True poses by step, NaN rows where there is none (:func:`truth_array`), or None.
        alignment: ``anchor`` or ``se2``.
        offsets: Steps whose truth is of a robot-frame point (:attr:`GroundTruth.offsets`).
        starts: Start priors' poses by step (:attr:`GroundTruth.starts`).

    Returns:
        Shape (N,), NaN where a pose has no truth.
    """
    out = np.full(len(poses), np.nan)
    if truth_poses is None:
        return out
    known = {i: pose for i, pose in enumerate(truth_poses) if np.isfinite(pose[:2]).all()}
    truth = GroundTruth(poses=known, offsets=dict(offsets or {}), starts=dict(starts or {}))
    errors = evaluate(Estimate("", poses, (), np.zeros((0, 2))), truth, alignment)
    if errors.indices is not None and errors.transform is not None:
        idx = errors.indices
        moved = apply_transform(errors.transform, scored_poses(poses, truth, idx))
        out[idx] = np.hypot(*(moved[:, :2] - truth_poses[idx, :2]).T)
    return out


def truth_array(truth: GroundTruth, steps: int) -> Array | None:
    """True poses by step, shape (steps, 3), NaN where a step has none; None without any truth."""
    if not truth.poses:
        return None
    out = np.full((steps, 3), np.nan)
    for i, pose in truth.poses.items():
        if i < steps:
            out[i] = pose
    return out


def nees_bounds(runs: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided bounds on a 3-dof NEES averaged over ``runs`` independent runs."""
    tail = (1.0 - probability) / 2.0
    low, high = chi2.ppf([tail, 1.0 - tail], NEES_DOF * runs) / runs
    return float(low), float(high)


def effective_steps(series: Array) -> float:
    """How many independent values a correlated series is worth: its length over its integrated autocorrelation
    time ``1 + 2 sum rho_k``, summed by Geyer's initial monotone sequence (1992; as MCMC's effective sample size).

    Decision: this, not batch means over blocks. On AR(1) chi-square series (3 dof) whose squared components
    correlate at 0.5 to 0.9 from step to step, the band it gives covered the true mean about 95% of the time
    where batch means (blocks doubled until their means' lag-1 correlation is insignificant) covered 86-92%: with
    the 20 or so blocks a run allows, the spread of block means is itself too noisy. Never more than the length
    (a negative sum counts as independent).

    Args:
        series: Finite values in step order, shape (N,).
    """
    n = len(series)
    deviation = series - series.mean()
    power = float(deviation @ deviation)
    if n < 4 or power == 0.0:
        return float(n)
    spectrum = np.fft.rfft(deviation, 2 * n)
    rho = np.fft.irfft(spectrum * np.conj(spectrum))[:n] / power
    pairs = rho[: 2 * ((n - 1) // 2)].reshape(-1, 2).sum(axis=1)  # rho_0 + rho_1, rho_2 + rho_3, ...
    positive = np.flatnonzero(pairs <= 0)
    kept = np.minimum.accumulate(pairs[: positive[0] if len(positive) else len(pairs)])
    time = max(2.0 * float(kept.sum()) - 1.0, 1.0)
    return n / time


def nees_band(nees: Array, probability: float = 0.95) -> NeesBand | None:
    """The two-sided band of one run's mean NEES (3 dof) for a consistent estimator, its steps' correlation
    counted: the chi-square band of a mean over :func:`effective_steps` independent steps (None without NEES).

    A lower bound on the width, said so wherever it is shown: a SLAM run's errors share a part that drifts over
    the whole run (the map's and the frame's), which no one run can measure; runs over noise seeds
    (``compare --runs``) measure it. Steps are in order; those without a NEES (NaN) are left out.
    """
    finite = np.asarray(nees, dtype=float)
    finite = finite[np.isfinite(finite)]
    if len(finite) == 0:
        return None
    effective = effective_steps(finite)
    tail = (1.0 - probability) / 2.0
    low, high = chi2.ppf([tail, 1.0 - tail], NEES_DOF * effective) / effective
    return NeesBand(float(low), float(high), len(finite), effective)


def share_in_bounds(nees: Array, runs: int = 1) -> float | None:
    """Fraction of finite per-step NEES values inside the two-sided 95% bounds (None if there are none)."""
    finite = nees[np.isfinite(nees)]
    if len(finite) == 0:
        return None
    low, high = nees_bounds(runs)
    return float(np.mean((finite >= low) & (finite <= high)))


def outlier_report(rejected: NDArray[np.bool_], truth: GroundTruth, marked: bool) -> OutlierReport:
    """Score an estimator's outlier decisions (one per sighting, in step order) against the stream's marks.

    Args:
        rejected: True where the estimator rejected the sighting, shape (n_sightings,).
        truth: Ground truth, with the marks of corrupted sightings by sighting number.
        marked: True when the stream marks its outliers (a contaminated simulation), so counts are meaningful.
    """
    rejected = np.asarray(rejected, dtype=bool)
    if not marked:
        return OutlierReport(int(rejected.sum()), len(rejected))
    truly = np.zeros(len(rejected), dtype=bool)
    marks = np.array([k for k in truth.outliers if k < len(rejected)], dtype=np.int64)
    truly[marks] = True
    return OutlierReport(
        rejected=int(rejected.sum()),
        sightings=len(rejected),
        true_outliers=int(truly.sum()),
        caught=int((rejected & truly).sum()),
        inliers_lost=int((rejected & ~truly).sum()),
    )
