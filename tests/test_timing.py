"""Sensor timing: sightings between odometry ticks, lines of one time in any order, late lines and the reorder
buffer, queries that predict without making a pose (library, CLI)."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_close
from inprocess import run_cli as _cli

from online_slam import ReplayConfig, Slam, replay
from online_slam.errors import InputError
from online_slam.geometry import compose
from online_slam.models.motion import compose_increments, extrapolate_increment, predict_pose, split_increment
from online_slam.options import replay_config
from online_slam.sources.events import Observation, Odometry
from online_slam.sources.stream import write_stream
from online_slam.sources.timing import TimingConfig, timing_world
from online_slam.sources.worlds import GridConfig, grid_world

SMALL = TimingConfig(duration=12.0, landmarks=120, seed=3)


@pytest.mark.parametrize("fraction", [1e-6, 0.04, 0.5, 0.97])
def test_a_split_increment_composes_to_the_whole_at_constant_twist(fraction: float) -> None:
    rng = np.random.default_rng(4)
    for _ in range(20):
        delta = rng.normal(size=3) * [1.0, 0.3, 1.2]
        root = rng.normal(size=(3, 3))
        cov = root @ root.T + 1e-3 * np.eye(3)
        a, cov_a, b, cov_b = split_increment(delta, cov, fraction)
        whole, whole_cov = compose_increments(a, cov_a, b, cov_b)
        np.testing.assert_allclose(whole, delta, atol=1e-12)
        np.testing.assert_allclose(whole_cov, cov, atol=1e-11)
        # constant twist: the first part, taken 1 / fraction times, is the whole
        again, _ = extrapolate_increment(a, cov_a, 1.0 / fraction)
        np.testing.assert_allclose(again, delta, atol=1e-6)
        assert np.all(np.linalg.eigvalsh(cov_a) > 0) and np.all(np.linalg.eigvalsh(cov_b) > 0)


def test_predict_pose_cuts_composes_and_goes_on_at_the_last_twist() -> None:
    pose, cov = np.array([1.0, 2.0, 0.3]), np.diag([0.01, 0.01, 0.001])
    step = (0.0, 1.0, np.array([1.0, 0.1, 0.2]), np.diag([0.02, 0.02, 0.004]))
    half, half_cov = predict_pose(pose, cov, 0.0, [step], 0.5)
    np.testing.assert_allclose(compose(half, split_increment(step[2], step[3], 0.5)[2]), compose(pose, step[2]))
    whole, _ = predict_pose(pose, cov, 0.0, [step], 1.0)
    np.testing.assert_allclose(whole, compose(pose, step[2]))
    on, on_cov = predict_pose(pose, cov, 0.0, [step], 2.0)
    np.testing.assert_allclose(on, compose(compose(pose, step[2]), step[2]), atol=1e-12)
    assert np.trace(cov) < np.trace(half_cov) < np.trace(on_cov)
    still, still_cov = predict_pose(pose, cov, 0.0, [], 3.0)
    np.testing.assert_array_equal(still, pose) and np.testing.assert_array_equal(still_cov, cov)


def test_noise_free_sightings_between_ticks_give_the_truth_in_every_estimator() -> None:
    """The split is the motion itself: with (almost) no noise, every estimator lands on the truth; attaching the
    same sightings to the tick before misses it by centimetres."""
    quiet = dataclasses.replace(SMALL, odometry_sigma=(1e-5, 1e-5, 1e-6), sensor_sigma=(1e-5, 1e-6))
    events = list(timing_world(quiet))
    results = replay(events, ReplayConfig(estimators=("ekf", "smoother", "batch")))
    assert results.poses > 121  # the 12 s of ticks and a pose per scan between them
    for name, row in results.rows().items():
        if name != "odometry":
            assert row.final_rmse_m < 1e-4 and row.landmark_rmse_m < 1e-4, name
    early = [
        dataclasses.replace(e, t=math.floor((e.t + 1e-9) * 10) / 10) if isinstance(e, Observation) else e
        for e in events
    ]
    early.sort(key=lambda e: getattr(e, "t", -math.inf))
    assert replay(early, ReplayConfig(estimators=("batch",))).rows()["batch"].landmark_rmse_m > 1e-2


def test_lines_arriving_late_within_the_budget_give_the_ordered_figures() -> None:
    ordered = list(timing_world(SMALL))
    arriving = list(timing_world(dataclasses.replace(SMALL, delay=0.15)))
    assert [type(e) for e in arriving] != [type(e) for e in ordered]  # sightings after later odometry
    estimators = "ekf,smoother,batch"
    base = replay(ordered, replay_config({"estimators": estimators}))
    held = replay(arriving, replay_config({"estimators": estimators, "max_latency": 0.2}))
    assert held.input.skipped_lines == 0 and held.poses == base.poses
    for name, row in base.rows().items():
        for key in ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "nees_mean"):
            if getattr(row, key) is not None:
                assert_close(getattr(held.rows()[name], key), getattr(row, key), rtol=1e-6)
    refused = replay(arriving, replay_config({"estimators": "ekf"}))  # no budget: as before
    assert refused.error is not None and "time goes backwards" in refused.error


def test_a_line_beyond_the_budget_is_skipped_and_counted() -> None:
    events = [e.to_record() for e in timing_world(SMALL)]
    late = {"type": "observation", "t": 5.0, "landmark": 3, "range": 4.0, "bearing": 0.1, "sigma": [0.05, 0.01]}
    at = next(i for i, r in enumerate(events) if r.get("t", 0) >= 8.0)
    events.insert(at, late)
    results = replay(events, replay_config({"estimators": "ekf", "max_latency": 0.5}))
    assert results.input.skipped_by_reason == {"late": 1} and results.error is None
    slam = Slam("ekf", max_latency=0.5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for record in events:
            slam.add(record)
    assert slam.late == 1 and len(caught) == 1 and "late by" in str(caught[0].message)


def test_slam_fed_in_arrival_order_matches_the_ordered_feed() -> None:
    ordered = list(timing_world(SMALL))
    arriving = list(timing_world(dataclasses.replace(SMALL, delay=0.15)))
    last = max(e.t for e in ordered if isinstance(e, Odometry))
    estimates = []
    for events, latency in ((ordered, 0.0), (arriving, 0.2)):
        slam = Slam("smoother", max_latency=latency)
        for event in events:
            slam.add(event)
        estimates.append(tuple(slam.estimate(landmark_covs=False, at=at, held=h) for at, h in
                               ((None, False), (last, False), (None, True))))  # fmt: skip
    (whole, now, _), (held, held_now, seen) = estimates
    n = len(held.trajectory)
    assert 0 < len(whole.trajectory) - n <= 3  # the estimator is 0.2 s behind: 2 ticks
    np.testing.assert_allclose(held.trajectory, whole.trajectory[:n], atol=1e-6)
    np.testing.assert_array_equal(held.trajectory_times, whole.trajectory_times[:n])
    assert held_now.t == now.t == last
    np.testing.assert_allclose(held_now.pose, now.pose, atol=1e-6)  # predicted with the held odometry
    np.testing.assert_array_equal(seen.trajectory_times, whole.trajectory_times)  # a copy took the held lines
    np.testing.assert_allclose(seen.trajectory, whole.trajectory, atol=1e-6)


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_a_query_sees_a_late_sighting_at_its_time_at_once(estimator: str) -> None:
    """A sighting stamped between two poses that arrives after the later one, within the budget: the estimate
    has a pose at its time with the sighting (as the feed in time order gives), before the budget has passed;
    ``held=False`` predicts with the held odometry alone."""
    sigma = [0.05, 0.05, 0.01]
    lines = [("odometry", 1.0, [1.0, 0.0, 0.1]), ("odometry", 2.0, [1.0, 0.0, 0.1]), ("sighting", 1.5, 7)]
    estimates = []
    for order, latency in ((lines, 0.5), ([lines[0], lines[2], lines[1]], 0.0)):
        slam = Slam(estimator, max_latency=latency)
        slam.start(0.0, [0.0, 0.0, 0.0])
        slam.add_observation(0.0, landmark=3, range=3.0, bearing=0.4, sigma=[0.1, 0.02])
        for kind, t, value in order:
            if kind == "odometry":
                slam.add_odometry(t, value, sigma=sigma)
            else:
                slam.add_observation(t, landmark=value, range=2.0, bearing=-0.3, sigma=[0.1, 0.02])
        estimates.append((slam.estimate(), slam.estimate(held=False), slam.map()))
    (late, predicted, late_map), (ordered, _, ordered_map) = estimates
    np.testing.assert_array_equal(late.trajectory_times, [0.0, 1.0, 1.5, 2.0])
    np.testing.assert_array_equal(ordered.trajectory_times, late.trajectory_times)
    assert late.landmark_ids == ordered.landmark_ids == (3, 7)
    np.testing.assert_allclose(late.trajectory, ordered.trajectory, atol=1e-8)
    np.testing.assert_allclose(late.pose_cov, ordered.pose_cov, atol=1e-8)
    np.testing.assert_allclose(late.landmark_array, ordered.landmark_array, atol=1e-8)
    assert predicted.landmark_ids == (3,) and predicted.t == 2.0  # the odometry to 2 s predicted, 7 not yet seen
    np.testing.assert_array_equal(predicted.trajectory_times, [0.0, 1.0])
    assert late_map.ids == ordered_map.ids == (3, 7)  # the map too, with its joint covariance
    np.testing.assert_allclose(late_map.joint, ordered_map.joint, atol=1e-8)


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_queries_that_see_held_lines_change_nothing(estimator: str) -> None:
    """The held lines reach a copy: a feed queried with them after every odometry line ends bit-identical to the
    same feed queried without them (the smoother starting and handing over global solves meanwhile)."""
    arriving = list(timing_world(dataclasses.replace(SMALL, delay=0.15)))
    ordered = Slam(estimator)
    for event in timing_world(SMALL):
        ordered.add(event)
    whole = ordered.estimate(landmark_covs=False)
    finals, previews, sizes = [], {True: 0, False: 0}, []
    for held in (True, False):
        slam = Slam(estimator, max_latency=0.2, **({"global_every": 20} if estimator == "smoother" else {}))
        for event in arriving:
            slam.add(event)
            if isinstance(event, Odometry):
                estimate = slam.estimate(landmark_covs=False, held=held)
                previews[held] += len(estimate.trajectory_times) > slam.poses  # poses the Slam has not made yet
                if held:
                    assert estimate.trajectory_times[-1] == event.t  # the newest pose is the newest odometry's
                    sizes.append(len(estimate.trajectory_times))
        slam.flush()
        finals.append(slam.estimate())
    assert previews[True] > 20 and previews[False] == 0  # held sightings seen at once by many queries
    assert all(np.diff(sizes) >= 1)  # the trajectory only grows
    np.testing.assert_array_equal(finals[0].trajectory, finals[1].trajectory)
    np.testing.assert_array_equal(finals[0].landmark_array, finals[1].landmark_array)
    np.testing.assert_allclose(finals[0].trajectory, whole.trajectory, atol=1e-6)


def test_queries_never_change_keyframing() -> None:
    events = [  # sightings at every fourth pose: keyframes merge the poses between
        e
        for e in grid_world(GridConfig(poses=120, landmarks=30, seed=4))
        if not isinstance(e, Observation) or round(e.t) % 4 == 0
    ]
    trajectories = []
    for query in (False, True):
        slam = Slam("smoother", keyframe_distance=3.0)
        for event in events:
            slam.add(event)
            if query and isinstance(event, Odometry):
                estimate = slam.estimate(landmark_covs=False)
                assert estimate.t == event.t  # the newest pose, predicted to the newest odometry
        trajectories.append(slam.estimate(landmark_covs=False))
    plain, queried = trajectories
    assert len(plain.trajectory) == len(queried.trajectory) < 120
    np.testing.assert_array_equal(plain.trajectory_times, queried.trajectory_times)
    np.testing.assert_allclose(queried.trajectory, plain.trajectory, rtol=1e-9, atol=1e-9)


def test_estimate_at_a_time_predicts_without_making_a_pose() -> None:
    slam = Slam("ekf")
    slam.start(0.0, [0.0, 0.0, 0.0])
    slam.add_odometry(1.0, [1.0, 0.0, 0.2], sigma=[0.05, 0.05, 0.01])
    now = slam.estimate()
    assert now.index == 1 and now.t == 1.0
    ahead = slam.estimate(at=1.5)
    assert ahead.index == 1 and ahead.t == 1.5 and len(ahead.trajectory) == 2
    np.testing.assert_allclose(ahead.pose, compose(now.pose, extrapolate_increment([1.0, 0.0, 0.2], np.eye(3), 0.5)[0]))
    assert np.trace(ahead.pose_cov) > np.trace(now.pose_cov)
    np.testing.assert_array_equal(ahead.trajectory_times, [0.0, 1.0])
    assert slam.poses == 2
    with pytest.raises(InputError, match="before the newest pose"):
        slam.estimate(at=0.5)


def test_cli_reads_late_lines_with_a_budget_and_stdin_has_one_by_default(tmp_path: Path) -> None:
    path = tmp_path / "late.jsonl"
    write_stream(path, timing_world(dataclasses.replace(SMALL, delay=0.15)))
    refused = _cli("replay", str(path), "--estimators", "ekf")
    assert refused.returncode == 2 and "time goes backwards" in refused.stderr
    out = tmp_path / "out.json"
    taken = _cli("replay", str(path), "--estimators", "ekf", "--max-latency", "0.2", "--json", str(out))
    assert taken.returncode == 0, taken.stderr
    document = json.loads(out.read_text())
    assert document["input"]["skipped_lines"] == 0 and document["error"] is None
    times = document["trajectory_times"]
    assert len(times) == document["poses"] and times == sorted(times)
    piped = _cli("replay", "-", "--estimators", "ekf", "--json", "-", stdin=path.read_text())
    assert piped.returncode == 0 and json.loads(piped.stdout)["estimators"] == document["estimators"] | {
        "ekf": json.loads(piped.stdout)["estimators"]["ekf"]
    }
    assert (
        json.loads(piped.stdout)["estimators"]["ekf"]["online_rmse_m"] == document["estimators"]["ekf"]["online_rmse_m"]
    )


def test_simulate_writes_the_timing_world_with_late_lines(tmp_path: Path) -> None:
    """``simulate timing --delay`` writes lines in arrival order; replayed with a budget they give the figures of the
    ``timing`` world in time order; other worlds refuse ``--delay``; a time going back is shown without float noise."""
    late = tmp_path / "late.jsonl"
    wrote = _cli("simulate", "timing", "--delay", "0.15", "-o", str(late))
    assert wrote.returncode == 0, wrote.stderr
    lines = [json.loads(line) for line in late.read_text().splitlines()]
    times = [line["t"] for line in lines if "t" in line]
    assert times != sorted(times)  # some sightings come after later odometry
    figures = []
    for source, budget in ((str(late), "0.2"), ("timing", "0")):
        run = _cli("replay", source, "--estimators", "ekf", "--max-latency", budget, "--json", "-")
        assert run.returncode == 0, run.stderr
        figures.append(json.loads(run.stdout)["estimators"]["ekf"])
    assert_close(figures[0]["online_rmse_m"], figures[1]["online_rmse_m"], rtol=1e-9)
    assert_close(figures[0]["nees_mean"], figures[1]["nees_mean"], rtol=1e-9)
    refused = _cli("simulate", "grid", "--delay", "0.1")
    assert refused.returncode == 2 and "--delay is the timing world's" in refused.stderr
    backwards = _cli("replay", str(late), "--estimators", "ekf")
    assert backwards.returncode == 2 and "0.6000000000000001" not in backwards.stderr


def test_slam_with_a_budget_shows_its_start_flushes_and_keeps_its_late_count(tmp_path: Path) -> None:
    slam = Slam("ekf", max_latency=0.3)
    slam.start(0.0, [1.0, 2.0, 0.0])
    slam.add_odometry(0.1, [0.1, 0.0, 0.0], sigma=[0.01, 0.01, 0.001])
    early, seen = slam.estimate(held=False), slam.estimate()
    assert early.index == 0 and early.t == 0.1  # the start, predicted with the held odometry
    assert seen.index == 1 and seen.t == 0.1  # the held odometry's pose, made in a copy
    np.testing.assert_allclose(early.pose, [1.1, 2.0, 0.0])
    np.testing.assert_allclose(seen.pose, early.pose)
    assert slam.poses == 1
    for k in range(2, 8):
        slam.add_odometry(0.1 * k, [0.1, 0.0, 0.0], sigma=[0.01, 0.01, 0.001])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        slam.add_observation(0.05, 3, range=2.0, bearing=0.1, sigma=[0.05, 0.01])  # 0.65 s late
    assert slam.late == 1 and "beyond max_latency 0.3 s" in str(caught[0].message)
    assert caught[0].filename == __file__  # the warning points at the user's call
    held = len(slam.estimate(held=False).trajectory)
    assert len(slam.estimate().trajectory) == 8 > held
    slam.flush()
    assert len(slam.estimate(held=False).trajectory) == 8
    slam.add_observation(0.65, 3, range=2.0, bearing=0.1, sigma=[0.05, 0.01])  # older than what was given on
    assert slam.late == 2
    slam.save(tmp_path / "late.ckpt")
    assert Slam.load(tmp_path / "late.ckpt").late == 2


def test_sightings_after_the_last_odometry_are_reported() -> None:
    events = [e for e in timing_world(SMALL) if not isinstance(e, Odometry) or e.t < 11.0]
    results = replay(events, ReplayConfig(estimators=("ekf",)))
    assert results.input.after_last_odometry > 0
    assert results.to_json()["input"]["after_last_odometry"] == results.input.after_last_odometry


def test_a_checkpoint_keeps_held_and_waiting_lines(tmp_path: Path) -> None:
    """Lines in the reorder buffer and sightings waiting for their odometry survive save and load bit for bit."""
    events = list(timing_world(dataclasses.replace(SMALL, delay=0.15, mount=(0.2, 0.0, 0.1))))
    whole = Slam("smoother", max_latency=0.2)
    for event in events:
        whole.add(event)
    half = Slam("smoother", max_latency=0.2)
    cut = len(events) // 2
    for event in events[:cut]:
        half.add(event)
    assert half._engine.frontend.held  # something is held at the cut
    half.save(tmp_path / "held.ckpt")
    again = Slam.load(tmp_path / "held.ckpt")
    for event in events[cut:]:
        again.add(event)
    np.testing.assert_array_equal(again.estimate().trajectory, whole.estimate().trajectory)
