"""The circle world (esde's Monte Carlo protocol) and the EKF's consistent linearizations (FEJ, OC, invariant)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import circle_anees

from online_slam.estimators.ekf import EkfSlam
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.linearization import (
    heading_column,
    invariant_retraction,
    null_space,
    observable,
    transport,
)
from online_slam.frontend.steps import FrontEnd
from online_slam.geometry.se2 import compose
from online_slam.models.range_bearing import range_bearing_with_jacobians
from online_slam.pipeline import ReplayConfig
from online_slam.sources.events import LandmarkTruth, Observation, Odometry, Start, Truth
from online_slam.sources.worlds import WORLDS, CircleConfig, circle_landmarks, circle_world


def test_circle_landmarks_are_esdes_gen_map() -> None:
    c = CircleConfig()
    landmarks = circle_landmarks(c)
    radius = 0.25 / 0.075 + 2 * 0.5
    for i in range(1, 16):  # gen_map.m: th = 2 pi i / nL, rho = v / omega + 2 rmin, centre (0.1251, 3.3318)
        th = 2 * np.pi * i / 15
        assert landmarks[i - 1] == pytest.approx([radius * np.cos(th) + 0.1251, radius * np.sin(th) + 3.3318])
    events = list(circle_world())
    truth_landmarks = {e.landmark: e.position for e in events if isinstance(e, LandmarkTruth)}
    assert np.array([truth_landmarks[j] for j in range(15)]) == pytest.approx(landmarks)


def test_circle_truth_odometry_and_visibility_follow_rws() -> None:
    c = CircleConfig()
    events = list(circle_world(c))
    start = next(e for e in events if isinstance(e, Start))
    assert start.pose == (0.0, 0.0, 0.0) and start.fixed
    truth = np.array([e.pose for e in events if isinstance(e, Truth)])
    odometry = [e for e in events if isinstance(e, Odometry)]
    assert len(truth) == 400 and len(odometry) == 399
    expected = np.zeros(3)
    for i in range(1, 400):  # rws.m: x_k = x_k-1 + v dt (cos, sin)(theta_k-1), theta_k = theta_k-1 + omega dt
        expected = compose(expected, [0.25, 0.0, 0.075])
        assert truth[i] == pytest.approx(expected, abs=1e-12)
    assert all(e.delta[1] == 0.0 and e.sigma == pytest.approx((0.02 / np.sqrt(2), 1e-6, 0.04 * np.sqrt(2)))
               for e in odometry)  # fmt: skip
    sightings = [e for e in events if isinstance(e, Observation)]
    landmarks = circle_landmarks(c)
    seen = {(round(e.t), e.landmark) for e in sightings}
    assert len(seen) == len(sightings)
    for i, pose in enumerate(truth):
        ranges = np.hypot(*(landmarks - pose[:2]).T)
        visible = {(i, j) for j in range(15) if 0.5 < ranges[j] < 5.0} if i > 0 else set()
        assert {s for s in seen if s[0] == i} == visible  # none from the first pose
    assert all(e.xy is not None and e.range is None and e.sigma == (0.1, 0.1) for e in sightings)


def _draws(c: CircleConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """esde's draws, written from the formulas: (measured speeds, turn rates, visible (pose, landmark), noise)."""
    rng = np.random.default_rng(c.seed)
    v_m = 0.25 + 0.02 / np.sqrt(2) * rng.normal(size=c.poses)
    omega_m = 0.075 + 2 * np.sqrt(2) * 0.02 * rng.normal(size=c.poses)
    theta = 0.075 * np.arange(c.poses)
    xy = np.zeros((c.poses, 2))
    xy[1:] = np.cumsum(0.25 * np.c_[np.cos(theta[:-1]), np.sin(theta[:-1])], axis=0)
    visible = [(i, j) for i in range(c.poses) for j, point in enumerate(circle_landmarks(c))
               if 0.5 < np.hypot(*(point - xy[i])) < 5.0]  # fmt: skip
    return v_m, omega_m, np.array(visible), rng.normal(size=(len(visible), 2))


@pytest.mark.parametrize("model", ["xy", "range-bearing"])
def test_circle_draws_are_the_formulas(model: str) -> None:
    """Every number of the stream from esde's formulas: velocity-input odometry (v_m dt, 0, omega_m dt); a
    landmark's position in the robot frame plus 0.1 m per axis, or its range and bearing plus (0.1 m, 0.04 rad)."""
    c = CircleConfig(poses=120, model=model, seed=5)
    v_m, omega_m, visible, noise = _draws(c)
    events = list(circle_world(c))
    deltas = np.array([e.delta for e in events if isinstance(e, Odometry)])
    assert deltas == pytest.approx(np.c_[v_m, np.zeros(c.poses), omega_m][:-1], abs=1e-15)
    truth = np.array([e.pose for e in events if isinstance(e, Truth)])
    landmarks = circle_landmarks(c)
    sightings = [e for e in events if isinstance(e, Observation)]
    used = visible[:, 0] > 0  # the first pose's draws are made, not used
    assert [(round(e.t), e.landmark) for e in sightings] == [tuple(v) for v in visible[used]]
    for e, (i, j), n in zip(sightings, visible[used], noise[used]):
        pose, d = truth[i], landmarks[j] - truth[i][:2]
        if model == "xy":
            c_, s_ = np.cos(pose[2]), np.sin(pose[2])
            assert e.xy == pytest.approx([c_ * d[0] + s_ * d[1] + 0.1 * n[0], -s_ * d[0] + c_ * d[1] + 0.1 * n[1]])
            assert e.sigma == (0.1, 0.1)
        else:
            bearing = np.arctan2(d[1], d[0]) - pose[2] + 0.04 * n[1]
            assert e.range == pytest.approx(np.hypot(*d) + 0.1 * n[0])
            assert np.cos(e.bearing - bearing) == pytest.approx(1.0) and abs(e.bearing) <= np.pi
            assert e.sigma == (0.1, 0.04)


def test_circle_is_a_built_in_world_scored_over_esdes_steps() -> None:
    world = WORLDS["circle"]
    assert world.scored == WORLDS["circle-rb"].scored == (4, 398)
    assert list(world.events(3)) == list(circle_world(CircleConfig(seed=3)))
    assert list(WORLDS["circle-rb"].events(3)) == list(circle_world(CircleConfig(model="range-bearing", seed=3)))
    with pytest.raises(ValueError, match="model"):
        CircleConfig(model="bearing-only")


def test_simulate_circle_takes_the_sighting_model(tmp_path: Path) -> None:
    from online_slam.cli.main import main
    from online_slam.sources import read_stream

    paths = [tmp_path / f"{k}.jsonl" for k in range(3)]
    assert main(["simulate", "circle", "--model", "range-bearing", "--seed", "4", "-o", str(paths[0])]) == 0
    assert main(["simulate", "circle-rb", "--seed", "4", "-o", str(paths[1])]) == 0
    assert main(["simulate", "circle", "--model", "xy", "--seed", "4", "-o", str(paths[2])]) == 0
    assert paths[0].read_text() == paths[1].read_text()
    assert list(read_stream(paths[2]))[1:] == list(circle_world(CircleConfig(seed=4)))[1:]  # header: lists for tuples
    assert main(["simulate", "circle-rb", "--model", "xy", "-o", str(paths[0])]) == 2  # a fixed world


def test_heading_column_is_the_derivative_of_a_turn() -> None:
    v, origin, h = np.array([1.3, -0.4]), np.array([0.2, 0.7]), 1e-7

    def turned(a: float) -> np.ndarray:
        c, s = np.cos(a), np.sin(a)
        return origin + np.array([[c, -s], [s, c]]) @ (v - origin)

    assert heading_column(v, origin) == pytest.approx((turned(h) - turned(-h)) / (2 * h), abs=1e-8)


def test_observable_jacobians_see_nothing_of_the_null_space_and_change_least() -> None:
    rng = np.random.default_rng(4)
    pose, landmarks = np.array([0.3, -0.2, 0.4]), rng.uniform(-3, 3, size=(5, 2))
    _, J_p, J_l = range_bearing_with_jacobians(pose, landmarks)
    robot_star, first = pose[:2] + [0.05, -0.03], landmarks + rng.normal(scale=0.1, size=landmarks.shape)
    O_p, O_l = observable(J_p, J_l, robot_star, first)
    N = null_space(robot_star, first)
    assert np.abs(np.concatenate([O_p, O_l], axis=-1) @ N).max() < 1e-12
    change = np.concatenate([J_p - O_p, J_l - O_l], axis=-1)  # in the row space of N^T: the nearest such H
    assert change == pytest.approx(change @ N @ np.linalg.pinv(N), abs=1e-12)
    # at the point itself the range-bearing Jacobians already satisfy the constraint: unchanged
    _, J_p0, J_l0 = range_bearing_with_jacobians(pose, landmarks)
    same_p, same_l = observable(J_p0, J_l0, pose[:2], landmarks)
    assert same_p == pytest.approx(J_p0, abs=1e-12) and same_l == pytest.approx(J_l0, abs=1e-12)


def test_fej_keeps_first_estimates_and_maps_the_null_space_through_placement() -> None:
    ekf = EkfSlam(EkfConfig(linearization="fej"))
    steps = FrontEnd().steps(circle_world(CircleConfig(poses=30, seed=2)))
    placed: dict = {}
    for step in steps:
        before = set(ekf.landmark_ids)
        ekf.step(step)
        for lid in set(ekf.landmark_ids) - before:
            placed[lid] = ekf.x[3 + 2 * ekf.state.index[lid] : 5 + 2 * ekf.state.index[lid], 0].copy()
    assert ekf.state.first == pytest.approx(np.array([placed[lid] for lid in ekf.landmark_ids]), abs=0)
    assert not np.allclose(ekf.state.first, ekf.x[3:, 0].reshape(-1, 2))  # estimates moved, first ones did not
    z = np.array([2.0, 0.3])
    position, G_r, _ = ekf._placed(z, 0)
    N_r = null_space(ekf.state.predicted[:2], position[None])[0]
    assert G_r @ N_r[:3] == pytest.approx(N_r[3:], abs=1e-12)  # the robot's directions onto the landmark's


@pytest.mark.slow
@pytest.mark.parametrize("linearization, consistent", [("standard", False), ("fej", True), ("invariant", True)])
def test_ten_run_anees_fails_for_the_standard_ekf_and_passes_for_the_consistent_ones(
    linearization: str, consistent: bool
) -> None:
    """esde's world, 10 seeded runs (100..109; ~4 s of CPU each linearization): the standard EKF is overconfident,
    FEJ and invariant inside the 95% band (measured: 6.48, 3.50, 3.49; band 1.68 .. 4.70). OC reads FEJ's 3.50 on
    these runs (3.12 both at esde's 20, seeds 100..119, band 2.02 .. 4.16; standard 5.90): it is left to ``python -m
    benchmarks --only circle``, its null space to the Jacobian tests above. Cut to 200 poses the standard EKF is not
    yet overconfident (3.84 at 20 runs): the drift that makes it so takes the whole 400."""
    config = ReplayConfig(estimators=("ekf",), ekf=EkfConfig(linearization=linearization))
    anees, low, high = circle_anees(config, seeds=tuple(range(100, 110)))
    assert (low <= anees <= high) == consistent and anees >= low, anees


def _group_error_to_ours(x: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """``exp(xi) X_hat - X_hat`` in our coordinates (heading wrapped): the invariant EKF's error as ours see it."""
    moved, _ = invariant_retraction(x, _D(x) @ xi)  # the correction that is xi on the group
    d = moved - x
    d[2] = np.angle(np.exp(1j * d[2]))
    return d


def _D(x: np.ndarray) -> np.ndarray:
    """d (our error) / d (group error xi) at x: I, with ``J p`` in the heading's column for each position."""
    D = np.eye(len(x))
    D[:2, 2] = heading_column(x[:2], 0.0)
    D[3:, 2] = heading_column(x[3:].reshape(-1, 2), 0.0).ravel()
    return D


def test_invariant_retraction_is_the_groups_exponential() -> None:
    rng = np.random.default_rng(4)
    x = np.r_[1.0, -2.0, 0.4, rng.normal(size=6) * 3.0]
    # a pure turn of the group error turns every position (robot and landmarks) about the origin
    turn = np.zeros(9)
    turn[2] = 0.3
    xi_as_ours = _D(x) @ turn  # the same correction, in our coordinates
    moved, _ = invariant_retraction(x, xi_as_ours)
    R = np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]])
    points = np.r_[x[:2], x[3:]].reshape(-1, 2)
    assert np.r_[moved[:2], moved[3:]].reshape(-1, 2) == pytest.approx(points @ R.T, abs=1e-12)
    assert moved[2] == pytest.approx(0.7)
    # to first order the correction is additive: d (result) / d (dx) at 0 is the identity (numerically)
    eps = 1e-7
    numeric = np.array(
        [(invariant_retraction(x, eps * e)[0] - invariant_retraction(x, -eps * e)[0]) / (2 * eps) for e in np.eye(9)]
    ).T
    assert numeric == pytest.approx(np.eye(9), abs=1e-6)


def test_invariant_transport_is_the_change_of_linearization_point() -> None:
    """The transport T carries a covariance in our coordinates at x to one at the corrected x+ with the same group
    covariance: ``T = D(x+) D(x)^-1``, D the Jacobian of our error in the group error (checked numerically)."""
    rng = np.random.default_rng(5)
    x = np.r_[0.5, 1.5, -0.2, rng.normal(size=4) * 4.0]
    eps = 1e-7
    numeric = np.array(
        [(_group_error_to_ours(x, eps * e) - _group_error_to_ours(x, -eps * e)) / (2 * eps) for e in np.eye(7)]
    ).T
    assert numeric == pytest.approx(_D(x), abs=1e-6)
    dx = rng.normal(size=7) * 0.2
    moved, column = invariant_retraction(x, dx)
    A = rng.normal(size=(7, 7))
    P = A @ A.T
    carried = P.copy()
    transport(carried, column)
    T = _D(moved) @ np.linalg.inv(_D(x))
    assert carried == pytest.approx(T @ P @ T.T, rel=1e-10, abs=1e-12)


def test_our_standard_ekf_equals_an_independent_port_of_esdes_on_the_same_draws() -> None:
    """benchmarks/esde_port.py is esde's rws.m and standard EKF written from their Matlab code alone; on the same
    draws its ANEES must be ours (it differs only by our stream's 1e-6 m lateral odometry sigma: 2e-4 measured),
    both reporting the covariance as linearized."""
    from benchmarks.esde_port import run

    seeds = (100, 101, 102)
    textbook = EkfConfig(linearization="standard", pose_covariance="linear")
    ours, low, high = circle_anees(ReplayConfig(estimators=("ekf",), ekf=textbook), seeds)
    port = run(range(100, 103))
    assert port.anees == pytest.approx(ours, rel=1e-3) and port.band == pytest.approx((low, high))
    assert run(range(100, 103), jacobians_at="truth").anees < 0.6 * ours  # the standard EKF's overconfidence


def _noise_free_circle() -> list[object]:
    """The circle world with every odometry increment and sighting exactly true (its noise declared as usual)."""
    from dataclasses import replace

    from online_slam.geometry.se2 import between, rotation

    events = list(circle_world(CircleConfig(poses=60)))
    truth = {e.t: np.array(e.pose) for e in events if isinstance(e, Truth)}
    landmarks = {e.landmark: np.array(e.position) for e in events if isinstance(e, LandmarkTruth)}
    times = sorted(truth)
    previous = {t: truth[times[k - 1]] for k, t in enumerate(times) if k}
    exact: list[object] = []
    for e in events:
        if isinstance(e, Odometry):
            e = replace(e, delta=tuple(between(previous[e.t], truth[e.t])))
        elif isinstance(e, Observation):
            pose = truth[e.t]
            e = replace(e, xy=tuple(rotation(pose[2]).T @ (landmarks[e.landmark] - pose[:2])))
        exact.append(e)
    return exact


def test_the_ideal_ekf_is_the_ekf_where_the_estimate_is_the_truth() -> None:
    """Noise-free data keep the estimate at the truth, so Jacobians at the truth are the EKF's own: the same
    covariances to 1e-9; on noisy data they differ."""
    from online_slam.estimators.ideal_ekf import IdealEkf

    for events, same in ((_noise_free_circle(), True), (list(circle_world(CircleConfig(poses=60))), False)):
        front = FrontEnd()
        steps = list(front.steps(events))
        ekf, ideal = EkfSlam(EkfConfig(linearization="standard")), IdealEkf(front.truth)
        gaps = []
        for step in steps:
            a, b = ekf.step(step), ideal.step(step)
            gaps.append(np.abs(a.pose_cov - b.pose_cov).max())
        assert (max(gaps) < 1e-9) == same, max(gaps)
    assert np.abs(b.pose - front.truth.poses[steps[-1].index]).max() < 1.0


def test_the_ideal_ekf_refuses_a_stream_without_truth() -> None:
    from online_slam.errors import OnlineSlamError
    from online_slam.estimators.ideal_ekf import IdealEkf
    from online_slam.frontend.pose import GroundTruth

    steps = list(FrontEnd().steps(circle_world(CircleConfig(poses=5))))
    ideal = IdealEkf(GroundTruth())
    ideal.step(steps[0])
    with pytest.raises(OnlineSlamError, match="ideal EKF: no true pose for step"):
        ideal.step(steps[1])
