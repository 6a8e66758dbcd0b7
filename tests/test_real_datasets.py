"""Estimators on real data: MRCLAM Dataset 6, every robot, from the raw files (skipped without the data)."""

from __future__ import annotations

import pytest
from conftest import SHARED_DATA, needs_data

from online_slam.pipeline import ReplayConfig, replay

MRCLAM = SHARED_DATA / "MRCLAM_Dataset6"


@pytest.mark.slow
@needs_data("MRCLAM_Dataset6")
@pytest.mark.parametrize("robot", [1, 2, 3, 4, 5])
def test_mrclam_every_estimator_beats_dead_reckoning_and_smoother_and_batch_reach_25_cm(robot: int) -> None:
    # The defaults, no flags (issue 12): global relinearization, batch from the smoother's estimate.
    results = replay(MRCLAM, ReplayConfig(dataset={"robot": robot}))
    dead_reckoning = results.odometry.rmse_m
    ate = {name: r.final_rmse_m for name, r in results.estimators.items()}
    assert all(value < dead_reckoning for value in ate.values()), (ate, dead_reckoning)
    assert ate["smoother"] <= 0.25 and ate["batch"] <= 0.25, ate
