"""TUM trajectory files (``timestamp tx ty tz qx qy qz qw``) for evo, in the frame the table's errors use.

One file per trajectory: ``truth.tum`` (poses with truth), ``odometry.tum``, ``<estimator>.tum`` (final
estimate) and ``<estimator>_online.tum`` (each pose as estimated when it was the newest). Estimates are moved
by the same rigid transform the table applies (anchor or SE(2) alignment), so ``evo_ape tum truth.tum X.tum``
prints the table's RMSE without any alignment option. z = 0; the quaternion is a rotation about z by the yaw.

With several robots each of these is one file per robot, ``<name>_robot<ID>.tum`` (``truth_robot1.tum``,
``ekf_online_robot1.tum``, ...), and no file mixes robots (their poses share timestamps). They are moved by the
transform of the figures over all robots, so evo on a robot's pair prints that robot's figure in the table.
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
    """Write the TUM files of a replay (with several robots, a file per robot and trajectory); returns their paths.

    Raises:
        OnlineSlamError: The folder cannot be written, or the results have no step times.
    """
    folder = Path(directory)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OnlineSlamError(f"{folder}: cannot create ({exc.strerror or exc})") from None
    if results.step_times is None:
        raise OnlineSlamError("--tum: the results hold no step times")
    files = _per_robot(_trajectories(results, results.step_times), results.step_robots)
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


Trajectory = tuple[NDArray[np.int_], Array, Array]
"""Step indices (K,), times (K,) and poses (K, 3) of one trajectory, in the table's frame."""


def _trajectories(results: Results, times: Array) -> dict[str, Trajectory]:
    """Every trajectory of the replay by file name (without ``.tum``), over all robots."""
    truth = GroundTruth(
        poses={i: p for i, p in enumerate(results.truth_poses)} if results.truth_poses is not None else {},
        landmarks=dict(results.truth_landmarks),
        starts=dict(results.truth_starts),
    )
    truth.poses = {i: p for i, p in truth.poses.items() if np.all(np.isfinite(p))}
    files: dict[str, Trajectory] = {}
    if truth.poses:
        idx = np.array(sorted(truth.poses))
        files["truth"] = (idx, times[idx], np.array([truth.poses[i] for i in idx]))

    def moved(estimate: Estimate) -> Array:
        errors = evaluate(estimate, truth, results.alignment)
        return estimate.poses if errors.transform is None else apply_transform(errors.transform, estimate.poses)

    for name, estimate in results.estimates.items():
        n = len(estimate.poses)
        files[name] = (np.arange(n), times[:n], moved(estimate))
        series = results.series.get(name)
        if series is not None:
            online = Estimate(name, series.poses, estimate.landmark_ids, estimate.landmarks)
            files[f"{name}_online"] = (np.arange(len(series.t)), series.t, moved(online))
    return files


def _per_robot(files: dict[str, Trajectory], robots: tuple) -> dict[str, tuple[Array, Array]]:
    """The files to write: each trajectory's times and poses, or with several robots (``robots``, the robot of
    each step) each robot's part of it as ``<name>_robot<ID>``."""
    if not robots:
        return {name: (t, poses) for name, (_, t, poses) in files.items()}
    column = np.array(robots, dtype=object)
    out = {}
    for name, (steps, t, poses) in files.items():
        for robot in dict.fromkeys(robots):
            mine = column[steps] == robot
            out[f"{name}_robot{robot}"] = (t[mine], poses[mine])
    return out
