"""TUM trajectory files (``timestamp tx ty tz qx qy qz qw``) for evo, in the frame the table's errors use.

One file per trajectory: ``truth.tum`` (poses with truth), ``odometry.tum``, ``<estimator>.tum`` (final
estimate) and ``<estimator>_online.tum`` (each pose as estimated when it was the newest). Estimates are moved
by the same rigid transform the table applies (anchor or SE(2) alignment), so ``evo_ape tum truth.tum X.tum``
prints the table's RMSE without any alignment option. z = 0; the quaternion is a rotation about z by the yaw.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.protocol import Estimate
from online_slam.evaluation.metrics import apply_transform
from online_slam.evaluation.results import Results
from online_slam.evaluation.scoring import evaluate
from online_slam.frontend.steps import GroundTruth

Array = NDArray[np.float64]


def tum_lines(times: Array, poses: Array) -> list[str]:
    """TUM rows for planar poses: times (N,), poses (N, 3) -> N lines (full float precision)."""
    half = 0.5 * poses[:, 2]
    zero = np.zeros(len(poses))
    rows = np.column_stack([times, poses[:, 0], poses[:, 1], zero, zero, zero, np.sin(half), np.cos(half)])
    return [" ".join(repr(float(v)) for v in row) for row in rows]


def _file_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name.replace(" ", "_"))


def write_tum(directory: str | Path, results: Results) -> list[Path]:
    """Write the TUM files of a replay; returns their paths.

    Raises:
        OnlineSlamError: The folder cannot be written, or the results have no step times.
    """
    folder = Path(directory)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OnlineSlamError(f"{folder}: cannot create ({exc.strerror or exc})") from None
    times = results.step_times
    if times is None:
        raise OnlineSlamError("--tum: the results hold no step times")
    truth = GroundTruth(
        poses={i: p for i, p in enumerate(results.truth_poses)} if results.truth_poses is not None else {},
        landmarks=dict(results.truth_landmarks),
    )
    truth.poses = {i: p for i, p in truth.poses.items() if np.all(np.isfinite(p))}
    files: dict[str, tuple[Array, Array]] = {}
    if truth.poses:
        idx = np.array(sorted(truth.poses))
        files["truth"] = (times[idx], np.array([truth.poses[i] for i in idx]))

    def moved(estimate: Estimate) -> Array:
        errors = evaluate(estimate, truth, results.alignment)
        return estimate.poses if errors.transform is None else apply_transform(errors.transform, estimate.poses)

    for name, estimate in results.estimates.items():
        files[name] = (times[: len(estimate.poses)], moved(estimate))
        series = results.series.get(name)
        if series is not None:
            online = Estimate(name, series.poses, estimate.landmark_ids, estimate.landmarks)
            files[f"{name}_online"] = (series.t, moved(online))
    written = []
    for name, (t, poses) in files.items():
        path = folder / f"{_file_name(name)}.tum"
        header = f"# online-slam {name}: timestamp tx ty tz qx qy qz qw ({results.alignment} frame of the table)"
        try:
            path.write_text("\n".join([header, *tum_lines(np.asarray(t, float), poses)]) + "\n", encoding="utf-8")
        except OSError as exc:
            raise OnlineSlamError(f"{path}: cannot write ({exc.strerror or exc})") from None
        written.append(path)
    return written
