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


@pytest.fixture(scope="module")
def meet_recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, online_slam.Results]:
    pytest.importorskip("rerun", reason="rerun-sdk is not installed")
    pytest.importorskip("datafusion", reason="rerun-sdk[catalog] is not installed")
    from online_slam.pipeline import estimator_names
    from online_slam.sinks.recording import Layout, RerunConfig, RerunSink

    rrd = tmp_path_factory.mktemp("rrd") / "meet.rrd"
    config = ReplayConfig(estimators=("ekf", "batch"))
    sink = RerunSink(RerunConfig(path=str(rrd)), "meet", Layout(*estimator_names(config)))
    return rrd, online_slam.replay(meet_world(SMALL_MEET), config, sinks=[sink])


def test_recording_has_each_robots_entities_in_its_colour(meet_recording) -> None:
    from online_slam.sinks.recording import Recording

    rrd, results = meet_recording
    with Recording(rrd) as recording:
        summary = recording.summary()
        data = set(recording._table(["/world/**"], "step").column_names)  # entities with data on the timeline
    robots = summary.results["recording"]["robots"]
    assert summary.robots == {"1": "robot_1", "2": "robot_2", "3": "robot_3"}
    assert len({robot["color"] for robot in robots.values()}) == 3  # a colour each
    for part in summary.robots.values():
        for root in ("truth", "odometry", "ekf"):
            assert f"/world/{root}/{part}/pose:Arrows2D:origins" in data
            assert f"/world/{root}/{part}/path_recent:LineStrips2D:strips" in data
        assert f"/world/ekf/{part}/pose_cov:LineStrips2D:strips" in data
        assert f"/world/observations/{part}:LineStrips2D:strips" in data
        assert f"/world/robot_sightings/{part}:LineStrips2D:strips" in data
        assert f"/world/batch/{part}/path:LineStrips2D:strips" in data
    assert not {"/world/ekf/pose:Arrows2D:origins", "/world/truth/pose:Arrows2D:origins"} & data  # all per robot
    assert "/world/ekf/landmarks:Points2D:positions" in data  # one shared map


def test_robot_sightings_go_from_the_sighting_pose_to_the_seen_robot(meet_recording) -> None:
    from online_slam.sinks.recording import Recording

    rrd, results = meet_recording
    with Recording(rrd) as recording:
        series = recording.series()
        table = recording._table(["/world/robot_sightings/**"], "step")
    steps = table.column("step").to_pylist()
    lines = 0
    for k, robot in enumerate(("1", "2", "3")):
        strips = table.column(f"/world/robot_sightings/robot_{robot}:LineStrips2D:strips").to_pylist()
        for step, drawn in zip(steps, strips):
            for start, end in drawn or []:
                lines += 1
                assert step % SMALL_MEET.robots == k  # drawn at a step of the sighting robot
                np.testing.assert_allclose(start, series.poses["ekf"][step, :2], atol=1e-4)  # float32
                truth = results.truth_poses
                assert truth is not None
                seen = [truth[i, :2] for i in range(step - step % 3, step - step % 3 + 3) if i != step]
                assert min(np.hypot(*(np.array(end) - p)) for p in seen) < 0.5  # ends at a seen robot
    assert lines > 10
    assert set(series.poses) == {"odometry", "ekf", "truth"}
    assert not np.isnan(series.poses["ekf"]).any()  # every step's pose, from its robot's entity


def test_inspect_a_step_shows_every_robot(meet_recording) -> None:
    from online_slam.sinks.recording import Recording

    rrd, _ = meet_recording
    with Recording(rrd) as recording:
        state = recording.state_at(100)
    assert {f"{name} robot {r}" for name in ("odometry", "ekf", "truth") for r in "123"} == set(state["estimators"])


def test_inspect_lists_the_robots_and_each_ones_figures(meet_recording, capsys: pytest.CaptureFixture) -> None:
    import json

    from online_slam.cli.main import main

    rrd, results = meet_recording
    assert main(["inspect", str(rrd)]) == 0
    text = capsys.readouterr().out
    assert "robots: 1 (entities .../robot_1), 2 (entities .../robot_2), 3 (entities .../robot_3)" in text
    final = results.estimators["ekf"].robots["2"].final_rmse_m
    assert any(line.split()[:2] == ["robot", "2"] and f"{final:.4f}" in line for line in text.splitlines())
    assert main(["inspect", str(rrd), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["robots"] == {r: f"robot_{r}" for r in "123"}


def test_read_recording_names_the_robot_of_every_step(meet_recording) -> None:
    rrd, results = meet_recording
    series = online_slam.read_recording(rrd)
    assert series.robot == tuple(str(r) for r in results.step_robots)
    np.testing.assert_allclose(series.poses["ekf"][:, :2], results.series["ekf"].poses[:, :2], atol=1e-4)
    pandas = pytest.importorskip("pandas")
    frame = series.to_pandas()
    assert isinstance(frame, pandas.DataFrame) and set(frame["robot"]) == {"1", "2", "3"}


@pytest.fixture(scope="module")
def meet_comparison(tmp_path_factory: pytest.TempPathFactory):
    from online_slam.compare import compare
    from online_slam.sources import write_stream

    stream = tmp_path_factory.mktemp("meet") / "meet.jsonl"
    write_stream(stream, meet_world(SMALL_MEET))
    return compare(str(stream))


def test_compare_gives_each_robots_figures_in_table_and_json(meet_comparison) -> None:
    from online_slam.reports.compare_table import format_comparison

    results = meet_comparison.results
    assert results.left == ()  # every estimator takes several robots
    text = format_comparison(meet_comparison)
    figures = meet_comparison.to_json()["estimators"]
    smoother = next(name for name in results.estimators if name.startswith("smoother"))
    for name in ("ekf", smoother, "batch"):
        for robot, mine in results.estimators[name].robots.items():
            assert f"{name}  robot {robot}" in text
            assert figures[name]["robots"][robot]["final_rmse_m"] == mine.final_rmse_m
    assert "left out" not in text


def test_compare_map_draws_a_path_per_robot(meet_comparison) -> None:
    pytest.importorskip("matplotlib")
    from online_slam.reports.plots import comparison_figure

    figure = comparison_figure(meet_comparison)
    ax = next(a for a in figure.axes if a.get_label() == "map")
    n = meet_comparison.results.poses
    paths = [line.get_xydata() for line in ax.get_lines() if len(line.get_xydata()) == n + SMALL_MEET.robots]
    assert len(paths) == 5  # truth, odometry, ekf, smoother, batch: each robot's poses, apart
    for xy in paths:
        assert np.isnan(xy[:, 0]).sum() == SMALL_MEET.robots  # a break after each robot
        steps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
        assert np.nanmax(steps) < 2.0  # no jump from one robot to another


def test_sweep_rows_per_robot_equal_the_replays() -> None:
    from online_slam.sources import WORLDS
    from online_slam.sweep import Cell, _value, run_cell

    cell = Cell("meet", ("ekf", "batch"), seed=WORLDS["meet"].seed)
    rows = {row["estimator"]: row for row in run_cell(cell)}
    assert list(rows) == ["ekf", *(f"ekf robot {r}" for r in "123"), "batch", *(f"batch robot {r}" for r in "123")]
    results = online_slam.replay("meet", cell.config())
    for name in ("ekf", "batch"):
        assert rows[name]["final_rmse_m"] == results.estimators[name].final_rmse_m
        for robot, mine in results.estimators[name].robots.items():
            assert rows[f"{name} robot {robot}"]["final_rmse_m"] == mine.final_rmse_m
            assert rows[f"{name} robot {robot}"]["online_rmse_m"] == mine.online_rmse_m
    assert _value("all", "robot") == "all" and _value("3", "robot") == 3  # MRCLAM --robot all reads back
