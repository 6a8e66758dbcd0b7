"""SE(2) and wrap: group properties (hypothesis) and analytic vs numerical Jacobians."""

from __future__ import annotations

import numpy as np
from conftest import numerical_jacobian
from hypothesis import given
from hypothesis import strategies as st

from online_slam.geometry import between, between_with_jacobians, compose, compose_with_jacobians, inverse, wrap

angles = st.floats(-50.0, 50.0, allow_nan=False)
coords = st.floats(-100.0, 100.0, allow_nan=False)
poses = st.tuples(coords, coords, angles).map(np.array)


@given(angles)
def test_wrap_is_in_range_and_idempotent(a: float) -> None:
    w = wrap(a)
    assert -np.pi <= w < np.pi
    assert wrap(w) == w
    assert np.isclose(np.cos(w), np.cos(a), atol=1e-9) and np.isclose(np.sin(w), np.sin(a), atol=1e-9)


@given(st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from([np.pi, -np.pi, 3 * np.pi, -0.0, -1e-20])))
def test_wrap_of_one_number_is_wrap_of_an_array_to_the_bit(a: float) -> None:
    """Numbers take a scalar path (Python float arithmetic): the same bits, sign of zero included."""
    expected = wrap(np.array([a]))[0]
    for number in (a, np.float64(a)):
        w = wrap(number)
        assert isinstance(w, np.float64) and w == expected and np.signbit(w) == np.signbit(expected)
    assert wrap(np.array(a)).shape == ()  # a 0-d array stays an array


def test_wrap_near_pi_boundaries() -> None:
    assert wrap(np.pi) == -np.pi
    assert wrap(-np.pi) == -np.pi
    below = np.nextafter(np.pi, 0)  # rounds onto the boundary: -pi is the same angle to the last bit
    assert abs(np.sin(wrap(below)) - np.sin(below)) < 1e-15 and -np.pi <= wrap(below) < np.pi
    assert wrap(3 * np.pi) == -np.pi
    w = wrap(np.array([np.pi - 1e-15, -np.pi + 1e-15, 1e9, -1e9]))
    assert np.all((w >= -np.pi) & (w < np.pi))


@given(poses, poses)
def test_between_inverts_compose(a: np.ndarray, d: np.ndarray) -> None:
    b = compose(a, d)
    back = between(a, b)
    assert np.allclose(back[:2], d[:2], atol=1e-8)
    assert abs(wrap(back[2] - d[2])) < 1e-9


@given(poses)
def test_inverse_composes_to_identity(a: np.ndarray) -> None:
    e = compose(a, inverse(a))
    assert np.allclose(e[:2], 0.0, atol=1e-9) and abs(wrap(e[2])) < 1e-9


@given(poses, poses, poses)
def test_compose_is_associative(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> None:
    left, right = compose(compose(a, b), c), compose(a, compose(b, c))
    assert np.allclose(left[:2], right[:2], atol=1e-7) and abs(wrap(left[2] - right[2])) < 1e-9


def test_vectorised_matches_single(rng: np.random.Generator) -> None:
    a = rng.normal(size=(50, 3)) * [5, 5, 3]
    b = rng.normal(size=(50, 3)) * [5, 5, 3]
    stacked = between(a, b)
    assert np.allclose(stacked, np.array([between(x, y) for x, y in zip(a, b)]))


def test_compose_jacobians_match_numerical(rng: np.random.Generator) -> None:
    for _ in range(20):
        a, d = rng.normal(size=3) * [3, 3, 3], rng.normal(size=3) * [3, 3, 3]
        _, J_a, J_d = compose_with_jacobians(a, d)
        assert np.allclose(J_a, numerical_jacobian(lambda x: compose(x, d), a, (2,)), atol=1e-6)
        assert np.allclose(J_d, numerical_jacobian(lambda x: compose(a, x), d, (2,)), atol=1e-6)


def test_between_jacobians_match_numerical(rng: np.random.Generator) -> None:
    for _ in range(20):
        a, b = rng.normal(size=3) * [3, 3, 3], rng.normal(size=3) * [3, 3, 3]
        _, J_a, J_b = between_with_jacobians(a, b)
        assert np.allclose(J_a, numerical_jacobian(lambda x: between(x, b), a, (2,)), atol=1e-6)
        assert np.allclose(J_b, numerical_jacobian(lambda x: between(a, x), b, (2,)), atol=1e-6)


def test_jacobians_vectorise(rng: np.random.Generator) -> None:
    a, b = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    _, J_a, J_b = between_with_jacobians(a, b)
    for k in range(7):
        _, ja, jb = between_with_jacobians(a[k], b[k])
        assert np.allclose(J_a[k], ja) and np.allclose(J_b[k], jb)
