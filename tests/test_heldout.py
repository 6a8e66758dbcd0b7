"""The held-out benchmark's bookkeeping: which cells miss a target, and the smoother that keeps every pose."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from benchmarks.heldout import ESTIMATORS, SO_FAR_WINDOW, TARGETS, Cell, scored_figures, worst
from online_slam.estimators.smoother.config import SmootherConfig, WindowConfig
from online_slam.pipeline import replay
from online_slam.pipeline.config import ReplayConfig
from online_slam.sources.worlds import GridConfig, grid_world


def _cell(held_out: bool, online: float, nees: float) -> Cell:
    online_m, mean_nees = {"ekf": 0.1, "smoother": online}, {"ekf": nees, "smoother": 2.0}
    final = {"ekf": 0.1, "smoother": 0.1, "batch": 0.1}
    return Cell("fit first, score second", held_out, 3, online_m, final, mean_nees)


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


def test_figures_over_a_span_are_the_replays_own_over_all_of_it_and_its_steps_over_a_part() -> None:
    events = list(grid_world(GridConfig(poses=120, seed=5)))
    results = replay(events, ReplayConfig(estimators=ESTIMATORS), name="spans")
    t = results.series["ekf"].t
    online, final, nees = scored_figures(results, (float(t[0]), float(np.nextafter(t[-1], np.inf))))
    for k in ("ekf", "smoother"):
        assert online[k] == pytest.approx(results.estimators[k].online_rmse_m, rel=1e-12)
        assert nees[k] == pytest.approx(results.estimators[k].nees_mean, rel=1e-12)
    for k in ESTIMATORS:
        assert final[k] == pytest.approx(results.estimators[k].final_rmse_m, rel=1e-12)
    later = (float(t[60]), float(np.nextafter(t[-1], np.inf)))
    online, final, nees = scored_figures(results, later)
    errors = results.series["smoother"].position_error_m[60:]
    assert online["smoother"] == pytest.approx(np.sqrt(np.mean(errors**2)), rel=1e-12)
    assert nees["ekf"] == pytest.approx(np.mean(results.series["ekf"].nees[60:]), rel=1e-12)
    assert final["batch"] != pytest.approx(results.estimators["batch"].final_rmse_m, rel=1e-6)  # a part, not all


def test_a_whole_run_cell_is_held_out_but_counted_apart_from_the_replays_of_a_part() -> None:
    half = _cell(True, 0.6, 2.0)
    whole = replace(_cell(True, 0.1, 2.0), whole_run=True)
    assert whole.misses() is False and half.misses()
    assert worst([half, whole])["online_m"] == 0.6
    assert worst([half, whole], whole_run=True)["online_m"] == 0.1
