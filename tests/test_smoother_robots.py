"""The sliding-window smoother on several robots: equals the batch with a covering window, robot sightings alone
pull a drifting robot back, marginalizing interleaved chains is exact at the solution, a resumed replay equals an
uninterrupted one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from online_slam.estimators import BatchEstimator, SlidingWindowSmoother
from online_slam.estimators.smoother import GlobalConfig, SmootherConfig, WindowConfig
from online_slam.factors.graph import layout, linearize
from online_slam.frontend import FrontEnd
from online_slam.geometry.angles import wrap
from online_slam.pipeline import Checkpointing, ReplayConfig, replay
from online_slam.sources import WORLDS, MeetConfig, Observation, meet_world


def run(events: list, config: SmootherConfig) -> tuple[SlidingWindowSmoother, object, object]:
    """The smoother and the batch over the same steps: (the smoother, its final estimate, the batch's)."""
    smoother, batch = SlidingWindowSmoother(config), BatchEstimator()
    for step in FrontEnd().steps(events):
        smoother.step(step)
        batch.step(step)
    return smoother, smoother.finish(), batch.finish()


def test_a_window_covering_the_meet_stream_equals_the_batch() -> None:
    events = list(meet_world(MeetConfig(poses=40)))
    _, final, batch = run(events, SmootherConfig(window=WindowConfig(size=10_000)))
    assert final.info["robot_sightings_in_window"] > 20
    assert np.max(np.linalg.norm(final.poses[:, :2] - batch.poses[:, :2], axis=1)) <= 1e-6
    assert np.max(np.abs(wrap(final.poses[:, 2] - batch.poses[:, 2]))) <= 1e-7
    assert np.max(np.linalg.norm(final.landmarks - batch.landmarks, axis=1)) <= 1e-6


def test_marginalizing_interleaved_chains_is_exact_at_the_solution() -> None:
    """Linearized at the optimum, marginalizing poses of three robots (robot sightings folded into the prior, each
    robot's oldest pose held) leaves the batch's estimate; the window's newest pose has the batch's covariance."""
    events = list(meet_world(MeetConfig(poses=15)))
    config = SmootherConfig(window=WindowConfig(size=10_000), global_solve=GlobalConfig(every=0))
    smoother, _, batch = run(events, config)
    marginalized: list[int] = []
    with threadpool_limits(limits=1, user_api="blas"):
        smoother.solve(final=True)
        for _ in range(25):
            smoother._marginalize_several(marginalized)
        smoother.solve(final=True)
    window, prior = smoother.window.indices, smoother.prior
    assert len(marginalized) == 25 and prior is not None and len(prior.poses) == 3
    assert sorted(prior.poses) == sorted(min(g for g in window if g % 3 == k) for k in range(3))  # each robot's oldest
    info = smoother.finish().info
    assert info["robot_sightings_folded"] > 5 and info["robot_sightings_unfolded"] == 0
    assert np.max(np.abs(smoother.window.values()[:, :2] - batch.poses[window, :2])) < 1e-7
    assert np.max(np.abs(smoother.landmarks - batch.landmarks)) < 1e-7
    graph = BatchEstimator()
    for step in FrontEnd().steps(events):
        graph.step(step)
    full = graph.log.graph()
    sparse = layout(full)
    _, J = linearize(full, sparse, batch.poses, batch.landmarks)
    covariance = np.linalg.inv((J.T @ J).toarray())
    last = sparse.pose_column[window[-1]] + np.arange(3)
    assert np.allclose(smoother.window.pose_cov, covariance[np.ix_(last, last)], rtol=1e-6, atol=1e-12)


def test_a_frozen_log_of_several_robots_does_not_change_with_later_steps() -> None:
    """A global solve reads a frozen copy of the log in the background: its robot sightings and starts stay."""
    steps = list(FrontEnd().steps(meet_world(MeetConfig(poses=30))))
    batch = BatchEstimator()
    for step in steps[:40]:
        batch.step(step)
    frozen = batch.log.frozen()
    before = frozen.graph()
    for step in steps[40:]:
        batch.step(step)
    after = frozen.graph()
    assert len(before.rob_from) > 5 and len(batch.log.graph().rob_from) > len(before.rob_from)
    for name in ("rob_from", "rob_to", "rob_z", "prior_pose", "fixed_poses"):
        assert np.array_equal(getattr(before, name), getattr(after, name)), name


def drifting(with_sightings: bool) -> list:
    """meet-apart with robot 2's landmark sightings dropped: only robot sightings can correct its odometry."""
    kept = []
    for e in WORLDS["meet-apart"].events():
        if isinstance(e, Observation) and e.robot == 2 and (e.robot_seen is None or not with_sightings):
            continue
        if isinstance(e, Observation) and e.robot_seen is not None and not with_sightings:
            continue
        kept.append(e)
    return kept


def test_robot_sightings_alone_pull_a_drifting_robot_back() -> None:
    config = ReplayConfig(estimators=("smoother",))
    with_them = replay(drifting(True), config).estimators["smoother"]
    without = replay(drifting(False), config).estimators["smoother"]
    assert with_them.robots["2"].online_rmse_m < 0.5 * without.robots["2"].online_rmse_m
    assert with_them.robots["2"].final_rmse_m < 0.5 * without.robots["2"].final_rmse_m
    assert with_them.details["robot_sightings_folded"] > 100


def test_a_resumed_multi_robot_replay_equals_the_uninterrupted_one(tmp_path: Path) -> None:
    """Checkpoints every 250 of 360 steps; resumed from the last one (the global solve started at 240 pending)."""
    config = ReplayConfig(
        estimators=("smoother",),
        smoother=SmootherConfig(window=WindowConfig(size=15, distance=0.0), global_solve=GlobalConfig(every=40)),
    )
    events = list(meet_world(MeetConfig(poses=120)))
    whole = replay(events, config, checkpoint=Checkpointing(tmp_path, 250))
    resumed = replay(events, config, resume=tmp_path)
    assert whole.estimators["smoother"].details["global_solves"] > 3
    assert figures(resumed.to_json()) == figures(whole.to_json())


def figures(document: object) -> object:
    """Every figure of a results document but timings."""
    if isinstance(document, dict):
        timings = ("total_s", "step_ms", "solve_s", "final_solve_s")
        return {k: figures(v) for k, v in document.items() if k not in timings}
    return document


def test_each_robots_newest_covariance_takes_the_robot_sightings() -> None:
    import online_slam

    covs = {}
    for kind in ("ekf", "smoother"):
        team = online_slam.Slam(kind)
        team.start(0.0, [0.0, 0.0, 0.0], robot=1)
        team.start(0.0, [5.0, 0.0, 0.0], robot=2)
        for t in (1.0, 2.0):
            team.add_odometry(t, delta=[1.0, 0.0, 0.0], sigma=[0.05, 0.05, 0.01], robot=1)
            team.add_odometry(t, delta=[1.0, 0.0, 0.0], sigma=[0.05, 0.05, 0.01], robot=2)
            team.add_robot_observation(t, robot_seen=2, range=5.0, bearing=0.0, sigma=[0.05, 0.01], robot=1)
        covs[kind] = {robot: newest.pose_cov for robot, newest in team.estimate().robots.items()}
    # robot 2 (not the newest pose) is pulled by robot 1's sightings: tighter than its odometry alone (0.05 m)
    assert np.sqrt(covs["smoother"][2][0, 0]) < 0.045
    for robot in (1, 2):
        np.testing.assert_allclose(covs["smoother"][robot], covs["ekf"][robot], rtol=0.02, atol=1e-6)
