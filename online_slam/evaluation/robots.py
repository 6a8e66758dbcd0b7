"""Figures per robot of a stream of several robots: each robot's poses scored as a whole stream's are, in the
frame and with the alignment of the figures over all robots (so the squares of the robots' errors add up to
theirs). The map is shared: every robot gets the map's landmark RMSE."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.protocol import Estimate
from online_slam.evaluation.metrics import apply_transform, endpoint_gap
from online_slam.evaluation.results import EstimatorResult, Latency, OdometryResult, Series
from online_slam.evaluation.scoring import Errors, nees_band, scored_poses, share_in_bounds
from online_slam.frontend.steps import GroundTruth
from online_slam.sources.events import RobotId

Array = NDArray[np.float64]


def robot_steps(robots: Sequence[RobotId | None]) -> dict[str, NDArray[np.int64]]:
    """The step indices of each robot by its id as text (the JSON key), in order of id (numbers first); {} with
    one."""
    if len(set(robots)) < 2:
        return {}
    order = sorted(set(robots), key=lambda r: (isinstance(r, str), r))
    index = {r: k for k, r in enumerate(order)}
    column = np.fromiter(map(index.__getitem__, robots), dtype=np.int64, count=len(robots))
    return {str(r): np.flatnonzero(column == k) for k, r in enumerate(order)}


def robots_gap(poses: Array, steps: dict[str, NDArray[np.int64]]) -> float:
    """The end gap over several robots: the root mean square of each robot's own (last to first position)."""
    gaps = [endpoint_gap(poses[idx]) for idx in steps.values() if len(idx) and idx[-1] < len(poses)]
    return float(np.sqrt(np.mean(np.square(gaps)))) if gaps else float("nan")


def _rmse(errors: Array) -> float | None:
    """Root mean square of the finite errors (None when there are none)."""
    finite = errors[np.isfinite(errors)]
    return float(np.sqrt(np.mean(finite**2))) if len(finite) else None


def final_errors(estimate: Estimate, truth: GroundTruth, errors: Errors) -> Array:
    """Each pose's position error in the final estimate after the alignment of ``errors`` (NaN without truth)."""
    out = np.full(len(estimate.poses), np.nan)
    if errors.indices is None or errors.transform is None:
        return out
    idx = errors.indices
    moved = apply_transform(errors.transform, scored_poses(estimate.poses, truth, idx))
    out[idx] = np.hypot(*(moved[:, :2] - np.array([truth.poses[i] for i in idx])[:, :2]).T)
    return out


def odometry_per_robot(
    estimate: Estimate, truth: GroundTruth, errors: Errors, steps: dict[str, NDArray[np.int64]]
) -> dict[str, OdometryResult]:
    """Dead reckoning's figures per robot (``steps``: :func:`robot_steps`), in the frame of ``errors``."""
    final = final_errors(estimate, truth, errors)
    return {
        robot: OdometryResult(_rmse(final[idx]), endpoint_gap(estimate.poses[idx]), errors.landmark_rmse_m)
        for robot, idx in steps.items()
    }


def _online(series: Series, steps: NDArray[np.int64], seconds: Array) -> dict[str, Any]:
    """The online figures of one robot's steps."""
    nees = series.nees[steps]
    ms = seconds[steps] * 1e3
    nis = series.nis[steps]
    return {
        "online_rmse_m": _rmse(series.position_error_m[steps]),
        "nees_mean": float(np.nanmean(nees)) if np.isfinite(nees).any() else None,
        "nees_in_bounds": share_in_bounds(nees),
        "nis_mean": float(np.nanmean(nis)) if np.isfinite(nis).any() else None,
        "nis_median": float(np.nanmedian(nis)) if np.isfinite(nis).any() else None,
        "nees_band": nees_band(nees),
        "step_ms": Latency(float(np.median(ms)), float(np.percentile(ms, 95)), float(ms.max())),
    }


def per_robot(
    overall: EstimatorResult,
    estimate: Estimate,
    final: Array,
    series: Series | None,
    seconds: Array,
    steps: dict[str, NDArray[np.int64]],
) -> dict[str, EstimatorResult]:
    """One estimator's figures per robot.

    Args:
        overall: Its figures over all robots (the landmark RMSE is taken from them).
        estimate: Its final estimate, every robot's poses in step order.
        final: Each pose's final position error (:func:`final_errors`), shape (N,).
        series: Its online record, or None (batch).
        seconds: Wall time of each step, shape (N,).
        steps: Each robot's step indices (:func:`robot_steps`).
    """
    out = {}
    for robot, idx in steps.items():
        online = {} if series is None else _online(series, idx, seconds)
        out[robot] = EstimatorResult(
            final_rmse_m=_rmse(final[idx]),
            endpoint_gap_m=endpoint_gap(estimate.poses[idx]),
            landmark_rmse_m=overall.landmark_rmse_m,
            landmarks=overall.landmarks,
            total_s=float(np.sum(seconds[idx])),
            **online,
        )
    return out
