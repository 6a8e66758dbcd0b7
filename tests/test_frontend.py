"""Front-end: events -> steps, truth kept apart, the ablation, keyframing, streaming."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from online_slam.frontend import FrontEnd, FrontEndConfig, KeyframeConfig
from online_slam.geometry import compose
from online_slam.models import compose_increments
from online_slam.sources import Event, LandmarkTruth, Observation, Odometry, Start, Truth, square_world

SIG3 = (0.1, 0.1, 0.05)
SIG2 = (0.1, 0.01)


def odo(t: float, d: tuple = (1.0, 0.0, 0.0)) -> Odometry:
    return Odometry(t=t, delta=d, sigma=SIG3)


def obs(t: float, lid: int | str, r: float = 2.0) -> Observation:
    return Observation(t=t, landmark=lid, range=r, bearing=0.1, sigma=SIG2)


def test_square_world_steps() -> None:
    fe = FrontEnd()
    steps = list(fe.steps(square_world()))
    assert len(steps) == 25
    assert [s.index for s in steps] == list(range(25))
    assert sum(len(s.landmarks) for s in steps) == 95
    assert steps[0].odometry is None and np.array_equal(steps[0].prior, np.zeros(3)) and steps[0].prior_cov is None
    assert all(s.odometry is not None and s.odometry_cov.shape == (3, 3) for s in steps[1:])
    assert len(fe.truth.poses) == 25 and len(fe.truth.landmarks) == 12
    assert fe.header is not None and fe.header.name == "square"


def test_a_sighting_between_ticks_gets_a_pose_at_its_own_time() -> None:
    turn = (1.0, 0.2, 0.4)
    events = [obs(0.0, "a"), odo(1.0), obs(1.5, "b"), obs(1.9, "c"), obs(1.9, "e"), odo(2.0, turn), obs(2.0, "d")]
    steps = list(FrontEnd().steps(events))
    assert [s.landmarks for s in steps] == [("a",), (), ("b",), ("c", "e"), ("d",)]
    assert [s.t for s in steps] == [0.0, 1.0, 1.5, 1.9, 2.0]
    assert [s.index for s in steps] == list(range(5))
    assert steps[3].z.shape == (2, 2) and steps[3].z_cov.shape == (2, 2, 2)
    # the increment 1.0 -> 2.0 is split at 1.5 and 1.9: the parts compose to it exactly, covariance included
    delta, cov = steps[2].odometry, steps[2].odometry_cov
    for step in steps[3:]:
        delta, cov = compose_increments(delta, cov, step.odometry, step.odometry_cov)
    np.testing.assert_allclose(delta, turn, atol=1e-12)
    np.testing.assert_allclose(cov, np.diag(np.square(SIG3)), atol=1e-14)
    # constant twist: the first part is half the motion's twist, and carries half the covariance's trace
    assert steps[2].odometry[2] == pytest.approx(0.2) and np.trace(steps[2].odometry_cov) == pytest.approx(
        0.5 * np.sum(np.square(SIG3)), rel=0.05
    )


def test_lines_of_one_time_attach_to_its_pose_in_any_order() -> None:
    start = Start(t=0.0, pose=(0.0, 0.0, 0.0))
    odometry_first = [start, odo(1.0), obs(1.0, "a"), Truth(1.0, (1, 0, 0)), odo(2.0), obs(2.0, "b")]
    sightings_first = [start, obs(1.0, "a"), Truth(1.0, (1, 0, 0)), odo(1.0), obs(2.0, "b"), odo(2.0)]
    fronts = FrontEnd(), FrontEnd()
    one, other = (list(fe.steps(events)) for fe, events in zip(fronts, (odometry_first, sightings_first)))
    assert [(s.t, s.landmarks) for s in one] == [(s.t, s.landmarks) for s in other]
    assert [(s.t, s.landmarks) for s in one] == [(0.0, ()), (1.0, ("a",)), (2.0, ("b",))]
    for a, b in zip(one, other):
        np.testing.assert_array_equal(a.z, b.z)
    assert fronts[0].truth.poses.keys() == fronts[1].truth.poses.keys() == {1}


def test_sightings_after_the_last_odometry_attach_to_the_last_pose_and_are_counted() -> None:
    fe = FrontEnd()
    steps = list(fe.steps([odo(1.0), obs(1.5, "a"), obs(1.7, "b")]))
    assert [(s.t, s.landmarks) for s in steps] == [(1.0, ()), (1.0, ("a", "b"))]
    assert fe.counts["after_last_odometry"] == 2


def test_a_reorder_buffer_puts_late_lines_at_their_time() -> None:
    ordered = [odo(0.1 * k) for k in range(1, 11)] + [obs(0.1 * k + 0.04, f"l{k}") for k in range(1, 10)]
    ordered.sort(key=lambda e: e.t)
    late = sorted(ordered, key=lambda e: e.t + (0.15 if isinstance(e, Observation) else 0.0))  # arrival order
    assert late != ordered
    want = [(s.t, s.landmarks) for s in FrontEnd().steps(ordered)]
    got = [(s.t, s.landmarks) for s in FrontEnd(FrontEndConfig(max_latency=0.2)).steps(late)]
    assert got == want


def test_start_prior_and_default_origin() -> None:
    start = Start(t=0.0, pose=(1.0, 2.0, 0.5), sigma=(0.1, 0.2, 0.3))
    step0 = next(FrontEnd().steps([start, odo(1.0)]))
    assert np.allclose(step0.prior, [1, 2, 0.5]) and np.allclose(np.diag(step0.prior_cov), [0.01, 0.04, 0.09])
    step0 = next(FrontEnd().steps([odo(3.0)]))
    assert step0.t == 3.0 and np.array_equal(step0.prior, np.zeros(3)) and step0.prior_cov is None


def test_truth_is_kept_apart_and_only_at_pose_times() -> None:
    events = [Truth(0.0, (0, 0, 0)), odo(1.0), Truth(1.5, (9, 9, 9)), odo(2.0), Truth(2.0, (2, 0, 0))]
    events.append(LandmarkTruth("x", (4.0, 5.0)))
    fe = FrontEnd()
    steps = list(fe.steps(events))
    assert len(steps) == 3
    assert sorted(fe.truth.poses) == [0, 2]
    assert np.allclose(fe.truth.landmarks["x"], [4, 5])
    assert not any(hasattr(s, "truth") for s in steps)


def test_first_observation_only() -> None:
    events = [obs(0.0, 1), obs(0.0, 2), odo(1.0), obs(1.0, 1), obs(1.0, 3), odo(2.0), obs(2.0, 2)]
    fe = FrontEnd(FrontEndConfig(first_observation_only=True))
    steps = list(fe.steps(events))
    assert [s.landmarks for s in steps] == [(1, 2), (3,), ()]
    assert fe.counts["dropped_repeat_observation"] == 2


def test_keyframing_merges_observation_free_steps() -> None:
    d = (0.1, 0.0, 0.05)
    events: list[Event] = [obs(0.0, 1)]
    events += [odo(0.1 * k, d) for k in range(1, 5)]
    events += [obs(0.4, 2), odo(0.5, d), obs(0.5, 3)]
    fe = FrontEnd(FrontEndConfig(keyframing=KeyframeConfig(max_distance=10, max_angle=10)))
    steps = list(fe.steps(events))
    assert [s.merged for s in steps] == [1, 4, 1]
    assert [s.landmarks for s in steps] == [(1,), (2,), (3,)]
    expected = np.zeros(3)
    cov = None
    for _ in range(4):
        if cov is None:
            expected, cov = np.array(d), np.diag(np.square(SIG3))
        else:
            expected, cov = compose_increments(expected, cov, d, np.diag(np.square(SIG3)))
    assert np.allclose(steps[1].odometry, expected) and np.allclose(steps[1].odometry_cov, cov)
    assert np.allclose(steps[1].odometry, compose(compose(compose(d, d), d), d))
    assert steps[1].t == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("limits", "merged"),
    [
        (KeyframeConfig(max_distance=0.25, max_angle=10), [1, 2, 2]),
        (KeyframeConfig(max_distance=10, max_angle=0.11), [1, 2, 2]),
        (KeyframeConfig(max_distance=10, max_angle=10, max_time=0.25), [1, 2, 2]),
        (KeyframeConfig(max_distance=10, max_angle=10), [1, 4]),
    ],
)
def test_keyframing_limits(limits: KeyframeConfig, merged: list[int]) -> None:
    events: list[Event] = [obs(0.0, 1)] + [odo(0.1 * k, (0.1, 0.0, 0.05)) for k in range(1, 5)]
    steps = list(FrontEnd(FrontEndConfig(keyframing=limits)).steps(events))
    assert [s.merged for s in steps] == merged


def test_keyframing_drops_truth_of_merged_away_times() -> None:
    events = [odo(1.0), Truth(1.0, (1, 0, 0)), odo(2.0), obs(2.0, 5)]
    fe = FrontEnd(FrontEndConfig(keyframing=KeyframeConfig(max_distance=10)))
    steps = list(fe.steps(events))
    assert len(steps) == 2 and steps[1].merged == 2
    assert 1 not in fe.truth.poses


def test_steps_stream_before_the_source_ends() -> None:
    def source() -> Iterator[Event]:
        yield obs(0.0, 1)
        yield odo(1.0)
        yield odo(2.0)
        raise RuntimeError("source exhausted early")

    steps = FrontEnd().steps(source())
    assert next(steps).index == 0
    assert next(steps).index == 1
    with pytest.raises(RuntimeError):
        next(steps)


def test_each_sightings_widening_reaches_its_step_and_its_own_covariance_is_the_declared_one_narrowed() -> None:
    """``widened`` (a line's variance factors): a step carries each sighting's, ones where a line gives none, and
    ``z_own_cov`` divides the covariance declared (times a noise scale, which the factors do not change) by
    ``sqrt(f f^T)``: a full covariance keeps its correlation."""
    cov = ((0.04, 0.003), (0.003, 0.0009))
    events = [
        obs(0.0, "a"),
        Observation(t=0.0, landmark="b", range=3.0, bearing=0.2, sigma=SIG2, widened=(4.0, 9.0)),
        Observation(t=0.0, landmark="c", range=3.0, bearing=0.2, cov=cov, widened=(25.0, 1.0)),
        odo(1.0),
        obs(1.0, "a"),
    ]
    steps = list(FrontEnd(FrontEndConfig(sensor_noise_scale=2.0)).steps(events))
    np.testing.assert_array_equal(steps[0].z_widening, [[1.0, 1.0], [4.0, 9.0], [25.0, 1.0]])
    own = steps[0].z_own_cov()
    np.testing.assert_allclose(own[0], steps[0].z_cov[0], rtol=1e-15)
    np.testing.assert_allclose(own[1], 2.0 * np.diag([0.1**2 / 4.0, 0.01**2 / 9.0]), rtol=1e-12)
    np.testing.assert_allclose(own[2], 2.0 * np.array([[0.04 / 25.0, 0.003 / 5.0], [0.003 / 5.0, 0.0009]]), rtol=1e-12)
    assert steps[1].z_widening.shape == (1, 2) and steps[1].z_own_cov() is steps[1].z_cov  # nothing widened
