"""Position sightings: the model, its inverse and their Jacobians; per-sighting dispatch between the models."""

from __future__ import annotations

import numpy as np
from conftest import numerical_jacobian
from hypothesis import given
from hypothesis import strategies as st

from online_slam.models import (
    POSITION,
    RANGE_BEARING,
    landmark_from_observation,
    landmark_from_position,
    landmark_from_position_with_jacobians,
    landmark_from_sighting,
    landmark_from_sighting_with_jacobians,
    position,
    position_with_jacobians,
    predict_with_jacobians,
    range_bearing,
    range_bearing_from_position,
    range_bearing_with_jacobians,
    wrap_bearings,
)

coords = st.floats(-50.0, 50.0, allow_nan=False)
angles = st.floats(-10.0, 10.0, allow_nan=False)


@given(coords, coords, angles, st.floats(-30.0, 30.0), st.floats(-30.0, 30.0))
def test_inverse_position_round_trips(x: float, y: float, th: float, dx: float, dy: float) -> None:
    pose = np.array([x, y, th])
    landmark = landmark_from_position(pose, [dx, dy])
    assert np.allclose(position(pose, landmark), [dx, dy], rtol=1e-9, atol=1e-9)


def test_position_is_the_landmark_in_the_robot_frame() -> None:
    pose = np.array([1.0, 2.0, np.pi / 2])  # facing +y
    assert np.allclose(position(pose, [1.0, 5.0]), [3.0, 0.0])
    assert np.allclose(position(pose, [0.0, 2.0]), [0.0, 1.0])


def test_position_jacobians(rng: np.random.Generator) -> None:
    for _ in range(30):
        pose, lm = rng.normal(size=3) * [5, 5, 3], rng.normal(size=2) * 5
        _, J_p, J_l = position_with_jacobians(pose, lm)
        assert np.allclose(J_p, numerical_jacobian(lambda p: position(p, lm), pose), atol=1e-6)
        assert np.allclose(J_l, numerical_jacobian(lambda x: position(pose, x), lm), atol=1e-6)


def test_inverse_position_jacobians(rng: np.random.Generator) -> None:
    for _ in range(30):
        pose, z = rng.normal(size=3) * [5, 5, 3], rng.normal(size=2) * 5
        _, J_p, J_z = landmark_from_position_with_jacobians(pose, z)
        assert np.allclose(J_p, numerical_jacobian(lambda p: landmark_from_position(p, z), pose), atol=1e-6)
        assert np.allclose(J_z, numerical_jacobian(lambda x: landmark_from_position(pose, x), z), atol=1e-6)


def test_position_jacobians_vectorised(rng: np.random.Generator) -> None:
    poses, landmarks = rng.normal(size=(7, 3)) * 4, rng.normal(size=(7, 2)) * 4
    z, J_p, J_l = position_with_jacobians(poses, landmarks)
    for i in range(7):
        one = position_with_jacobians(poses[i], landmarks[i])
        assert np.allclose(z[i], one[0]) and np.allclose(J_p[i], one[1]) and np.allclose(J_l[i], one[2])


def test_range_bearing_from_position_propagates_covariance(rng: np.random.Generator) -> None:
    z, cov = np.array([3.0, 4.0]), np.diag([0.01, 0.04])
    rb, rb_cov = range_bearing_from_position(z, cov)
    assert np.allclose(rb, [5.0, np.arctan2(4.0, 3.0)])
    samples = z + rng.multivariate_normal(np.zeros(2), cov, 200_000)
    polar = np.c_[np.hypot(samples[:, 0], samples[:, 1]), np.arctan2(samples[:, 1], samples[:, 0])]
    assert np.allclose(rb_cov, np.cov(polar.T), rtol=0.05, atol=1e-5)


def test_dispatch_by_tag_matches_each_model(rng: np.random.Generator) -> None:
    poses, landmarks = rng.normal(size=(6, 3)) * 4, rng.normal(size=(6, 2)) * 4
    model = np.array([0, 1, 1, 0, 1, 0], dtype=np.int8)
    z, J_p, J_l = predict_with_jacobians(poses, landmarks, model)
    rb, xy = range_bearing_with_jacobians(poses, landmarks), position_with_jacobians(poses, landmarks)
    for got, a, b in zip((z, J_p, J_l), rb, xy):
        assert np.array_equal(got[model == RANGE_BEARING], a[model == RANGE_BEARING])
        assert np.array_equal(got[model == POSITION], b[model == POSITION])
    points = landmark_from_sighting(poses, z, model)
    assert np.allclose(points, landmarks)
    value, G_p, G_z = landmark_from_sighting_with_jacobians(poses, z, model)
    assert np.allclose(value, landmarks)
    i = 1
    f = lambda x: landmark_from_sighting(poses[i], x, POSITION)  # noqa: E731
    assert np.allclose(G_z[i], numerical_jacobian(f, z[i]), atol=1e-6)


def test_range_bearing_dispatch_is_bit_identical(rng: np.random.Generator) -> None:
    poses, landmarks = rng.normal(size=(9, 3)) * 4, rng.normal(size=(9, 2)) * 4
    rb = range_bearing_with_jacobians(poses, landmarks)
    for got, want in zip(predict_with_jacobians(poses, landmarks, np.zeros(9, dtype=np.int8)), rb):
        assert np.array_equal(got, want)
    z = range_bearing(poses, landmarks)
    assert np.array_equal(landmark_from_sighting(poses, z, RANGE_BEARING), landmark_from_observation(poses, z))


def test_only_bearings_are_wrapped() -> None:
    e = np.array([[0.0, 7.0], [0.0, 7.0]])
    wrap_bearings(e, np.array([RANGE_BEARING, POSITION]))
    assert np.isclose(e[0, 1], 7.0 - 2 * np.pi) and e[1, 1] == 7.0
