"""Range-bearing model and its inverse, odometry residual, increment composition: values and Jacobians."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import numerical_jacobian
from hypothesis import given
from hypothesis import strategies as st

from online_slam.geometry import compose, wrap
from online_slam.models import (
    compose_increments,
    landmark_from_observation,
    landmark_from_observation_with_jacobians,
    odometry_residual_with_jacobians,
    range_bearing,
    range_bearing_with_jacobians,
)

coords = st.floats(-50.0, 50.0, allow_nan=False)
angles = st.floats(-10.0, 10.0, allow_nan=False)


@given(coords, coords, angles, st.floats(0.1, 30.0), st.floats(-np.pi, np.pi - 1e-9))
def test_inverse_observation_round_trips(x: float, y: float, th: float, r: float, b: float) -> None:
    pose = np.array([x, y, th])
    landmark = landmark_from_observation(pose, [r, b])
    z = range_bearing(pose, landmark)
    assert np.isclose(z[0], r, rtol=1e-9, atol=1e-9)
    assert abs(np.angle(np.exp(1j * (z[1] - b)))) < 1e-8


def test_range_bearing_jacobians(rng: np.random.Generator) -> None:
    for _ in range(30):
        pose, lm = rng.normal(size=3) * [5, 5, 3], rng.normal(size=2) * 5
        _, J_p, J_l = range_bearing_with_jacobians(pose, lm)
        assert np.allclose(J_p, numerical_jacobian(lambda p: range_bearing(p, lm), pose, (1,)), atol=1e-6)
        assert np.allclose(J_l, numerical_jacobian(lambda x: range_bearing(pose, x), lm, (1,)), atol=1e-6)


def test_range_bearing_at_a_landmark_on_the_pose_is_finite_and_unchanged_elsewhere() -> None:
    poses = np.array([[1.0, 2.0, 0.5], [0.0, 0.0, 0.5]])
    landmarks = np.array([[1.0, 2.0], [1e-150, 0.0]])  # on the pose; a hair (1e-150 m) off it
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        z, J_p, J_l = range_bearing_with_jacobians(poses, landmarks)
    assert z[0].tolist() == [0.0, wrap(-0.5)]
    assert not J_l[0].any() and J_p[0].tolist() == [[0.0, 0.0, 0.0], [0.0, 0.0, -1.0]]
    assert J_l[1, 0] == pytest.approx([1.0, 0.0]) and J_l[1, 1, 1] == pytest.approx(1e150)  # off it: analytic


def test_inverse_observation_jacobians(rng: np.random.Generator) -> None:
    for _ in range(30):
        pose, z = rng.normal(size=3) * [5, 5, 3], np.array([rng.uniform(0.5, 10), rng.uniform(-3, 3)])
        _, J_p, J_z = landmark_from_observation_with_jacobians(pose, z)
        assert np.allclose(J_p, numerical_jacobian(lambda p: landmark_from_observation(p, z), pose), atol=1e-6)
        assert np.allclose(J_z, numerical_jacobian(lambda x: landmark_from_observation(pose, x), z), atol=1e-6)


def test_odometry_residual_jacobians(rng: np.random.Generator) -> None:
    for _ in range(30):
        a, b, d = rng.normal(size=3) * 3, rng.normal(size=3) * 3, rng.normal(size=3)
        e, J_a, J_b = odometry_residual_with_jacobians(a, b, d)
        assert -np.pi <= e[2] < np.pi
        f_a = lambda x: odometry_residual_with_jacobians(x, b, d)[0]
        f_b = lambda x: odometry_residual_with_jacobians(a, x, d)[0]
        assert np.allclose(J_a, numerical_jacobian(f_a, a, (2,)), atol=1e-6)
        assert np.allclose(J_b, numerical_jacobian(f_b, b, (2,)), atol=1e-6)


def test_odometry_residual_wraps_across_pi() -> None:
    a = np.array([0.0, 0.0, np.pi - 0.01])
    b = np.array([1.0, 0.0, -np.pi + 0.01])
    e, _, _ = odometry_residual_with_jacobians(a, b, [0.0, 0.0, 0.0])
    assert np.isclose(e[2], 0.02)


def test_compose_increments_mean_and_covariance_by_monte_carlo() -> None:
    rng = np.random.default_rng(3)
    d1, d2 = np.array([1.0, 0.2, 0.3]), np.array([0.5, -0.1, -0.2])
    c1, c2 = np.diag([0.01, 0.02, 0.003]) ** 1, np.diag([0.02, 0.01, 0.002])
    d, cov = compose_increments(d1, c1, d2, c2)
    assert np.allclose(d, compose(d1, d2))
    n = 200_000
    s = compose(d1 + rng.multivariate_normal(np.zeros(3), c1, n), d2 + rng.multivariate_normal(np.zeros(3), c2, n))
    empirical = np.cov(s.T)
    assert np.allclose(cov, empirical, rtol=0.05, atol=2e-4)
    assert np.allclose(cov, cov.T)
