"""The curved second moment of a pose belief (:mod:`online_slam.geometry.pose_moments`)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from online_slam.geometry.pose_moments import curved_covariance


def _belief(lever: tuple[float, float], sigma: float, rest: float = 0.01) -> np.ndarray:
    """A pose covariance whose heading (sd ``sigma``) turns the position about a pivot at ``lever`` from it."""
    l = np.array(lever)
    w = np.array([-l[1], l[0]])  # J l: the position's move per radian
    P = np.zeros((3, 3))
    P[:2, :2] = sigma**2 * np.outer(w, w) + rest**2 * np.array([[1.0, 0.3], [0.3, 2.0]])
    P[:2, 2] = P[2, :2] = sigma**2 * w
    P[2, 2] = sigma**2
    return P


def test_it_is_the_second_moment_of_the_arc_sampled() -> None:
    """Against a million draws of the curved error (a ~ N(0, s^2) turn about the pivot, then V(a) v)."""
    rng = np.random.default_rng(7)
    P = _belief((4.0, -1.5), 0.3)
    s2 = P[2, 2]
    w = P[:2, 2] / s2
    lever = np.array([w[1], -w[0]])
    a = rng.normal(0.0, np.sqrt(s2), 1_000_000)
    v = rng.multivariate_normal(np.zeros(2), P[:2, :2] - s2 * np.outer(w, w), len(a))
    c, s = np.cos(a), np.sin(a)
    turn = np.stack([(c - 1) * lever[0] - s * lever[1], s * lever[0] + (c - 1) * lever[1]], -1)
    moved = np.stack([s / a * v[:, 0] - (1 - c) / a * v[:, 1], (1 - c) / a * v[:, 0] + s / a * v[:, 1]], -1)
    d = np.c_[turn + moved, a]
    sampled = d.T @ d / len(d)
    assert curved_covariance(P) == pytest.approx(sampled, abs=4e-3 * np.abs(sampled).max())
    assert not np.allclose(curved_covariance(P), P, atol=1e-2)  # at 0.3 rad the arc is far from its tangent


def test_it_adds_variance_along_the_lever_where_the_position_is_thin() -> None:
    """A 5 m lever, 0.06 rad: about 0.75 |l|^2 s^4 more along the lever (radial: 0.012 m of sd on a position 0.02 m
    thin there); across it (along the turn) E[sin^2 a] < s^2: a relative s^2 less."""
    P = _belief((5.0, 0.0), 0.06, rest=0.02)
    M = curved_covariance(P)
    radial = M[0, 0] - P[0, 0]
    assert radial == pytest.approx(0.75 * 25.0 * 0.06**4, rel=0.05)
    assert M[1, 1] == pytest.approx(P[1, 1] - 25.0 * 0.06**4, rel=0.05) and M[2, 2] == P[2, 2]
    assert np.sqrt(M[0, 0]) > 1.15 * np.sqrt(P[0, 0])


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-20.0, 20.0), st.floats(-20.0, 20.0), st.floats(1e-4, 0.5), st.floats(-np.pi, np.pi),
    st.floats(1e-3, 0.5),
)  # fmt: skip
def test_it_turns_with_the_frame_and_tends_to_the_linear_one(lx: float, ly: float, sigma: float, turn: float,
                                                             rest: float) -> None:  # fmt: skip
    """Frame-independent (a rotated belief gives the rotated moment; the pivot comes from P, not the origin);
    symmetric positive definite; equal to P as the heading's sd goes to 0."""
    P = _belief((lx, ly), sigma, rest)
    R = np.eye(3)
    R[:2, :2] = [[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]]
    M = curved_covariance(P)
    assert curved_covariance(R @ P @ R.T) == pytest.approx(R @ M @ R.T, abs=1e-9 * max(1.0, np.abs(M).max()))
    assert np.allclose(M, M.T) and np.linalg.eigvalsh(M).min() > 0.0
    tiny = _belief((lx, ly), 1e-5, rest)
    assert curved_covariance(tiny) == pytest.approx(tiny, rel=1e-6, abs=1e-14)


def test_a_known_heading_or_a_stack_is_handled() -> None:
    fixed = np.diag([0.1, 0.2, 0.0])
    assert np.array_equal(curved_covariance(fixed), fixed)
    stack = np.stack([_belief((3.0, 1.0), 0.1), fixed, np.full((3, 3), np.nan)])
    out = curved_covariance(stack)
    assert out[0] == pytest.approx(curved_covariance(stack[0])) and np.array_equal(out[1], fixed)
    assert np.isnan(out[2]).all()


def test_estimators_report_it_and_estimate_the_same_either_way() -> None:
    """``pose_covariance``: the EKF's and the smoother's snapshots carry the curved moment of what they hold
    (``linear``: what they hold); their estimates do not change, bit for bit."""
    from dataclasses import replace

    from online_slam.frontend.steps import FrontEnd
    from online_slam.pipeline import ReplayConfig
    from online_slam.pipeline.config import make_estimator
    from online_slam.sources.worlds import CircleConfig, circle_world

    steps = list(FrontEnd().steps(circle_world(CircleConfig(poses=80))))
    base = ReplayConfig(estimators=("ekf", "smoother"))
    linear = replace(base, ekf=replace(base.ekf, pose_covariance="linear"),
                     smoother=replace(base.smoother, pose_covariance="linear"))  # fmt: skip
    for name in ("ekf", "smoother"):
        a, b = make_estimator(name, base), make_estimator(name, linear)
        for step in steps:
            sa, sb = a.step(step), b.step(step)
            assert np.array_equal(sa.pose, sb.pose)
            assert sa.pose_cov == pytest.approx(curved_covariance(sb.pose_cov), rel=1e-12, abs=1e-300)
        assert not np.allclose(sa.pose_cov, sb.pose_cov, rtol=1e-3, atol=0.0)
    with pytest.raises(ValueError, match="pose_covariance"):
        replace(base.ekf, pose_covariance="banana")


def _by_quadrature(P: np.ndarray, nodes: int = 40) -> np.ndarray:
    """The same moment by Gauss-Hermite quadrature over the heading error (exact in v)."""
    s2 = P[2, 2]
    w = P[:2, 2] / s2
    lever = np.array([w[1], -w[0]])
    S = P[:2, :2] - s2 * np.outer(w, w)
    x, weights = np.polynomial.hermite.hermgauss(nodes)
    M = np.zeros((3, 3))
    for a, q in zip(np.sqrt(2.0 * s2) * x, weights / np.sqrt(np.pi)):
        c, s = np.cos(a), np.sin(a)
        V = np.array([[s / a, -(1 - c) / a], [(1 - c) / a, s / a]])
        turn = np.array([[c - 1, -s], [s, c - 1]]) @ lever
        M[:2, :2] += q * (np.outer(turn, turn) + V @ S @ V.T)
        M[:2, 2] += q * a * turn
        M[2, 2] += q * a * a
    M[2, :2] = M[:2, 2]
    return M


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(1e-3, 1.5))
def test_the_closed_form_is_the_quadrature(seed: int, sigma: float) -> None:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    P = A @ A.T + 1e-3 * np.eye(3)
    P = P * (sigma**2 / P[2, 2]) ** np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.5], [0.5, 0.5, 1.0]])
    assert curved_covariance(P) == pytest.approx(_by_quadrature(P), rel=1e-9, abs=1e-10 * np.abs(P).max())
