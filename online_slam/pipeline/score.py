"""Scoring a replay: every estimator's final estimate (batch from the initial values it is given), scored
against the stream's truth, into one :class:`~online_slam.evaluation.results.Results`."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.batch import BatchConfig, BatchEstimator
from online_slam.estimators.protocol import Estimate, Estimator
from online_slam.evaluation.association import AssociationScore, majority, score_association, true_labels, with_true_ids
from online_slam.evaluation.results import (
    EstimatorResult,
    InputReport,
    MapReport,
    OdometryResult,
    Results,
    Series,
    WithoutIdReport,
)
from online_slam.evaluation.robots import final_errors, odometry_per_robot, per_robot, robot_steps, robots_gap
from online_slam.evaluation.scoring import (
    evaluate,
    nees_band,
    online_figures,
    outlier_report,
    share_in_bounds,
    truth_array,
)
from online_slam.pipeline.config import ReplayConfig
from online_slam.pipeline.run import ReplayRun
from online_slam.sources.events import LandmarkId
from online_slam.sources.landmark_map import LandmarkMap, block_diagonal, diagonal_blocks, joint_of

Array = NDArray[np.float64]


def score_run(run: ReplayRun, config: ReplayConfig) -> Results:
    """Finish every estimator of a run (batch last: it may start from another's estimate) and score them."""
    truth = run.engine.frontend.truth
    estimates: dict[str, Estimate] = {"odometry": run.odometry.finish()}
    figures: dict[str, EstimatorResult] = {}
    series: dict[str, Series] = {}
    for estimator in sorted(run.estimators, key=lambda e: isinstance(e, BatchEstimator)):
        started = time.perf_counter()
        initial = initial_values(config.batch, estimates) if isinstance(estimator, BatchEstimator) else None
        if isinstance(estimator, BatchEstimator) and initial is not None:
            estimate = estimator.finish(initial)
        else:
            estimate = estimator.finish()
        final_s = time.perf_counter() - started
        estimates[estimator.name] = estimate
        figures[estimator.name], online = _score_estimator(run, estimator, estimate, final_s, config.alignment)
        if online is not None:
            series[estimator.name] = online
    odometry = evaluate(estimates["odometry"], truth, config.alignment)
    robots = robot_steps(run.odometry.log.robots)
    odometry_gap = robots_gap(estimates["odometry"].poses, robots) if robots else odometry.endpoint_gap_m
    odometry_robots = odometry_per_robot(estimates["odometry"], truth, odometry, robots) if robots else {}
    steps = run.engine.steps
    return Results(
        source=run.source,
        poses=steps,
        landmarks=len(estimates["odometry"].landmark_ids) or len(set(truth.sighting_landmarks.values())),
        observations=run.engine.observations,
        odometry=OdometryResult(odometry.rmse_m, odometry_gap, odometry.landmark_rmse_m, odometry_robots),
        estimators=figures,
        estimates=estimates,
        alignment=config.alignment,
        series=series,
        truth_poses=truth_array(truth, steps),
        truth_offsets=dict(truth.offsets),
        truth_starts=dict(truth.starts),
        truth_landmarks=dict(truth.landmarks),
        error=run.error,
        input=InputReport(
            sum(run.skipped.by_reason.values()),
            run.skipped.by_reason,
            run.engine.frontend.counts.get("after_last_odometry", 0),
        ),
        step_times=np.array(run.step_times, dtype=float),
        robot=header.meta.get("robot") if (header := run.engine.frontend.header) is not None else None,
        left=tuple(run.engine.state.left),
        step_robots=tuple(run.odometry.log.robots) if robots else (),
        warning=run.warning,
        map=map_report(run, estimates),
    )


def map_report(run: ReplayRun, estimates: Mapping[str, Estimate]) -> MapReport:
    """The map started from and the final map: positions of the batch if it ran, else of the smoother, else of the
    EKF; covariances of the smoother, else of the EKF (the batch has none): where those lack a landmark, or are not
    finite, the map's own (a landmark never seen keeps its prior)."""
    loaded = run.landmark_map
    fixed = loaded is not None and run.map_fixed
    online = next((estimates[n] for n in ("smoother", "ekf") if n in estimates), None)
    joint = loaded is not None and loaded.joint is not None and not fixed
    report = MapReport(0 if loaded is None else len(loaded), fixed, run.not_in_map, joint=joint, path=run.map_path)
    if online is None or online.landmark_covs is None:
        return report
    best = next(estimates[n] for n in ("batch", "smoother", "ekf") if n in estimates)
    covs = {lid: c for lid, c in zip(online.landmark_ids, online.landmark_covs)}
    prior = {} if loaded is None else dict(zip(loaded.ids, np.zeros((len(loaded), 2, 2)) if fixed else loaded.cov))
    rows = []
    for lid in best.landmark_ids:
        cov = covs.get(lid)
        rows.append(cov if cov is not None and np.isfinite(cov).all() else prior.get(lid, np.full((2, 2), np.nan)))
    known = [k for k, cov in enumerate(rows) if np.isfinite(cov).all()]  # a landmark without covariance is left out
    covariances = np.array(rows)[known].reshape(-1, 2, 2)
    ids = [best.landmark_ids[k] for k in known]
    final = LandmarkMap.of(ids, best.landmarks[known], covariances, run.source, _joint(online, ids, covariances))
    return dataclasses.replace(report, final=final, positions_from=best.estimator, covariances_from=online.estimator)


def _joint(online: Estimate, ids: list[LandmarkId], covariances: Array) -> Array | None:
    """The online estimate's joint landmark covariance over ``ids`` in their order (a landmark it lacks, or has
    none for: its ``covariances`` block, independent of the others); None when it has none or it is not finite."""
    if online.landmark_joint is None:
        return None
    blocks = diagonal_blocks(online.landmark_joint).reshape(-1, 4)
    where = {lid: k for k, lid in enumerate(online.landmark_ids) if np.isfinite(blocks[k]).all()}
    have = np.array([i for i, lid in enumerate(ids) if lid in where], dtype=np.int64)
    source = np.array([where[ids[i]] for i in have], dtype=np.int64)
    joint = block_diagonal(covariances)
    to = (2 * have[:, None] + np.arange(2)).reshape(-1)
    joint[np.ix_(to, to)] = joint_of(online.landmark_joint, source)
    return joint if np.isfinite(joint).all() else None


def initial_values(batch: BatchConfig, estimates: Mapping[str, Estimate]) -> Estimate | None:
    """The estimate batch starts from, by ``batch.initial``; None for composed odometry.

    ``auto`` takes the (first) smoother's estimate, else the EKF's, else composed odometry.

    Raises:
        OnlineSlamError: The estimator named did not run.
    """
    source = batch.initial
    if source == "auto":
        smoothers = [n for n in estimates if n.startswith("smoother")]
        source = smoothers[0] if smoothers else "ekf" if "ekf" in estimates else "odometry"
    if source == "odometry":
        return None
    if source not in estimates:
        raise OnlineSlamError(f"batch initial values from {source!r}, which did not run")
    return estimates[source]


def _score_estimator(
    run: ReplayRun, estimator: Estimator, estimate: Estimate, final_s: float, alignment: str
) -> tuple[EstimatorResult, Series | None]:
    """One estimator's figures, and its per-step series when it is online."""
    truth = run.engine.frontend.truth
    track = run.tracks[estimator.name]
    details = dict(estimate.info)
    rejected = details.pop("rejected", None)
    labels = details.pop("labels", None)
    outliers = association = None
    scored = estimate
    if labels is not None and run.association != "known":
        association, scored = _score_association(run, estimate, labels)
        rejected = None  # per used sighting, not per stream sighting
    without_id = _without_id(run, estimate, labels) if run.association == "known" else None
    if rejected is not None:
        header = run.engine.frontend.header
        marked = bool(truth.outliers) or bool(header is not None and header.meta.get("contamination"))
        outliers = outlier_report(rejected, truth, marked)
    errors = evaluate(scored, truth, alignment)
    online = None
    if estimator.online:
        online = online_figures(
            estimate, np.array(track.poses), track.covariances, np.array(track.times), np.array(track.nis),
            np.array(track.seconds), truth, alignment,
        )  # fmt: skip
    result = EstimatorResult(
        final_rmse_m=errors.rmse_m,
        endpoint_gap_m=errors.endpoint_gap_m,
        landmark_rmse_m=errors.landmark_rmse_m,
        total_s=float(np.sum(track.seconds)) + final_s,
        online_rmse_m=None if online is None else online.rmse_m,
        nees_mean=None if online is None else online.nees_mean,
        nees_in_bounds=None if online is None else share_in_bounds(online.series.nees),
        nis_mean=None if online is None else _finite_mean(online.series.nis),
        nis_median=None if online is None else _finite_median(online.series.nis),
        nees_band=None if online is None else nees_band(online.series.nees),
        landmarks=errors.landmarks,
        step_ms=None if online is None else online.latency,
        details=details,
        outliers=outliers,
        association=association,
        without_id=without_id,
    )
    steps = robot_steps(run.odometry.log.robots)
    if steps:  # several robots: the same figures per robot
        final = final_errors(scored, truth, errors)
        series = None if online is None else online.series
        robots = per_robot(result, scored, final, series, np.array(track.seconds), steps)
        result = dataclasses.replace(result, robots=robots, endpoint_gap_m=robots_gap(scored.poses, steps))
    return result, None if online is None else online.series


def _score_association(
    run: ReplayRun, estimate: Estimate, labels: Sequence[LandmarkId | None]
) -> tuple[AssociationScore, Estimate]:
    """How an estimator paired sightings, against the stream's (or hidden true) ids; its estimate with landmarks
    named by them."""
    truth = run.engine.frontend.truth
    truth_labels = true_labels(run.sighting_ids, truth.outliers, truth.sighting_landmarks)
    owner = majority(labels, truth_labels)
    association = score_association(run.association, labels, truth_labels, estimate.landmark_ids, owner)
    return association, with_true_ids(estimate, owner)


def _without_id(
    run: ReplayRun, estimate: Estimate, labels: Sequence[LandmarkId | None] | None
) -> WithoutIdReport | None:
    """Under known association: the stream's sightings without an id, and how many the estimator mapped (its
    ``labels``, one per such sighting, where it associated them); None when every sighting has an id."""
    count = run.without_id
    if not count:
        return None
    mapped = set(estimate.landmark_ids)
    used = (
        sum(lid is not None and lid in mapped for lid in labels) if labels is not None and len(labels) == count else 0
    )
    return WithoutIdReport(count, used)


def _finite_mean(values: np.ndarray) -> float | None:
    """Mean of the finite values; None when there are none."""
    return float(np.nanmean(values)) if np.isfinite(values).any() else None


def _finite_median(values: np.ndarray) -> float | None:
    """Median of the finite values; None when there are none."""
    return float(np.nanmedian(values)) if np.isfinite(values).any() else None
