"""Several robots in the estimators: the robot-sighting factor, steps in index order, the batch (== GTSAM) and
the centralized EKF, robot sightings pulling a drifting robot back, and the figures per robot (the smoother's in
test_smoother_robots.py)."""

from __future__ import annotations

import copy
import dataclasses
import json

import numpy as np
import pytest
from inprocess import run_cli

from online_slam.errors import OnlineSlamError
from online_slam.estimators import BatchEstimator
from online_slam.estimators.ekf import EkfConfig, EkfSlam
from online_slam.estimators.smoother import SmootherConfig
from online_slam.factors.graph import (
    DenseAssembler,
    FactorGraph,
    evaluate,
    layout,
    linearize,
    robot_sighting_residual_with_jacobians,
)
from online_slam.frontend import FrontEnd
from online_slam.geometry.angles import wrap
from online_slam.pipeline import ReplayConfig, replay
from online_slam.reports.table import format_results
from online_slam.sources import WORLDS, MeetConfig, Observation, Odometry, Start, meet_world

SIG3, SIG2 = (0.05, 0.05, 0.01), (0.05, 0.01)


def test_robot_sighting_jacobians_equal_numerical_ones() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(20, 3)) * [3, 3, 2], rng.normal(size=(20, 3)) * [3, 3, 2]
    z = rng.normal(size=(20, 2)) + [4, 0]
    _, J_a, J_b = robot_sighting_residual_with_jacobians(a, b, z)
    eps = 1e-6
    for which, J in ((0, J_a), (1, J_b)):
        columns = []
        for d in np.eye(3) * eps:
            moved = [(a + d, b), (a, b + d)][which], [(a - d, b), (a, b - d)][which]
            plus, minus = (robot_sighting_residual_with_jacobians(*m, z)[0] for m in moved)
            diff = plus - minus
            diff[:, 1] = wrap(diff[:, 1])
            columns.append(diff / (2 * eps))
        assert np.allclose(J, np.stack(columns, axis=2), atol=1e-6)
    assert np.all(J_b[:, :, 2] == 0.0)  # the seen robot's heading is not measured


def small_graph() -> tuple[FactorGraph, np.ndarray, np.ndarray]:
    """Two chains of three poses, one landmark each, two robot sightings; pose 0 fixed, pose 3 with a prior."""
    rng = np.random.default_rng(5)
    poses = rng.normal(size=(6, 3)) * [2, 2, 1]
    landmarks = rng.normal(size=(2, 2)) * 3
    graph = FactorGraph.build(
        6, 2, fixed_poses=[0], prior_pose=[3], prior_mean=[poses[3] + 0.1], prior_cov=[np.eye(3) * 0.01],
        odo_from=[0, 1, 3, 4], odo_to=[1, 2, 4, 5], odo_delta=rng.normal(size=(4, 3)), odo_cov=[np.eye(3) * 0.04] * 4,
        obs_pose=[1, 4], obs_landmark=[0, 1], obs_z=[[3.0, 0.2], [2.0, -0.3]], obs_cov=[np.diag(SIG2) ** 2] * 2,
        rob_from=[2, 5], rob_to=[4, 1], rob_z=[[2.5, 0.4], [1.5, 2.9]], rob_cov=[np.diag(SIG2) ** 2] * 2,
    )  # fmt: skip
    return graph, poses, landmarks


def test_the_graph_linearizes_robot_sightings_as_its_residuals_change() -> None:
    graph, poses, landmarks = small_graph()
    sparse = layout(graph)
    r, J = linearize(graph, sparse, poses, landmarks)
    assert np.array_equal(r, evaluate(graph, poses, landmarks)) and J.shape == (graph.n_residuals, 5 * 3 + 4)
    free = np.flatnonzero(sparse.pose_column >= 0)
    eps, columns = 1e-6, []
    for k in range(J.shape[1]):
        dp, dl = np.zeros_like(poses), np.zeros_like(landmarks)
        if k < 3 * len(free):
            dp[free[k // 3], k % 3] = eps
        else:
            dl.reshape(-1)[k - 3 * len(free)] = eps
        columns.append(evaluate(graph, poses + dp, landmarks + dl) - evaluate(graph, poses - dp, landmarks - dl))
    assert np.allclose(J.toarray(), np.stack(columns, axis=1) / (2 * eps), atol=1e-5)
    H, g, cost = DenseAssembler(graph, sparse)(poses, landmarks)
    assert np.allclose(H, (J.T @ J).toarray()) and np.allclose(g, J.T @ r) and cost == pytest.approx(0.5 * r @ r)


def interleaved() -> list:
    """Robot 1 starts; robot 2 starts later; both move at t = 2 (robot 1 first); robot 1 sights robot 2 then."""
    return [
        Start(0.0, (0.0, 0.0, 0.0), robot=1),
        Odometry(1.0, (1.0, 0.0, 0.0), SIG3, robot=1),
        Start(1.5, (1.0, 2.0, 0.0), robot=2),
        Odometry(2.0, (1.0, 0.0, 0.0), SIG3, robot=1),
        Odometry(2.0, (0.5, 0.0, 0.0), SIG3, robot=2),
        Observation(2.0, None, 2.0, 1.0, SIG2, robot=1, robot_seen=2),
        Odometry(3.0, (1.0, 0.0, 0.0), SIG3, robot=2),
    ]


def test_steps_of_several_robots_leave_in_index_order() -> None:
    steps = list(FrontEnd().steps(interleaved()))
    assert [(s.index, s.robot, s.t) for s in steps] == [(0, 1, 0.0), (1, 1, 1.0), (2, 2, 1.5), (3, 1, 2.0),
                                                        (4, 2, 2.0), (5, 2, 3.0)]  # fmt: skip
    assert steps[3].robots_seen == (2,) and steps[2].prior is not None and steps[4].odometry is not None


def test_a_robot_sighting_links_the_seen_pose_of_its_time_even_when_it_comes_later() -> None:
    batch = BatchEstimator()
    for step in FrontEnd().steps(interleaved()):
        batch.step(step)
    graph = batch.log.graph()
    assert list(graph.odo_from) == [0, 1, 2, 4] and list(graph.odo_to) == [1, 3, 4, 5]
    assert list(graph.rob_from) == [3] and list(graph.rob_to) == [4]  # robot 2's pose of t = 2, index 4
    assert list(graph.fixed_poses) == [0, 2]  # both starts held


def test_the_multi_robot_batch_equals_gtsam_levenberg_marquardt() -> None:
    pytest.importorskip("gtsam", reason="the 'peers' extra (gtsam) is not installed")
    from online_slam import gtsam_peer

    batch = BatchEstimator()
    for step in FrontEnd().steps(meet_world(MeetConfig(poses=80))):
        batch.step(step)
    ours = batch.finish()
    graph = batch.log.graph()
    assert len(graph.rob_from) > 20 and ours.info["converged"]
    peer = gtsam_peer.levenberg_marquardt(graph, np.array(batch.log.poses), batch.log.landmarks, exact=True, tight=True)
    assert np.max(np.linalg.norm(ours.poses[:, :2] - peer.poses[:, :2], axis=1)) <= 1e-5
    assert np.max(np.linalg.norm(ours.landmarks - peer.landmarks, axis=1)) <= 1e-5
    assert ours.info["final_cost"] == pytest.approx(peer.final_cost, rel=1e-5)


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
    config = ReplayConfig(estimators=("ekf", "batch"))
    with_them, without = replay(drifting(True), config), replay(drifting(False), config)
    ekf, batch = (with_them.estimators[n].robots["2"] for n in ("ekf", "batch"))
    ekf_alone, batch_alone = (without.estimators[n].robots["2"] for n in ("ekf", "batch"))
    assert ekf.online_rmse_m < 0.5 * ekf_alone.online_rmse_m
    assert batch.final_rmse_m < 0.5 * batch_alone.final_rmse_m
    assert with_them.estimators["ekf"].details["robot_sightings_used"] > 100


def test_figures_per_robot_add_up_to_those_over_all_robots() -> None:
    results = replay("meet", ReplayConfig(estimators=("ekf", "batch")))
    for result in results.estimators.values():
        assert sorted(result.robots) == ["1", "2", "3"]
        steps = 3 * MeetConfig.poses
        squares = sum(r.final_rmse_m**2 * MeetConfig.poses for r in result.robots.values())
        assert np.sqrt(squares / steps) == pytest.approx(result.final_rmse_m, rel=1e-9)
        gaps = [r.endpoint_gap_m for r in result.robots.values()]  # each robot's loop, not one robot to another
        assert result.endpoint_gap_m == pytest.approx(np.sqrt(np.mean(np.square(gaps))), rel=1e-12)
        assert result.endpoint_gap_m < 2.0
    odometry = results.odometry  # dead reckoning too
    squares = sum(r.rmse_m**2 * MeetConfig.poses for r in odometry.robots.values())
    assert sorted(odometry.robots) == ["1", "2", "3"]
    assert np.sqrt(squares / (3 * MeetConfig.poses)) == pytest.approx(odometry.rmse_m, rel=1e-9)
    assert results.to_json()["odometry"]["robots"]["2"]["rmse_m"] == odometry.robots["2"].rmse_m
    ekf = results.estimators["ekf"]
    assert ekf.online_rmse_m < 0.1 and results.estimators["batch"].final_rmse_m < ekf.final_rmse_m
    whole_run = (
        "gated",
        "landmarks_",
        "state_",
        "robot",
        "association",
        "outliers",
        "linearization",
        "pose_covariance",
        "adapted_noise",
    )
    assert set(ekf.robots["1"].to_json()) == {k for k in ekf.to_json() if not k.startswith(whole_run)}


def test_replay_meet_runs_every_estimator() -> None:
    done = run_cli("replay", "meet", "--json", "-")
    assert done.returncode == 0, done.stderr
    data = json.loads(done.stdout)
    assert not data.get("left") and sorted(data["estimators"]) == ["batch", "ekf", "smoother"]
    for name in ("ekf", "smoother"):
        assert sorted(data["estimators"][name]["robots"]) == ["1", "2", "3"]
    assert "left out" not in done.stderr
    assert "ekf  robot 3" in done.stderr and "smoother  robot 3" in done.stderr


def test_the_ekf_refuses_first_estimates_for_several_robots() -> None:
    with pytest.raises(OnlineSlamError, match="^several robots: the EKF's fej and oc linearizations take one robot"):
        replay("meet-apart", ReplayConfig(estimators=("ekf",), ekf=EkfConfig(linearization="fej")))


def test_the_invariant_ekf_updates_as_the_standard_one_once_a_second_robot_begins() -> None:
    """Its group has one heading: with several robots the updates are the standard ones (the covariance is in the
    same coordinates either way); with one robot they are not."""
    for world, same in (("square", False), ("meet-apart", True)):
        steps = list(FrontEnd().steps(WORLDS[world].events(0)))
        invariant = EkfSlam(EkfConfig(linearization="invariant"))
        for step in steps[:5]:  # meet-apart: both robots have begun
            invariant.step(step)
        standard = EkfSlam(dataclasses.replace(invariant.config, linearization="standard"))
        standard.load_state(copy.deepcopy(invariant.state_dict()))
        for step in steps[5:40]:
            invariant.step(step)
            standard.step(step)
        assert (np.array_equal(invariant.x, standard.x) and np.array_equal(invariant.P, standard.P)) == same


def test_the_invariant_smoother_recentres_its_prior_exactly_with_several_robots() -> None:
    """With several robots the prior holds several headings: it is re-centred exactly, as the standard one (with
    solves started undamped as the invariant option starts them, the runs are the same bit for bit); with one
    robot its covariance is carried and the runs differ."""
    from online_slam.estimators.smoother import SlidingWindowSmoother, WindowConfig

    window = WindowConfig(size=5, distance=0.0)
    solver = dataclasses.replace(SmootherConfig().solver, initial_lambda=0.0)
    for world, same in (("square", False), ("meet-apart", True)):
        steps = list(FrontEnd().steps(WORLDS[world].events(0)))[:80]
        runs = []
        for config in (
            SmootherConfig(window=window, linearization="invariant"),
            SmootherConfig(window=window, solver=solver, linearization="standard"),
        ):
            smoother = SlidingWindowSmoother(config)
            runs.append(np.array([smoother.step(step).pose for step in steps]))
        assert len(steps) > 20  # the window has marginalized poses
        assert np.array_equal(runs[0], runs[1]) == same


def test_the_table_says_which_linearization_the_ekf_and_the_smoother_ran() -> None:
    apart = list(WORLDS["meet-apart"].events(0))[:600]  # a quarter: both robots have begun at its third event
    one = format_results(replay("square", ReplayConfig(estimators=("ekf",))))
    several = format_results(replay(apart, ReplayConfig(estimators=("ekf",)), name="meet-apart"))
    assert "\nekf: invariant linearization\n" in one + "\n"
    assert "\nekf: invariant linearization (standard updates: several robots)" in several
    smoothers = [
        format_results(replay(world, ReplayConfig(estimators=("smoother",), smoother=SmootherConfig(linearization=l))))
        for world, l in (("square", "standard"), (apart, "invariant"))
    ]
    assert "\nsmoother: standard linearization\n" in smoothers[0] + "\n"
    assert "\nsmoother: invariant linearization (re-centred: several robots)" in smoothers[1]
