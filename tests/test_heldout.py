"""The held-out benchmark's bookkeeping: which cells miss a target, and the smoother that keeps every pose."""

from __future__ import annotations

from benchmarks.heldout import SO_FAR_WINDOW, TARGETS, Cell
from online_slam.estimators.smoother.config import SmootherConfig, WindowConfig
from online_slam.pipeline import replay
from online_slam.pipeline.config import ReplayConfig
from online_slam.sources.worlds import GridConfig, grid_world


def _cell(held_out: bool, online: float, nees: float) -> Cell:
    online_m, mean_nees = {"ekf": 0.1, "smoother": online}, {"ekf": nees, "smoother": 2.0}
    return Cell("fit first, score second", held_out, 3, online_m, {}, mean_nees)


def test_a_held_out_cell_misses_a_target_by_either_figure_of_either_estimator() -> None:
    assert not _cell(True, TARGETS["online_m"], TARGETS["nees"]).misses()  # at the targets: met
    assert _cell(True, TARGETS["online_m"] + 0.01, 2.0).misses()
    assert _cell(True, 0.1, TARGETS["nees"] + 0.01).misses()
    assert not _cell(False, 1.0, 20.0).misses()  # in-sample cells are no held-out figures


def test_the_smoother_keeping_every_pose_marginalizes_none_and_ends_where_the_windowed_one_does() -> None:
    events = list(grid_world(GridConfig(poses=150, seed=3)))
    kept = ReplayConfig(estimators=("smoother",), smoother=SmootherConfig(window=WindowConfig(size=SO_FAR_WINDOW)))
    every = replay(events, kept, name="every pose kept")
    windowed = replay(events, ReplayConfig(estimators=("smoother",)), name="windowed")
    assert every.estimates["smoother"].info["marginalized_poses"] == 0
    assert windowed.estimates["smoother"].info["marginalized_poses"] > 100
    assert abs(every.estimators["smoother"].final_rmse_m - windowed.estimators["smoother"].final_rmse_m) < 0.01
