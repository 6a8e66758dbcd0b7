"""Outputs of a replay of several robots: a TUM file per robot and trajectory, a Rerun recording with every
robot in its own colour, and compare and sweep on a stream of several robots."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import online_slam
from online_slam import ReplayConfig
from online_slam.sinks.tum import write_tum
from online_slam.sources import MeetConfig, meet_world

SMALL_MEET = MeetConfig(robots=3, poses=60, landmarks=30)


def read_tum(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) and positions (N, 2) of a TUM file."""
    rows = np.loadtxt(path, comments="#", ndmin=2)
    return rows[:, 0], rows[:, 1:3]


def ape(truth: Path, estimate: Path) -> float:
    """Position RMSE of an estimate file against a truth file, poses matched by time (as evo_ape does)."""
    t_true, p_true = read_tum(truth)
    t_est, p_est = read_tum(estimate)
    common, i, j = np.intersect1d(t_true, t_est, return_indices=True)
    assert len(common) == len(t_est)
    return float(np.sqrt(np.mean(np.sum((p_true[i] - p_est[j]) ** 2, axis=1))))


@pytest.mark.parametrize("alignment", ["anchor", "se2"])
def test_tum_files_per_robot_give_each_robots_figures(tmp_path: Path, alignment: str) -> None:
    results = online_slam.replay(meet_world(SMALL_MEET), ReplayConfig(estimators=("ekf", "batch"), alignment=alignment))
    written = write_tum(tmp_path, results)
    robots = ["1", "2", "3"]
    names = ["truth", "odometry", "ekf", "ekf_online", "batch"]
    assert sorted(p.name for p in written) == sorted(f"{n}_robot{r}.tum" for n in names for r in robots)
    figures = results.to_json()["estimators"]
    for robot in robots:
        truth = tmp_path / f"truth_robot{robot}.tum"
        assert len(read_tum(truth)[0]) == SMALL_MEET.poses
        for name in ("ekf", "batch"):
            mine = figures[name]["robots"][robot]
            assert ape(truth, tmp_path / f"{name}_robot{robot}.tum") == pytest.approx(mine["final_rmse_m"], abs=1e-9)
        online = ape(truth, tmp_path / f"ekf_online_robot{robot}.tum")
        assert online == pytest.approx(figures["ekf"]["robots"][robot]["online_rmse_m"], abs=1e-9)


def test_tum_files_of_one_robot_keep_their_names(tmp_path: Path) -> None:
    results = online_slam.replay("square", ReplayConfig(estimators=("ekf",)))
    assert results.step_robots == ()
    names = sorted(p.name for p in write_tum(tmp_path, results))
    assert names == ["ekf.tum", "ekf_online.tum", "odometry.tum", "truth.tum"]
