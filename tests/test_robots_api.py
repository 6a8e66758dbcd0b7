"""The library API with several robots: ``Slam`` fed a world of robots event by event equals the replay; robot
sightings are checked as stream lines are; each robot's pose, covariance and trajectory; checkpoints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import online_slam
from online_slam import ConfigError, InputError, ReplayConfig, Slam
from online_slam.sources import MeetConfig, Odometry, meet_world
from online_slam.sources.validate import validate_events

SMALL_MEET = MeetConfig(robots=3, poses=60, landmarks=30)
SIG3, SIG2 = [0.05, 0.05, 0.01], [0.05, 0.01]
SEVERAL = ["ekf", "smoother"]
"""The online estimators, each taking several robots."""


def drive(slam: Slam, events: list) -> dict[int, np.ndarray]:
    """Add events one by one; read the newest pose the estimator has before each odometry (as a replay records
    each complete pose). Returns the poses read, by index."""
    online = {}
    for event in events:
        if isinstance(event, Odometry) and slam.poses:
            estimate = slam.estimate(landmark_covs=False)
            online[estimate.index] = estimate.pose.copy()
        slam.add(event)
    return online


def two_robots(slam: Slam) -> None:
    """Two robots five metres apart, each one step forward (robot 2 not yet complete)."""
    slam.start(0.0, [0.0, 0.0, 0.0], robot=1)
    slam.start(0.0, [5.0, 0.0, 0.0], robot=2)
    slam.add_observation(0.0, "tree", 3.0, 0.5, sigma=SIG2, robot=1)
    slam.add_odometry(1.0, [1.0, 0.0, 0.0], sigma=[0.3, 0.3, 0.05], robot=1)
    slam.add_odometry(1.0, [1.0, 0.0, 0.0], sigma=[0.3, 0.3, 0.05], robot=2)


@pytest.mark.parametrize("estimator", SEVERAL)
def test_event_by_event_equals_replay(estimator: str) -> None:
    events = list(meet_world(SMALL_MEET))
    slam = Slam(estimator)
    online = drive(slam, events)
    results = online_slam.replay(iter(events), ReplayConfig(estimators=(estimator,)))
    replayed = results.series[estimator].poses
    assert len(online) >= len(replayed) - SMALL_MEET.robots  # all but the newest poses, still open
    assert max(np.abs(pose - replayed[i]).max() for i, pose in online.items()) == 0.0
    truth = results.truth_poses
    assert truth is not None
    errors = results.series[estimator].position_error_m  # the meet world starts at the truth: no alignment
    for k in range(len(results.estimators[estimator].robots)):
        steps = [i for i in online if i % SMALL_MEET.robots == k]  # robots take turns, one pose each per time
        mine = [np.hypot(*(online[i][:2] - truth[i][:2])) for i in steps]
        np.testing.assert_allclose(mine, errors[steps], rtol=0, atol=1e-12)


@pytest.mark.parametrize("estimator", SEVERAL)
def test_each_robot_has_its_pose_covariance_and_trajectory(estimator: str) -> None:
    slam = Slam(estimator)
    for event in meet_world(SMALL_MEET):
        slam.add(event)
    estimate = slam.estimate()
    assert list(estimate.robots) == [1, 2, 3]
    seen = []
    for robot, mine in estimate.robots.items():
        np.testing.assert_array_equal(mine.trajectory, estimate.trajectory[mine.steps])
        np.testing.assert_array_equal(mine.trajectory[-1], mine.pose)
        assert mine.steps[-1] == mine.index and mine.t == pytest.approx(SMALL_MEET.poses - 1 - (robot > 1))
        assert np.all(np.linalg.eigvalsh(mine.pose_cov) > 0) and not mine.pose.flags.writeable
        seen += list(mine.steps)
    assert sorted(seen) == list(range(len(estimate.trajectory)))  # every pose is one robot's
    assert estimate.robots[1].index == estimate.index  # the newest pose the estimator has is robot 1's
    np.testing.assert_array_equal(estimate.robots[1].pose_cov, estimate.pose_cov)


@pytest.mark.parametrize("estimator", SEVERAL)
def test_each_robot_keeps_its_poses_behind_a_latency_budget(estimator: str) -> None:
    """With ``max_latency`` the lines reach the front-end in bursts, starting poses of robots other than the line's
    own: every pose is still its robot's, whether a query reads what the estimator took or the held lines too."""
    events = list(meet_world(SMALL_MEET))
    plain, held = Slam(estimator), Slam(estimator, max_latency=0.3)
    for event in events:
        plain.add(event)
        held.add(event)
    whole = plain.estimate(landmark_covs=False)
    seen, taken = held.estimate(landmark_covs=False), held.estimate(landmark_covs=False, held=False)
    assert len(taken.trajectory) < len(seen.trajectory) == len(whole.trajectory)
    for robot, mine in whole.robots.items():
        np.testing.assert_array_equal(seen.robots[robot].steps, mine.steps)
        np.testing.assert_allclose(seen.robots[robot].trajectory, mine.trajectory, atol=1e-9)
        n = len(taken.robots[robot].steps)
        np.testing.assert_array_equal(taken.robots[robot].steps, mine.steps[:n])


def test_one_named_robot_and_no_robot() -> None:
    named, unnamed = Slam("smoother"), Slam("smoother")
    named.start(0.0, [0.0, 0.0, 0.0], robot="r")
    unnamed.start(0.0, [0.0, 0.0, 0.0])
    for slam, robot in ((named, "r"), (unnamed, None)):
        slam.add_observation(0.0, 1, 2.0, 0.3, sigma=SIG2, robot=robot)
        slam.add_odometry(1.0, [1.0, 0.0, 0.0], sigma=SIG3, robot=robot)
        slam.add_observation(1.0, 1, 1.0, 0.3, sigma=SIG2, robot=robot)
    one, none = named.estimate(), unnamed.estimate()
    np.testing.assert_array_equal(one.trajectory, none.trajectory)
    assert dict(none.robots) == {} and list(one.robots) == ["r"]
    np.testing.assert_array_equal(one.robots["r"].trajectory, one.trajectory)
    np.testing.assert_array_equal(one.robots["r"].pose_cov, one.pose_cov)


@pytest.mark.parametrize(
    ("call", "field", "message"),
    [
        (dict(t=1.0, robot_seen=1, range=2.0, bearing=0.1, sigma=SIG2, robot=1), "robot_seen", "cannot sight itself"),
        (dict(t=1.0, robot_seen=7, range=2.0, bearing=0.1, sigma=SIG2, robot=1), "robot_seen", "unknown robot 7"),
        (dict(t=1.0, robot_seen=2, range=2.0, bearing=0.1, sigma=SIG2), "robot", "missing required field"),
        (dict(t=1.0, robot_seen=2, range=-2.0, bearing=0.1, sigma=SIG2, robot=1), "range", "range > 0"),
        (dict(t=1.0, robot_seen=2, range=2.0, bearing=45.0, sigma=SIG2, robot=1), "bearing", "degrees"),
        (dict(t=0.5, robot_seen=2, range=2.0, bearing=0.1, sigma=SIG2, robot=1), "t", "time goes backwards"),
        (dict(t=1.0, robot_seen=2, range=2.0, bearing=0.1, robot=1), "sigma", "missing noise"),
    ],
)
def test_a_bad_robot_sighting_raises_the_streams_error_and_changes_nothing(call, field: str, message: str) -> None:
    slam = Slam("ekf")
    two_robots(slam)
    record = {"type": "observation", **call}
    stream = [{"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0], "robot": r} for r in (1, 2)]
    stream += [{"type": "odometry", "t": 1.0, "delta": [1.0, 0.0, 0.0], "sigma": SIG3, "robot": 1}, record]
    with pytest.raises(InputError) as from_stream:
        list(validate_events(stream))
    before = (slam.poses, slam._validator.state)
    with pytest.raises(InputError, match=message) as from_api:
        slam.add_robot_observation(**call)
    assert from_api.value.field == from_stream.value.field == field
    assert from_api.value.message == from_stream.value.message
    assert (slam.poses, slam._validator.state) == before
    slam.add_robot_observation(1.0, 2, 4.0, 0.0, sigma=SIG2, robot=1)  # a good one goes on
    assert slam.estimate().robots[1].index == 2


def test_a_robot_sighting_pulls_both_robots_and_after_a_query_is_refused() -> None:
    slam, alone = Slam("ekf"), Slam("ekf")
    two_robots(slam)
    two_robots(alone)
    slam.add_robot_observation(1.0, 2, 4.0, 0.0, sigma=[0.01, 0.01], robot=1)
    for each in (slam, alone):
        each.add_odometry(2.0, [1.0, 0.0, 0.0], sigma=SIG3, robot=1)
        each.add_odometry(2.0, [1.0, 0.0, 0.0], sigma=SIG3, robot=2)
    linked, apart = slam.estimate().robots, alone.estimate().robots
    assert np.linalg.det(linked[2].pose_cov) < np.linalg.det(apart[2].pose_cov)
    # Robot 1's pose at t=2 is shown to the estimator by the query: its robot sightings are refused from then on.
    with pytest.raises(InputError, match="queried already") as refused:
        slam.add_robot_observation(2.0, 2, 4.0, 0.0, sigma=SIG2, robot=1)
    assert refused.value.field == "robot_seen"
    slam.add_robot_observation(2.0, 1, 4.0, np.pi, sigma=SIG2, robot=2)  # robot 2's newest pose waits: taken
    slam.add_odometry(3.0, [1.0, 0.0, 0.0], sigma=SIG3, robot=1)
    assert slam.poses == 7


def test_batch_is_no_online_estimator_and_replays_the_same_events() -> None:
    with pytest.raises(ConfigError, match="online_slam.replay"):
        Slam("batch")
    records = [event.to_record() for event in meet_world(SMALL_MEET)]
    from_records = online_slam.replay(records, ReplayConfig(estimators=("ekf", "batch")))
    from_world = online_slam.replay(meet_world(SMALL_MEET), ReplayConfig(estimators=("ekf", "batch")))
    for name in ("ekf", "batch"):
        np.testing.assert_array_equal(from_records.estimates[name].poses, from_world.estimates[name].poses)
        robots = from_records.estimators[name].robots
        assert list(robots) == ["1", "2", "3"]
        assert [r.final_rmse_m for r in robots.values()] == [
            r.final_rmse_m for r in from_world.estimators[name].robots.values()
        ]


@pytest.mark.parametrize("estimator", SEVERAL)
def test_save_load_continue_equals_uninterrupted(tmp_path: Path, estimator: str) -> None:
    events = list(meet_world(SMALL_MEET))
    whole, first = Slam(estimator), Slam(estimator)
    online = drive(whole, events)
    half = len(events) // 2
    drive(first, events[:half])
    first.save(tmp_path / "half.ckpt")
    resumed = Slam.load(tmp_path / "half.ckpt")
    later = drive(resumed, events[half:])
    assert all(np.array_equal(pose, online[i]) for i, pose in later.items()) and later
    mine, theirs = resumed.estimate(), whole.estimate()
    np.testing.assert_array_equal(mine.trajectory, theirs.trajectory)
    for robot in theirs.robots:
        np.testing.assert_array_equal(mine.robots[robot].pose_cov, theirs.robots[robot].pose_cov)
        np.testing.assert_array_equal(mine.robots[robot].steps, theirs.robots[robot].steps)


def test_a_robot_start_right_after_a_solve_has_no_increment_to_carry() -> None:
    """The smoother's association covariance carries the last solve's newest pose through the newest increment; a
    second robot's start pose has none (the noise adaptation asked for it and met a KeyError on held-out MRCLAM, all
    five robots): the solve does not apply, and the window is linearized instead."""
    from types import SimpleNamespace

    from online_slam.estimators.smoother.covariance import _carry

    solved = SimpleNamespace(window=[0, 1, 2])
    window = SimpleNamespace(indices=[0, 1, 2, 3], unsolved={3}, observations={}, previous={}, odometry={},
                             poses={2: np.zeros(3), 3: np.ones(3)})  # fmt: skip
    assert _carry(solved, window) == (False, None)  # type: ignore[arg-type]
    window.odometry[3] = (np.array([0.5, 0.0, 0.0]), np.eye(3) * 0.01, None)
    applies, carried = _carry(solved, window)  # type: ignore[arg-type]
    assert applies and carried is not None and carried[0].shape == (3, 3)
