"""EKF-SLAM: structured operations equal their dense filterpy counterparts; gating; consistency; PSD; accuracy."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la
from conftest import numerical_jacobian
from filterpy.kalman import ExtendedKalmanFilter
from scipy.stats import chi2

import online_slam
from benchmarks.ekf import random_state
from online_slam.estimators import EkfConfig, EkfSlam
from online_slam.estimators.linearization import invariant_retraction, transport
from online_slam.frontend import FrontEnd, Step
from online_slam.geometry import compose, compose_with_jacobians, wrap
from online_slam.models import landmark_from_observation, range_bearing, range_bearing_with_jacobians
from online_slam.sources import GridConfig, grid_world, square_world


def random_filter(rng: np.random.Generator, m: int, linearization: str = "standard") -> EkfSlam:
    """A filter holding m landmarks with a random dense SPD covariance."""
    x, P = random_state(rng, m)
    return EkfSlam.from_state(x, P, list(range(m)), EkfConfig(gate_probability=1.0, linearization=linearization))


def dense_H(x: np.ndarray, indices: np.ndarray) -> np.ndarray:
    landmarks = x[3:].reshape(-1, 2)[indices]
    _, J_p, J_l = range_bearing_with_jacobians(x[:3], landmarks)
    H = np.zeros((2 * len(indices), len(x)))
    for i, j in enumerate(indices):
        H[2 * i : 2 * i + 2, :3] = J_p[i]
        H[2 * i : 2 * i + 2, 3 + 2 * j : 5 + 2 * j] = J_l[i]
    return H


def wrapped_residual(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    y = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    y[1::2] = wrap(y[1::2])
    return y


@pytest.mark.parametrize("linearization", ["standard", "invariant"])
@pytest.mark.parametrize(("m", "k"), [(50, 1), (60, 5), (80, 13)])
def test_structured_update_equals_filterpy_stock_update(m: int, k: int, linearization: str) -> None:
    """The standard update is filterpy's; the invariant one is filterpy's correction applied on the group, with
    the covariance carried to the corrected estimate."""
    rng = np.random.default_rng(m * 100 + k)
    ekf = random_filter(rng, m, linearization)
    indices = rng.choice(m, size=k, replace=False)
    x0 = ekf.x[:, 0].copy()
    z = range_bearing(x0[:3], x0[3:].reshape(-1, 2)[indices]) + rng.normal(size=(k, 2)) * [0.1, 0.05]
    z[:, 1] = wrap(z[:, 1])
    B = rng.normal(size=(k, 2, 2)) * 0.1
    R = B @ np.swapaxes(B, 1, 2) + 0.01 * np.eye(2)

    stock = ExtendedKalmanFilter(dim_x=len(x0), dim_z=2 * k)
    stock.x, stock.P = ekf.x.copy(), ekf.P.copy()
    H = dense_H(x0, indices)
    stock.update(
        z.reshape(-1, 1),
        HJacobian=lambda x: H,
        Hx=lambda x: range_bearing(x[:3, 0], x[3:, 0].reshape(-1, 2)[indices]).reshape(-1, 1),
        R=la.block_diag(*R),
        residual=wrapped_residual,
    )
    if linearization == "invariant":
        moved, column = invariant_retraction(x0, stock.x[:, 0] - x0)
        stock.x[:, 0] = moved
        transport(stock.P, column)
    stock.x[2, 0] = wrap(stock.x[2, 0])

    nis, accepted = ekf.update_structured(indices, z, R)
    assert accepted.all() and nis.shape == (k,)
    assert np.max(np.abs(ekf.x - stock.x)) <= 1e-9
    assert np.max(np.abs(ekf.P - stock.P)) <= 1e-9
    assert np.allclose(ekf.S, stock.S, atol=1e-12) and np.allclose(ekf.K, stock.K, atol=1e-9)
    assert np.allclose(ekf.y, stock.y, atol=1e-12)
    assert np.isfinite(ekf.log_likelihood) and np.isclose(ekf.log_likelihood, stock.log_likelihood)


def test_predict_touches_only_the_robot_block() -> None:
    rng = np.random.default_rng(5)
    ekf = random_filter(rng, 20)
    x0, P0 = ekf.x[:, 0].copy(), ekf.P.copy()
    u, Q = np.array([0.5, 0.1, 0.2]), np.diag([0.01, 0.02, 0.003])
    ekf.predict(u, Q)
    _, F_r, G = compose_with_jacobians(x0[:3], u)
    F = np.eye(len(x0))
    F[:3, :3] = F_r
    Gf = np.zeros((len(x0), 3))
    Gf[:3] = G
    assert np.allclose(ekf.P, F @ P0 @ F.T + Gf @ Q @ Gf.T, atol=1e-12)
    assert np.allclose(ekf.x[:3, 0], compose(x0[:3], u)) and np.array_equal(ekf.x[3:, 0], x0[3:])


def test_landmark_initialisation_has_full_cross_covariance() -> None:
    rng = np.random.default_rng(6)
    ekf = random_filter(rng, 10)
    x0, P0 = ekf.x[:, 0].copy(), ekf.P.copy()
    z, R = np.array([4.0, 0.7]), np.diag([0.04, 0.001])
    ekf.add_landmark("new", z, R)

    def augment(v: np.ndarray) -> np.ndarray:
        return np.r_[v[:-2], landmark_from_observation(v[:3], v[-2:])]

    J = numerical_jacobian(augment, np.r_[x0, z])
    expected = J @ la.block_diag(P0, R) @ J.T
    assert ekf.P.shape == (len(x0) + 2,) * 2 and ekf.dim_x == len(x0) + 2 and ekf._I.shape == ekf.P.shape
    assert np.allclose(ekf.P, expected, atol=1e-7)
    assert np.allclose(ekf.x[-2:, 0], landmark_from_observation(x0[:3], z))
    assert ekf.landmark_ids[-1] == "new"


def step_with(index: int, landmarks: tuple, z: np.ndarray, odometry: np.ndarray | None = None) -> Step:
    k = len(landmarks)
    return Step(
        index=index,
        t=float(index),
        odometry=odometry,
        odometry_cov=None if odometry is None else np.diag([0.01, 0.01, 0.001]),
        landmarks=landmarks,
        z=np.asarray(z, dtype=float).reshape(k, 2),
        z_cov=np.tile(np.diag([0.01, 0.0003]), (k, 1, 1)),
        prior=np.zeros(3) if index == 0 else None,
    )


def test_gross_outlier_is_gated_reported_and_harmless() -> None:
    ekf = EkfSlam()
    ekf.step(step_with(0, ("a", "b"), [[3.0, 0.5], [4.0, -0.5]]))
    before = ekf.x.copy()
    snap = ekf.step(step_with(1, ("a", "b"), [[3.0, 0.5 + 2.5], [4.0, -0.5]], odometry=np.zeros(3)))
    assert snap.info["gated"] == ("a",)
    assert snap.info["nis"][0] > chi2.ppf(EkfConfig().gate_probability, 2) and snap.info["nis"][1] < 1.0
    assert np.allclose(snap.landmarks, before[3:, 0].reshape(-1, 2), atol=1e-6)
    assert ekf.finish().info["gated_observations"] == 1


def test_a_moved_landmark_is_reanchored_and_a_drifted_filter_uses_persistent_sightings() -> None:
    from online_slam.estimators.ekf import REANCHOR_AFTER

    # "a" moved while "b" still agrees with the filter: the landmark, not the robot, is off. After
    # REANCHOR_AFTER - 1 rejections of mutually consistent sightings, "a" restarts where they put it.
    ekf = EkfSlam()
    ekf.step(step_with(0, ("a", "b"), [[3.0, 0.5], [4.0, -0.5]]))
    ekf.step(step_with(1, ("a", "b"), [[3.0, 0.5], [4.0, -0.5]], odometry=np.zeros(3)))  # both confirmed
    moved = [[3.0, 0.5 + 1.0], [4.0, -0.5]]
    for index in range(2, 2 + REANCHOR_AFTER - 1):
        assert ekf.step(step_with(index, ("a", "b"), moved, odometry=np.zeros(3))).info["gated"] == ("a",)
    snap = ekf.step(step_with(2 + REANCHOR_AFTER - 1, ("a", "b"), moved, odometry=np.zeros(3)))
    assert snap.info["gated"] == () and ekf.state.reanchored == 1
    expected = 3.0 * np.array([np.cos(1.5), np.sin(1.5)])
    assert np.allclose(snap.landmarks[0], expected, atol=1e-6) and np.allclose(snap.pose, 0.0, atol=1e-6)
    # Every confirmed landmark fails by one robot offset: the filter drifted. After gate_persistence - 1
    # rejections in a row the sightings are used and pull the robot.
    persistence = EkfConfig().gate_persistence
    ekf = EkfSlam()
    first = [[3.0, 0.5], [4.0, -0.5], [5.0, 1.2]]
    ekf.step(step_with(0, ("a", "b", "c"), first))
    ekf.step(step_with(1, ("a", "b", "c"), first, odometry=np.zeros(3)))
    shifted = [[r, b + 1.0] for r, b in first]  # the robot turned 1 rad without knowing it
    for index in range(2, 2 + persistence - 1):
        assert ekf.step(step_with(index, ("a", "b", "c"), shifted, odometry=np.zeros(3))).info["gated"] == (
            "a",
            "b",
            "c",
        )
    snap = ekf.step(step_with(1 + persistence, ("a", "b", "c"), shifted, odometry=np.zeros(3)))
    assert snap.info["gated"] == () and snap.pose[2] < -0.5 and ekf.state.reanchored == 0
    strict = EkfSlam(EkfConfig(gate_persistence=0))
    strict.step(step_with(0, ("a", "b"), [[3.0, 0.5], [4.0, -0.5]]))
    for index in range(1, persistence + 3):
        assert strict.step(step_with(index, ("a", "b"), moved, odometry=np.zeros(3))).info["gated"] == ("a",)


def test_same_new_landmark_twice_in_one_step() -> None:
    ekf = EkfSlam()
    snap = ekf.step(step_with(0, (7, 7), [[3.0, 0.5], [3.01, 0.5]]))
    assert snap.landmark_ids == (7,) and snap.info["new_landmarks"] == (7,)
    assert np.isfinite(snap.info["nis"][1]) and np.isnan(snap.info["nis"][0])


def test_joint_equals_sequential_for_single_observations() -> None:
    steps = [s for s in FrontEnd().steps(square_world())]
    single = [
        Step(s.index, s.t, s.odometry, s.odometry_cov, s.landmarks[:1], s.z[:1], s.z_cov[:1], s.prior, s.prior_cov)
        for s in steps
    ]
    joint, sequential = EkfSlam(EkfConfig(update="joint")), EkfSlam(EkfConfig(update="sequential"))
    for s in single:
        a, b = joint.step(s), sequential.step(s)
    assert np.allclose(a.pose, b.pose, atol=1e-12) and np.allclose(a.pose_cov, b.pose_cov, atol=1e-12)


@pytest.mark.slow
def test_monte_carlo_nees_within_chi_square_bounds() -> None:
    """Average pose NEES over 50 noise seeds of the square world lies inside the 95% bounds (3 dof)."""
    runs = 50
    nees = np.full((runs, 25), np.nan)
    for r in range(runs):
        fe, ekf = FrontEnd(), EkfSlam()
        for step in fe.steps(square_world(seed=1000 + r)):
            snap = ekf.step(step)
            if step.index > 0:  # pose 0 is held fixed: no covariance to test
                e = snap.pose - fe.truth.poses[step.index]
                e[2] = wrap(e[2])
                nees[r, step.index] = e @ np.linalg.solve(snap.pose_cov, e)
    average = nees[:, 1:].mean(axis=0)
    low, high = chi2.ppf([0.025, 0.975], 3 * runs) / runs
    # The first half of the run must be consistent; over the whole run, at most two steps may stray
    # (the 95% band lets 1 in 20 out by chance, and EKF-SLAM grows overconfident as linearization errors add up).
    assert np.all((average[:12] > low) & (average[:12] < high)), average
    assert np.sum((average < low) | (average > high)) <= 2, average


@pytest.mark.slow
@pytest.mark.portable  # symmetric bit for bit on every BLAS kernel: one triangle computed, then mirrored
def test_covariance_stays_symmetric_psd_over_10000_steps() -> None:
    ekf = EkfSlam()
    worst = 0.0
    for step in FrontEnd().steps(grid_world(GridConfig(poses=10_000, landmarks=60, seed=11))):  # 60: a fifth of the CPU
        ekf.step(step)
        if step.index % 500 == 0:
            eig = np.linalg.eigvalsh(ekf.P)
            worst = min(worst, eig[0] / eig[-1])
            assert np.array_equal(ekf.P, ekf.P.T)
    assert step.index == 9_999
    assert worst >= -1e-9
    assert -np.pi <= ekf.x[2, 0] < np.pi


@pytest.mark.slow
def test_ekf_accuracy_on_the_square() -> None:
    square = online_slam.replay("square")
    ekf = square.estimators["ekf"]
    assert ekf.online_rmse_m < 0.25 * square.odometry.rmse_m
    assert ekf.step_ms is not None and ekf.nees_mean is not None
    # on the 2000-pose grid: tests/test_smoother.py::test_window_20_on_the_2000_pose_grid (one replay for both)
