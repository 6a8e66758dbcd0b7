"""The replay pipeline: source -> events -> front-end steps -> estimators -> snapshots -> sinks.

:func:`replay` is the library call behind ``online-slam replay``; it returns one :class:`Results` that the table,
the JSON file and later sinks all read.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import InputError, OnlineSlamError
from online_slam.estimators.batch import BatchConfig, BatchEstimator
from online_slam.estimators.dead_reckoning import DeadReckoning
from online_slam.estimators.ekf import EkfConfig, EkfSlam
from online_slam.estimators.protocol import Estimate, Estimator, Snapshot
from online_slam.estimators.smoother import SlidingWindowSmoother, SmootherConfig
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
from online_slam.evaluation.results import EstimatorResult, Latency, OdometryResult, Results, Series
from online_slam.frontend.steps import FrontEnd, FrontEndConfig, GroundTruth
from online_slam.sinks.protocol import ReplaySink
from online_slam.sources.events import Event
from online_slam.sources.resolve import open_source

Array = NDArray[np.float64]

ESTIMATORS = ("ekf", "smoother", "batch")
"""Names of the estimators ``replay`` can run (all run by default)."""


@dataclass(frozen=True)
class ReplayConfig:
    """What a replay runs and how it is evaluated."""

    estimators: tuple[str, ...] = ESTIMATORS
    """Estimators to run beside dead reckoning, by name."""
    frontend: FrontEndConfig = field(default_factory=FrontEndConfig)
    """How events become steps (keyframing, first-observation-only ablation)."""
    ekf: EkfConfig = field(default_factory=EkfConfig)
    """Settings of the EKF."""
    smoother: SmootherConfig = field(default_factory=SmootherConfig)
    """Settings of the sliding-window smoother."""
    extra_smoothers: tuple[SmootherConfig, ...] = ()
    """Further smoother configurations run side by side, named ``smoother W=<window> K=<relinearize_every>``."""
    batch: BatchConfig = field(default_factory=BatchConfig)
    """Settings of the batch solver."""
    alignment: str = "anchor"
    """Frame for errors: ``anchor`` (first pose with truth) or ``se2`` (least-squares rigid alignment)."""
    dataset: dict = field(default_factory=dict)
    """Options for dataset sources: ``format``, ``robot`` (MRCLAM), ``truth``, ``dt``, ``convention``."""


def make_estimator(name: str, config: ReplayConfig) -> Estimator:
    """Build an estimator by name."""
    if name == "ekf":
        return EkfSlam(config.ekf)
    if name == "smoother":
        return SlidingWindowSmoother(config.smoother)
    if name == "batch":
        return BatchEstimator(config.batch)
    raise OnlineSlamError(f"unknown estimator {name!r}; expected one of {', '.join(ESTIMATORS)}")


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


def evaluate(estimate: Estimate, truth: GroundTruth, alignment: str = "anchor") -> Errors:
    """Compare an estimate with the truth gathered by the front-end.

    Args:
        estimate: A final (or online) estimate.
        truth: Ground truth by step index and landmark id.
        alignment: ``anchor`` or ``se2``.

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
    if alignment == "se2" and len(indices) >= 2:
        T = align_se2(estimate.poses[indices], true_poses)
    else:
        T = anchor_transform(estimate.poses[indices[0]], true_poses[0])
    rmse = position_rmse(apply_transform(T, estimate.poses[indices]), true_poses)
    common = [(k, lid) for k, lid in enumerate(estimate.landmark_ids) if lid in truth.landmarks]
    lm_rmse = None
    if common:
        est = apply_transform(T, estimate.landmarks[[k for k, _ in common]])
        lm_rmse = landmark_rmse(est, np.array([truth.landmarks[lid] for _, lid in common]))
    return Errors(rmse, lm_rmse, gap, T, indices)


@dataclass
class _Track:
    """What the pipeline records of one estimator while it runs."""

    estimator: Estimator
    poses: list[Array] = field(default_factory=list)
    covariances: list[Array | None] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    nis: list[float] = field(default_factory=list)

    def record(self, snapshot: Snapshot, seconds: float) -> None:
        self.poses.append(snapshot.pose)
        self.covariances.append(snapshot.pose_cov)
        self.seconds.append(seconds)
        self.times.append(snapshot.t)
        nis = np.asarray(snapshot.info.get("nis", ()), dtype=float)
        self.nis.append(float(np.nanmean(nis)) if np.isfinite(nis).any() else np.nan)


def _online_figures(track: _Track, final: Estimate, truth: GroundTruth, alignment: str) -> tuple:
    """Online RMSE, mean NEES, latency and the per-step series of an estimator with real-time snapshots."""
    online = Estimate(final.estimator, np.array(track.poses), final.landmark_ids, final.landmarks)
    errors = evaluate(online, truth, alignment)
    n = len(track.poses)
    error_m, nees = np.full(n, np.nan), np.full(n, np.nan)
    sigma = np.array([np.sqrt(np.trace(c[:2, :2])) if c is not None else np.nan for c in track.covariances])
    nees_mean = None
    if errors.indices is not None:
        idx = errors.indices
        true_poses = np.array([truth.poses[i] for i in idx])
        moved = apply_transform(errors.transform, online.poses[idx])
        error_m[idx] = np.hypot(*(moved[:, :2] - true_poses[:, :2]).T)
        if all(track.covariances[i] is not None for i in idx):
            covs = transform_pose_covariance(errors.transform, np.array([track.covariances[i] for i in idx]))
            nees[idx] = pose_nees(moved, covs, true_poses)
            nees_mean = float(np.nanmean(nees)) if np.isfinite(nees).any() else None
    ms = np.array(track.seconds) * 1e3
    latency = Latency(float(np.median(ms)), float(np.percentile(ms, 95)), float(ms.max()))
    series = Series(np.array(track.times), online.poses, error_m, sigma, nees, np.array(track.nis), ms)
    return errors.rmse_m, nees_mean, latency, series


def _truth_array(truth: GroundTruth, steps: int) -> Array | None:
    if not truth.poses:
        return None
    out = np.full((steps, 3), np.nan)
    for i, pose in truth.poses.items():
        if i < steps:
            out[i] = pose
    return out


def replay(
    source: str | Path | Iterable[Event],
    config: ReplayConfig | None = None,
    *,
    name: str | None = None,
    sinks: Sequence[ReplaySink] = (),
) -> Results:
    """Replay a stream through the front-end and the estimators, step by step, and evaluate.

    Args:
        source: A built-in world name, a stream path (``.gz`` allowed), ``-`` for stdin, or an iterable of events.
        config: What to run; defaults run dead reckoning, the EKF, the smoother and the batch solver.
        name: Source name for reports (defaults to the path or world name).
        sinks: Given every step with all estimators' snapshots (``wall_s`` set), then the results.

    Returns:
        The results. When the input turns bad part-way, the results cover every step before the bad line
        and ``Results.error`` holds the message.

    Raises:
        InputError: When the input is bad before the first step is complete (nothing to report).
    """
    cfg = config or ReplayConfig()
    estimators = [make_estimator(n, cfg) for n in cfg.estimators]
    for extra in cfg.extra_smoothers:
        estimators.append(SlidingWindowSmoother(extra, name=f"smoother W={extra.window} K={extra.relinearize_every}"))
    names = [e.name for e in estimators]
    if len(set(names)) != len(names):
        raise OnlineSlamError(f"estimator names repeat: {', '.join(names)}")
    if isinstance(source, (str, Path)):
        label, events = open_source(source, **dict(cfg.dataset))
    else:
        label, events = "<events>", iter(source)
    label = name or label
    frontend = FrontEnd(cfg.frontend)
    odometry = DeadReckoning()
    tracks = [_Track(e) for e in estimators]
    steps = observations = 0
    error: str | None = None
    try:
        for step in frontend.steps(events):
            steps += 1
            observations += len(step.landmarks)
            snapshots = {"odometry": odometry.step(step)}
            for track in tracks:
                started = time.perf_counter()
                snapshot = track.estimator.step(step)
                elapsed = time.perf_counter() - started
                track.record(snapshot, elapsed)
                snapshots[track.estimator.name] = dataclasses.replace(snapshot, wall_s=elapsed) if sinks else snapshot
            for sink in sinks:
                sink.on_step(step, snapshots, frontend.truth)
    except InputError as exc:
        if steps == 0:
            raise
        error = str(exc)
    if steps == 0:
        raise InputError(label, 0, "", "the stream holds no pose")
    estimates: dict[str, Estimate] = {"odometry": odometry.finish()}
    tracks.sort(key=lambda tr: isinstance(tr.estimator, BatchEstimator))  # batch last: it may start from another
    figures: dict[str, EstimatorResult] = {}
    series: dict[str, Series] = {}
    for track in tracks:
        estimator = track.estimator
        started = time.perf_counter()
        initial = estimates.get(cfg.batch.initial) if isinstance(estimator, BatchEstimator) else None
        if isinstance(estimator, BatchEstimator) and cfg.batch.initial != "odometry" and initial is None:
            raise OnlineSlamError(f"batch initial values from {cfg.batch.initial!r}, which did not run")
        estimate = estimator.finish(initial) if initial is not None else estimator.finish()
        final_s = time.perf_counter() - started
        estimates[estimator.name] = estimate
        errors = evaluate(estimate, frontend.truth, cfg.alignment)
        online_rmse = nees_mean = latency = None
        if getattr(estimator, "online", True):
            online_rmse, nees_mean, latency, series[estimator.name] = _online_figures(
                track, estimate, frontend.truth, cfg.alignment
            )
        figures[estimator.name] = EstimatorResult(
            final_rmse_m=errors.rmse_m,
            endpoint_gap_m=errors.endpoint_gap_m,
            landmark_rmse_m=errors.landmark_rmse_m,
            total_s=float(np.sum(track.seconds)) + final_s,
            online_rmse_m=online_rmse,
            nees_mean=nees_mean,
            step_ms=latency,
            details=dict(estimate.info),
        )
    odo = evaluate(estimates["odometry"], frontend.truth, cfg.alignment)
    results = Results(
        source=label,
        poses=steps,
        landmarks=len(estimates["odometry"].landmark_ids),
        observations=observations,
        odometry=OdometryResult(odo.rmse_m, odo.endpoint_gap_m, odo.landmark_rmse_m),
        estimators=figures,
        estimates=estimates,
        alignment=cfg.alignment,
        series=series,
        truth_poses=_truth_array(frontend.truth, steps),
        truth_landmarks=dict(frontend.truth.landmarks),
        error=error,
    )
    for sink in sinks:
        sink.on_finish(results, frontend.truth)
    return results
