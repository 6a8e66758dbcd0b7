"""compare: one table for filter, smoothers and batch; the same numbers as replay; figures; Monte Carlo."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from inprocess import run_cli as cli

import online_slam
from online_slam.compare import CompareConfig, compare, nees_bounds
from online_slam.estimators.presets import smoother_label
from online_slam.estimators.smoother import SmootherConfig, WindowConfig
from online_slam.evaluation.scoring import share_in_bounds
from online_slam.pipeline import ReplayConfig


@pytest.mark.slow
def test_square_table_has_the_article_figures_beside_ekf_and_smoothers() -> None:
    done = cli("compare", "square", "--window", "10,20", "--relinearize-every", "1,5")
    assert done.returncode == 0, done.stderr
    rows = {
        re.split(r"\s{2,}", line.strip())[0]: re.split(r"\s{2,}", line.strip())[1:]
        for line in done.stdout.splitlines()[4:]
        if line.strip()
    }
    assert rows["odometry"][0] == "1.338" and rows["batch"][1] == "0.082"
    grid = {f"smoother W={w}..120 D=18 K={k} invariant" for w in (10, 20) for k in (1, 5)}
    assert set(rows) >= {"ekf", *grid}


@pytest.mark.slow
def test_compare_equals_replay_for_the_same_configuration(tmp_path: Path) -> None:
    from online_slam.sources import GridConfig, grid_world, write_stream

    path = tmp_path / "grid300.jsonl"  # 300 poses: a global relinearization (at 200) and marginalization take part
    write_stream(path, grid_world(GridConfig(poses=300, seed=3)))
    config = ReplayConfig(smoother=SmootherConfig(window=WindowConfig(size=20)))
    replayed = online_slam.replay(path, config)
    compared = compare(path, CompareConfig(windows=(20,), relinearize_every=(1,), replay=config))
    row, ref = compared.rows[smoother_label(config.smoother)], replayed.estimators["smoother"]
    assert compared.results.poses == 300
    for key in ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "endpoint_gap_m", "nees_mean"):
        assert getattr(row, key) == getattr(ref, key)
    for name in ("ekf", "batch"):
        assert compared.rows[name].final_rmse_m == replayed.estimators[name].final_rmse_m
    assert compared.rows["odometry"].final_rmse_m == replayed.odometry.rmse_m


def test_rows_flatten_every_estimators_figures_odometry_first() -> None:
    """Results.rows(): the one flat record compare's table and JSON and the sweep's columns read."""
    results = online_slam.replay("square")
    rows = results.rows()
    assert list(rows) == ["odometry", "ekf", "smoother", "batch"]
    odometry = rows["odometry"]
    assert odometry.online_rmse_m == odometry.final_rmse_m == results.odometry.rmse_m and odometry.total_s == 0.0
    for name, result in results.estimators.items():
        row = rows[name]
        assert (row.final_rmse_m, row.total_s, row.nees_mean) == (result.final_rmse_m, result.total_s, result.nees_mean)
        series = results.series.get(name)
        if series is None:  # batch: no per-step figures
            assert row.step_median_ms is row.nees_in_bounds is row.nis_mean is None
            continue
        assert (row.step_median_ms, row.step_p95_ms, row.step_max_ms) == (
            result.step_ms.median, result.step_ms.p95, result.step_ms.max,
        )  # fmt: skip
        assert row.nees_in_bounds == share_in_bounds(series.nees)
    assert rows["ekf"].nis_mean == float(np.nanmean(results.series["ekf"].nis)) and rows["smoother"].nis_mean is None


@pytest.mark.slow
def test_figures_are_written_and_every_panel_has_content(tmp_path: Path) -> None:
    from PIL import Image

    png = tmp_path / "compare.png"
    done = cli("compare", "square", "--window", "5,20", "--plot", str(png), "--quiet")
    assert done.returncode == 0, done.stderr
    rgb = np.asarray(Image.open(png).convert("RGB"), dtype=float)
    height, width, _ = rgb.shape
    assert width >= 1000 and height >= 800
    colored = rgb.max(axis=2) - rgb.min(axis=2) > 60  # estimator curves are coloured; frames and text are grey
    for quadrant in (colored[: height // 2, : width // 2], colored[: height // 2, width // 2 :],
                     colored[height // 2 :, : width // 2], colored[height // 2 :, width // 2 :]):  # fmt: skip
        assert quadrant.mean() > 0.005  # curves drawn in every panel


@pytest.mark.slow
def test_monte_carlo_50_runs_reports_average_nees_with_bounds(tmp_path: Path) -> None:
    out = tmp_path / "mc.json"
    done = cli("compare", "square", "--runs", "50", "--estimators", "ekf,batch", "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    mc = json.loads(out.read_text())["monte_carlo"]
    assert mc["runs"] == 50 and len(mc["seeds"]) == 50
    low, high = nees_bounds(50)
    assert mc["anees_bounds"] == pytest.approx([low, high])
    assert low <= mc["anees"]["ekf"] <= high
    assert mc["mean"]["batch"]["final_rmse_m"] < mc["mean"]["odometry"]["final_rmse_m"]
    assert mc["std"]["ekf"]["online_rmse_m"] > 0


@pytest.mark.slow
def test_monte_carlo_needs_a_simulated_world(tmp_path: Path) -> None:
    stream = tmp_path / "s.jsonl"
    assert cli("simulate", "square", "-o", str(stream)).returncode == 0
    done = cli("compare", str(stream), "--runs", "3")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "simulated world" in done.stderr.strip().splitlines()[-1]


def test_a_peer_runs_in_monte_carlo_only_and_must_be_known() -> None:
    with pytest.raises(ValueError, match="runs >= 2"):
        CompareConfig(peers=("isam2",))
    with pytest.raises(ValueError, match="isam2"):
        CompareConfig(runs=2, peers=("isam",))
    done = cli("compare", "square", "--peer", "isam2")
    assert done.returncode == 2 and "give --runs 2 or more" in done.stderr


def test_isam2_reports_the_newest_poses_covariance_in_world_axes() -> None:
    """One odometry step from a start heading north: its forward variance lies along y in world axes."""
    pytest.importorskip("gtsam", reason="the 'peers' extra (gtsam) is not installed")
    from online_slam import gtsam_peer
    from online_slam.frontend.steps import FrontEnd
    from online_slam.sources.events import Odometry, Start

    events = [Start(t=0.0, pose=(1.0, 2.0, np.pi / 2)), Odometry(t=1.0, delta=(1.0, 0.0, 0.0), sigma=(0.1, 0.01, 1e-3))]
    run = gtsam_peer.isam2_online(list(FrontEnd().steps(events)), covariances=True, qr=True)
    assert run.poses[1] == pytest.approx([1.0, 3.0, np.pi / 2])
    assert run.covariances is not None
    assert run.covariances[1] == pytest.approx(np.diag([1e-4, 1e-2, 1e-6]), abs=1e-9)


@pytest.mark.slow
def test_monte_carlo_puts_isam2_and_the_ideal_ekf_beside_the_estimators(tmp_path: Path) -> None:
    pytest.importorskip("gtsam", reason="the 'peers' extra (gtsam) is not installed")
    out, png = tmp_path / "mc.json", tmp_path / "mc.png"
    done = cli("compare", "circle", "--runs", "2", "--estimators", "ekf", "--peer", "isam2,ideal", "--json", str(out),
               "--plot", str(png))  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert png.stat().st_size > 0  # the peers drawn in the NEES panel, in the legend
    mc = json.loads(out.read_text())["monte_carlo"]
    assert set(mc["anees"]) == {"ekf", "isam2", "ideal"} and "isam2" not in mc["mean"]  # no row: figures over steps
    assert 1.0 < mc["anees"]["ideal"] < 10.0 and mc["landmark_anees"]["ideal"] > 0.5  # the ideal EKF has a map
    assert abs(mc["position_rmse_m"]["ideal"] - mc["position_rmse_m"]["ekf"]) < 0.05
    assert 1.0 < mc["anees"]["isam2"] < 10.0 and 0.0 < mc["position_rmse_m"]["isam2"] < 1.0
    assert mc["landmark_anees"]["isam2"] is None and len(mc["anees_per_step"]["isam2"]) == 400
    assert re.search(r"^\s+isam2\s+\d+\.\d\d\s+\w+\s+\d+%\s+-\s+\d\.\d{4}", done.stdout, flags=re.M)
