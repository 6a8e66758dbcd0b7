"""Position sightings (``xy``: the landmark in the robot frame) through the stream, the engine and every estimator."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from inprocess import run_cli

import online_slam
from online_slam import InputError, ReplayConfig, Slam
from online_slam.estimators import BatchEstimator, EkfSlam, SlidingWindowSmoother, SmootherConfig
from online_slam.estimators.smoother import WindowConfig
from online_slam.frontend import FrontEnd
from online_slam.geometry import wrap
from online_slam.models import POSITION, RANGE_BEARING
from online_slam.sources import GridConfig, Observation, Odometry, Start, grid_world
from online_slam.sources.events import Event
from online_slam.sources.stream import read_stream, write_stream
from online_slam.sources.validate import EventValidator
from online_slam.sources.worlds import Contamination, contaminate, without_ids

XY_GRID = GridConfig(poses=300, seed=5, model="xy")
"""A small grid world sensing positions."""


def mixed(events: Iterator[Event]) -> Iterator[Event]:
    """Every other range-bearing sighting as a position sighting (its covariance propagated to first order)."""
    for k, event in enumerate(events):
        if isinstance(event, Observation) and k % 2:
            r, b = event.range, event.bearing
            J = np.array([[np.cos(b), -r * np.sin(b)], [np.sin(b), r * np.cos(b)]])
            cov = J @ event.covariance @ J.T
            cov = tuple(map(tuple, 0.5 * (cov + cov.T)))
            event = dataclasses.replace(
                event, range=None, bearing=None, sigma=None, cov=cov, xy=(r * np.cos(b), r * np.sin(b))
            )
        yield event


def run_all(events: list[Event], window: int = 20) -> tuple[FrontEnd, dict]:
    fe = FrontEnd()
    estimators = {
        "ekf": EkfSlam(),
        "smoother": SlidingWindowSmoother(SmootherConfig(window=WindowConfig(size=window))),
        "batch": BatchEstimator(),
    }
    for step in fe.steps(iter(events)):
        for estimator in estimators.values():
            estimator.step(step)
    return fe, {name: estimator.finish() for name, estimator in estimators.items()}


def rmse(poses: np.ndarray, fe: FrontEnd) -> float:
    truth = np.array([fe.truth.poses[i] for i in range(len(poses))])
    return float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth[:, :2]) ** 2, axis=1))))


# -- the stream ---------------------------------------------------------------------------------------------------
def test_an_xy_line_round_trips(tmp_path: Path) -> None:
    events = [Start(0.0, (0.0, 0.0, 0.0)), Observation(0.0, 3, sigma=(0.1, 0.2), xy=(1.5, -2.0))]
    path = tmp_path / "xy.jsonl"
    write_stream(path, events)
    line = json.loads(path.read_text().splitlines()[1])
    assert line == {"type": "observation", "t": 0.0, "landmark": 3, "xy": [1.5, -2.0], "sigma": [0.1, 0.2]}
    back = list(read_stream(path))
    assert back == events
    assert back[1].model == POSITION and back[1].z == (1.5, -2.0)


@pytest.mark.parametrize(
    ("record", "field", "message"),
    [
        ({"range": 1.0, "bearing": 0.1, "xy": [1.0, 0.0]}, "xy", "not both"),
        ({"bearing": 0.1, "xy": [1.0, 0.0]}, "xy", "not both"),
        ({}, "range", "give range and bearing, or xy"),
        ({"xy": [1.0]}, "xy", "list of 2 numbers"),
        ({"xy": [1.0, 2.0, 3.0]}, "xy", "list of 2 numbers"),
        ({"xy": 1.0}, "xy", "list of 2 numbers"),
        ({"xy": [1.0, float("nan")]}, "xy[1]", "finite"),
        ({"xy": [float("inf"), 1.0]}, "xy[0]", "finite"),
        ({"xy": ["a", 1.0]}, "xy[0]", "expected a number"),
        ({"xy": [1.0, 2.0], "sigma": [0.1]}, "sigma", "list of 2 numbers"),
        ({"xy": [1.0, 2.0], "cov": [[1.0, 0.0], [0.0, -1.0]]}, "cov", "positive definite"),
        ({"xy": [1.0, 2.0], "sigma": [0.1, 0.1], "cov": [[1.0, 0.0], [0.0, 1.0]]}, "cov", "not both"),
    ],
)
def test_bad_sightings_name_their_field(record: dict, field: str, message: str) -> None:
    line = {"type": "observation", "t": 0.0, "landmark": 1, **record}
    line.setdefault("sigma", [0.1, 0.1]) if "cov" not in record else None
    with pytest.raises(InputError) as caught:
        EventValidator("s.jsonl").parse_record(line, 4)
    assert caught.value.field == field
    assert message in caught.value.message


def test_a_scan_of_positions_is_checked_as_a_whole() -> None:
    validator = EventValidator("scan")
    scan = validator.parse_scan(0.0, [1, 2], None, None, [0.1, 0.1], xy=[[1.0, 2.0], [3.0, -4.0]])
    assert scan.xy == ((1.0, 2.0), (3.0, -4.0)) and scan.ranges == ()
    with pytest.raises(InputError) as caught:
        validator.parse_scan(1.0, [1, 2], None, None, [0.1, 0.1], xy=[[1.0, 2.0], [3.0, float("nan")]])
    assert caught.value.field == "xy[1][1]"
    with pytest.raises(InputError) as caught:
        validator.parse_scan(1.0, [1, 2], [1.0, 2.0], [0.1, 0.2], [0.1, 0.1], xy=[[1.0, 2.0], [3.0, 4.0]])
    assert caught.value.field == "xy"
    with pytest.raises(InputError) as caught:
        validator.parse_scan(1.0, [1, 2], None, None, [0.1, 0.1], xy=[[1.0, 2.0]])
    assert caught.value.field == "xy"
    assert validator.state.last_t == 0.0  # rejected scans changed nothing


# -- the estimators -----------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_every_estimator_converges_on_position_sightings() -> None:
    fe, xy = run_all(list(grid_world(XY_GRID)))
    fe_rb, rb = run_all(list(grid_world(dataclasses.replace(XY_GRID, model="range-bearing"))))
    for name in ("ekf", "smoother", "batch"):
        error, reference = rmse(xy[name].poses, fe), rmse(rb[name].poses, fe_rb)
        assert error < 0.15, name
        assert error < 2.0 * reference + 0.02, name  # comparable to range-bearing sightings of the same world
    assert xy["batch"].info["converged"]
    assert fe.counts["observation"] == fe_rb.counts["observation"]


@pytest.mark.slow
@pytest.mark.parametrize(
    "events",
    [
        lambda: grid_world(dataclasses.replace(XY_GRID, poses=150)),
        lambda: mixed(grid_world(GridConfig(poses=150, seed=5))),
    ],
    ids=["xy", "mixed"],
)
def test_window_covering_the_stream_equals_batch(events) -> None:
    _, out = run_all(list(events()), window=10_000)
    final, batch = out["smoother"], out["batch"]
    assert np.max(np.linalg.norm(final.poses[:, :2] - batch.poses[:, :2], axis=1)) <= 1e-6
    assert np.max(np.abs(wrap(final.poses[:, 2] - batch.poses[:, 2]))) <= 1e-7
    assert np.max(np.linalg.norm(final.landmarks - batch.landmarks, axis=1)) <= 1e-6


@pytest.mark.slow
def test_a_mixed_stream_converges_with_marginalization() -> None:
    events = list(mixed(grid_world(GridConfig(poses=300, seed=5))))
    steps = list(FrontEnd().steps(iter(events)))
    models = np.concatenate([s.z_model for s in steps])
    assert (models == POSITION).any() and (models == RANGE_BEARING).any()
    fe, out = run_all(events, window=10)
    for name in ("ekf", "smoother", "batch"):
        assert rmse(out[name].poses, fe) < 0.2, name


@pytest.mark.slow
def test_unknown_association_on_position_sightings() -> None:
    events = list(without_ids(contaminate(grid_world(XY_GRID), Contamination(clutter=0.05, range_spikes=0.02))))
    results = online_slam.replay(iter(events), ReplayConfig(estimators=("ekf", "smoother")).with_association("jcbb"))
    for name in ("ekf", "smoother"):
        assert results.estimators[name].final_rmse_m < 0.3, name


def test_repeated_sightings_of_both_models_fold_into_one() -> None:
    from online_slam.estimators.smoother.prior import fuse_repeats
    from online_slam.models.position import range_bearing_from_position

    z = np.array([[3.0, 0.5], [3.0 * np.cos(0.5), 3.0 * np.sin(0.5)]])
    cov = np.array([np.diag([0.01, 0.001]), np.diag([0.01, 0.01])])
    indices, fused, fused_cov, model = fuse_repeats(np.array([4, 4]), z, cov, np.array([0, 1], dtype=np.int8))
    assert list(indices) == [4] and list(model) == [RANGE_BEARING]
    rb, rb_cov = range_bearing_from_position(z[1], cov[1])
    info = np.linalg.inv(cov[0]) + np.linalg.inv(rb_cov)
    assert np.allclose(fused_cov[0], np.linalg.inv(info))
    assert np.allclose(fused[0], [3.0, 0.5])


# -- the API and the sinks ----------------------------------------------------------------------------------------
def test_slam_takes_position_sightings() -> None:
    events = list(grid_world(dataclasses.replace(XY_GRID, poses=60)))
    one, scans = Slam("ekf"), Slam("ekf")
    for event in events:
        if isinstance(event, Observation):
            one.add_observation(event.t, event.landmark, xy=np.array(event.xy), sigma=event.sigma)
            scans.add_observations(event.t, [event.landmark], xy=[event.xy], sigma=event.sigma)
        elif isinstance(event, Odometry):
            for slam in (one, scans):
                slam.add_odometry(event.t, event.delta, sigma=event.sigma)
        elif isinstance(event, Start):
            for slam in (one, scans):
                slam.start(event.t, event.pose)
    results = online_slam.replay(iter(events), ReplayConfig(estimators=("ekf",)))
    np.testing.assert_array_equal(one.estimate().trajectory, results.estimates["ekf"].poses)
    np.testing.assert_array_equal(one.estimate().trajectory, scans.estimate().trajectory)
    with pytest.raises(InputError) as caught:
        one.add_observation(1e6, 1, range=1.0, bearing=0.0, xy=[1.0, 0.0], sigma=[0.1, 0.1])
    assert caught.value.field == "xy"
    with pytest.raises(InputError) as caught:
        one.add_observation(1e6, 1, sigma=[0.1, 0.1])
    assert caught.value.field == "range"


@pytest.mark.slow
def test_a_recording_of_position_sightings_reads_back(tmp_path: Path) -> None:
    pytest.importorskip("rerun", reason="rerun-sdk is not installed")
    pytest.importorskip("datafusion", reason="rerun-sdk[catalog] is not installed")
    stream, rrd, out = tmp_path / "xy.jsonl", tmp_path / "xy.rrd", tmp_path / "xy.json"
    write_stream(stream, grid_world(dataclasses.replace(XY_GRID, poses=40)))
    done = run_cli("replay", str(stream), "--rrd", str(rrd), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    series = online_slam.read_recording(rrd)
    assert series.results["poses"] == 40
    results = json.loads(out.read_text())
    assert series.results["estimators"] == results["estimators"]


@pytest.mark.slow
def test_batch_equals_gtsam_on_position_sightings() -> None:
    pytest.importorskip("gtsam", reason="the 'peers' extra (gtsam) is not installed")
    from online_slam import gtsam_peer

    fe, batch = FrontEnd(), BatchEstimator()
    for step in fe.steps(mixed(grid_world(dataclasses.replace(XY_GRID, poses=120, model="range-bearing")))):
        batch.step(step)
    ours = batch.finish()
    graph = batch.log.graph()
    assert (graph.obs_model == POSITION).any()
    peer = gtsam_peer.levenberg_marquardt(graph, np.array(batch.log.poses), batch.log.landmarks, exact=True, tight=True)
    assert np.max(np.linalg.norm(ours.poses[:, :2] - peer.poses[:, :2], axis=1)) <= 1e-6
    assert np.max(np.linalg.norm(ours.landmarks - peer.landmarks, axis=1)) <= 1e-6
    assert ours.info["final_cost"] == pytest.approx(peer.final_cost, rel=1e-9)


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_save_load_continue_on_position_sightings(tmp_path: Path, estimator: str) -> None:
    events = list(mixed(grid_world(dataclasses.replace(XY_GRID, poses=60, model="range-bearing"))))
    cut = next(k for k, e in enumerate(events) if isinstance(e, Observation) and e.t == 30.0 and e.xy is not None)
    whole, first = Slam(estimator), Slam(estimator)
    for event in events:
        whole.add(event)
    for event in events[:cut]:
        first.add(event)
    first.save(tmp_path / "slam.ckpt")  # mid-step: the newest pose holds sightings of both models
    second = Slam.load(tmp_path / "slam.ckpt")
    for event in events[cut:]:
        second.add(event)
    np.testing.assert_array_equal(second.estimate().trajectory, whole.estimate().trajectory)


def test_position_sightings_convert_to_g2o_point_edges(tmp_path: Path) -> None:
    from online_slam.importers.g2o.reader import read_g2o, write_g2o

    events = [Start(0.0, (1.0, 2.0, 0.5)), Observation(0.0, "a", sigma=(0.1, 0.2), xy=(3.0, -1.0))]
    write_g2o(tmp_path / "xy.g2o", events)
    text = (tmp_path / "xy.g2o").read_text()
    edge = next(line for line in text.splitlines() if line.startswith("EDGE_SE2_XY")).split()
    assert edge[1:5] == ["0", "1", "3.0", "-1.0"]
    assert np.allclose([float(v) for v in edge[5:]], [100.0, 0.0, 25.0])
    back = [e for e in read_g2o(tmp_path / "xy.g2o") if isinstance(e, Observation)]
    assert np.allclose([back[0].range * np.cos(back[0].bearing), back[0].range * np.sin(back[0].bearing)], [3, -1])
