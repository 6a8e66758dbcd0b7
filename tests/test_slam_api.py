"""The library API: ``online_slam.Slam`` driven event by event, as a robot's loop would."""

from __future__ import annotations

import copy
import functools
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import online_slam
from online_slam import ConfigError, InputError, OnlineSlamError, ReplayConfig, Slam
from online_slam.sources.events import Observation, Odometry, Start
from online_slam.sources.worlds import GridConfig, grid_world, square_world

SMALL_GRID = GridConfig(poses=300, landmarks=60, seed=3)


def drive(slam: Slam, events, stop_at: int | None = None) -> list[np.ndarray]:
    """Add events one by one; read the newest pose each time a pose is complete (its successor arrives).

    Returns the online poses (one per complete pose); with ``stop_at`` returns once that many poses exist.
    """
    online = []
    for event in events:
        if isinstance(event, Odometry) and slam.poses:
            if stop_at is not None and slam.poses == stop_at:
                return online
            online.append(slam.estimate(landmark_covs=False).pose.copy())
        slam.add(event)
    online.append(slam.estimate(landmark_covs=False).pose.copy())
    return online


def online_rmse(poses: list[np.ndarray], truth: dict[int, np.ndarray]) -> float:
    errors = [np.hypot(*(poses[i][:2] - truth[i][:2])) for i in truth if i < len(poses)]
    return float(np.sqrt(np.mean(np.square(errors))))


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_event_by_event_equals_replay(estimator: str) -> None:
    events = list(grid_world(SMALL_GRID))
    slam = Slam(estimator)
    online = drive(slam, events)
    results = online_slam.replay(iter(events), ReplayConfig(estimators=(estimator,)))
    replayed = results.series[estimator].poses
    assert len(online) == len(replayed) == SMALL_GRID.poses
    assert np.abs(np.array(online) - replayed).max() <= 1e-9
    truth = {i: p for i, p in enumerate(results.truth_poses)}  # the grid's first pose is the origin: anchor = id
    assert online_rmse(online, truth) == pytest.approx(results.estimators[estimator].online_rmse_m, abs=1e-9)
    final = slam.estimate(landmark_covs=False)
    assert final.trajectory.shape == (SMALL_GRID.poses, 3)
    np.testing.assert_array_equal(final.trajectory[-1], final.pose)


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_no_latency_sightings_count_before_the_next_odometry(estimator: str) -> None:
    slam = Slam(estimator)
    slam.start(0.0, [0.0, 0.0, 0.0])
    slam.add_observation(0.0, "tree", 5.0, 0.0, sigma=[0.1, 0.01])
    slam.add_odometry(1.0, [1.0, 0.0, 0.0], sigma=[0.3, 0.3, 0.05])
    before = slam.estimate()
    assert before.index == 1 and before.pose_cov[0, 0] > 0.08  # odometry only so far
    # A sighting of the newest pose: the estimate uses it at once, before any further odometry.
    slam.add_observation(1.0, "tree", 3.5, 0.0, sigma=[0.1, 0.01])
    after = slam.estimate()
    assert after.index == 1
    assert after.pose[0] == pytest.approx(1.45, abs=0.05)  # pulled from 1.0 towards 5.0 - 3.5 = 1.5
    assert after.pose_cov[0, 0] < 0.5 * before.pose_cov[0, 0]
    assert after.trajectory.shape == (2, 3) and set(after.landmarks) == {"tree"}
    assert after.landmark_covs is not None and after.landmark_covs["tree"].shape == (2, 2)
    # A second sighting of the same pose after the query is used too.
    slam.add_observation(1.0, "tree", 3.5, 0.0, sigma=[0.1, 0.01])
    assert slam.estimate().pose_cov[0, 0] < after.pose_cov[0, 0]


def test_estimate_is_read_only() -> None:
    slam = Slam("ekf")
    slam.add_observation(0.0, 1, 2.0, 0.3, sigma=[0.1, 0.01])
    estimate = slam.estimate()
    with pytest.raises(ValueError):
        estimate.pose[0] = 1.0
    with pytest.raises(TypeError):
        estimate.landmarks[2] = np.zeros(2)  # type: ignore[index]
    with pytest.raises(AttributeError):
        estimate.pose = np.zeros(3)  # type: ignore[misc]


def test_options_are_validated() -> None:
    with pytest.raises(ConfigError, match=r"unknown option 'windw' \(did you mean window\?\)"):
        Slam("smoother", windw=10)
    with pytest.raises(ConfigError, match="window must be >= 1"):
        Slam("smoother", window=0)
    with pytest.raises(ConfigError, match="for the ekf"):
        Slam("smoother", gate_probability=0.99)
    with pytest.raises(ConfigError, match="expected float"):
        Slam("ekf", gate_probability="high")
    with pytest.raises(ConfigError, match="estimator must be"):
        Slam("particle")
    assert Slam("smoother", window=50, relinearize_every=2, robust="cauchy", robust_scale=3.0).options["window"] == 50


def test_estimator_names_ignore_case_and_batch_points_to_replay() -> None:
    assert Slam("EKF").estimator_name == "ekf" and Slam(" Smoother ").estimator_name == "smoother"
    with pytest.raises(ConfigError, match=r"batch solver is not an online estimator.*online_slam\.replay"):
        Slam("Batch")


def test_input_and_config_errors_are_value_errors_of_ours() -> None:
    for error in (InputError, ConfigError):
        assert issubclass(error, ValueError) and issubclass(error, OnlineSlamError)
    with pytest.raises(ValueError, match="range > 0"):
        Slam().add_observation(0.0, 1, -1.0, 0.0, sigma=[0.1, 0.01])


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_estimate_before_any_event_is_empty(estimator: str) -> None:
    empty = Slam(estimator).estimate()
    assert empty.index == -1 and math.isnan(empty.t)
    assert empty.trajectory.shape == (0, 3) and empty.landmark_array.shape == (0, 2)
    assert np.isnan(empty.pose).all() and empty.pose.shape == (3,) and np.isnan(empty.pose_cov).all()
    assert dict(empty.landmarks) == {} and dict(empty.landmark_covs) == {} and empty.landmark_ids == ()
    assert Slam(estimator).estimate(landmark_covs=False).landmark_covs is None


def test_add_takes_stream_records_as_well_as_events() -> None:
    events = list(square_world())
    by_object, by_record = Slam("ekf"), Slam("ekf")
    for event in events:
        by_object.add(event)
        by_record.add({key: np.asarray(v) if isinstance(v, list) else v for key, v in event.to_record().items()})
    np.testing.assert_array_equal(by_object.estimate().trajectory, by_record.estimate().trajectory)
    assert by_record.poses == 25
    by_record.add({"type": "odometry", "t": 25.0, "delta": [1.0, 0.0, 0.0], "sigma": [0.05, 0.05, 0.01]})
    assert by_record.poses == 26


@pytest.mark.parametrize(
    ("item", "field", "message"),
    [
        ({"type": "odometry", "t": 100.0, "delta": [1.0, 0.0], "sigma": [0.1, 0.1, 0.1]}, "delta", "list of 3"),
        ({"type": "odometry", "t": 100.0, "delta": [1.0, 0.0, 0.0]}, "sigma", "missing noise"),
        ({"type": "odometry", "t": 100.0, "delta": [1.0, 0.0, 0.0], "sigmas": [0.1] * 3}, "sigmas", "unknown field"),
        ({"t": 100.0, "delta": [1.0, 0.0, 0.0], "sigma": [0.1, 0.1, 0.1]}, "type", "unknown event type"),
        ({"type": "observation", "t": 100.0, "range": 2.0, "bearing": 45.0, "sigma": [0.1, 0.01]}, "bearing", "deg"),
        ("odometry", "", "expected an event or a stream-v1 record, got str"),
    ],
)
def test_add_refuses_a_bad_record_naming_its_field(item, field: str, message: str) -> None:
    slam = _warm_slam("ekf")
    before = _fingerprint(slam)
    with pytest.raises(InputError, match=message) as caught:
        slam.add(item)
    assert caught.value.field == field and caught.value.source.startswith("Slam.add")
    assert _fingerprint(slam) == before


def test_angles_in_degrees_are_refused() -> None:
    slam = Slam("ekf")
    slam.add_observation(0.0, 1, 2.0, -2 * math.pi, sigma=[0.1, 0.01])  # the limits themselves are radians
    with pytest.raises(InputError, match=r"\[-2 pi, 2 pi\].*degrees") as caught:
        slam.add_observation(0.0, 1, 2.0, 45.0, sigma=[0.1, 0.01])
    assert caught.value.field == "bearing" and caught.value.reason == "out_of_range"
    with pytest.raises(InputError, match="degrees") as caught:
        slam.add_observations(0.0, [1, 2], [2.0, 3.0], [0.5, -90.0], sigma=[0.1, 0.01])
    assert caught.value.field == "bearing[1]"
    assert slam.estimate().landmark_ids == (1,)  # the scan changed nothing
    with pytest.raises(InputError, match="degrees") as caught:
        slam.add_odometry(1.0, delta=[1.0, 0.0, 90.0], sigma=[0.05, 0.05, 0.01])
    assert caught.value.field == "delta[2]" and slam.poses == 1
    with pytest.raises(InputError, match="degrees") as caught:
        Slam("ekf").start(0.0, [0.0, 0.0, 90.0])
    assert caught.value.field == "pose[2]"


def test_smoother_landmark_covariances_equal_batch_marginals_with_a_covering_window() -> None:
    from online_slam.engine import Engine
    from online_slam.estimators.batch import BatchEstimator
    from online_slam.factors.graph import layout
    from online_slam.solvers.least_squares import SolverConfig, solve

    slam = Slam("smoother", window=100)
    drive(slam, square_world())
    estimate = slam.estimate()
    batch = BatchEstimator()
    engine = Engine([batch])
    for event in square_world():
        engine.push(event)
    engine.close()
    graph = batch.log.graph()
    ids = batch.log.landmark_ids
    landmarks = np.array([estimate.landmarks[i] for i in ids])
    linear = solve(graph, estimate.trajectory, landmarks, SolverConfig(max_iterations=0), return_information=True)
    H = linear.information.toarray() if hasattr(linear.information, "toarray") else linear.information
    C = np.linalg.inv(H)
    columns = layout(graph, entries=False).landmark_column
    for k, lid in enumerate(ids):
        c = columns[k] + np.arange(2)
        np.testing.assert_allclose(estimate.landmark_covs[lid], C[np.ix_(c, c)], rtol=1e-8, atol=1e-14)


def test_smoother_landmark_covariances_after_marginalization_stay_close() -> None:
    covering, short = Slam("smoother", window=100), Slam("smoother", window=3)
    drive(covering, square_world())
    drive(short, square_world())
    a, b = covering.estimate().landmark_covs, short.estimate().landmark_covs
    for lid in a:
        assert np.all(np.linalg.eigvalsh(b[lid]) > 0)
        # frozen linearization of the marginalized poses: measured within 6% of the covering window's
        assert np.linalg.norm(b[lid] - a[lid], 2) <= 0.1 * np.linalg.norm(a[lid], 2)


# -- checkpoints ---------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_save_load_continue_equals_uninterrupted(tmp_path: Path, estimator: str) -> None:
    events = list(grid_world(GridConfig(poses=300, landmarks=80, seed=5)))
    whole = Slam(estimator)
    drive(whole, events)
    first = Slam(estimator)
    drive(first, events, stop_at=220)  # the smoother's global solve started at step 200 is pending until 250
    # stop mid-step too: sightings of pose 219 queried, more may follow
    consumed = sum(1 for _ in _until_poses(events, 220))
    first.save(tmp_path / "at220.ckpt")
    resumed = Slam.load(tmp_path / "at220.ckpt")
    assert resumed.poses == first.poses == 220
    drive(resumed, events[consumed:])
    a, b = whole.estimate(), resumed.estimate()
    np.testing.assert_array_equal(a.trajectory, b.trajectory)
    np.testing.assert_array_equal(a.pose_cov, b.pose_cov)
    assert a.landmarks.keys() == b.landmarks.keys()
    for lid in a.landmarks:
        np.testing.assert_array_equal(a.landmarks[lid], b.landmarks[lid])
        np.testing.assert_allclose(a.landmark_covs[lid], b.landmark_covs[lid], rtol=0, atol=1e-12)


def _until_poses(events, poses: int):
    """The events a ``drive(..., stop_at=poses)`` consumed."""
    count = 0
    for event in events:
        if isinstance(event, Odometry) or (count == 0 and isinstance(event, (Start, Observation))):
            if isinstance(event, Odometry) and count == poses:
                return
            count += isinstance(event, Odometry) or count == 0
        yield event


def test_checkpoint_mid_step_keeps_pending_sightings(tmp_path: Path) -> None:
    events = list(square_world())
    whole = Slam("smoother")
    for event in events:
        whole.add(event)
    cut = 40  # inside a step
    part = Slam("smoother")
    for event in events[:cut]:
        part.add(event)
    part.estimate()
    part.save(tmp_path / "mid.ckpt")
    again = Slam.load(tmp_path / "mid.ckpt")
    for event in events[cut:]:
        again.add(event)
    for event in events[cut:]:
        part.add(event)
    np.testing.assert_array_equal(again.estimate().trajectory, part.estimate().trajectory)


@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
def test_estimate_right_after_loading_a_checkpoint_taken_after_a_query(tmp_path: Path, estimator: str) -> None:
    """The loaded engine has nothing new to deliver: the estimate comes from the restored estimator."""
    slam = Slam(estimator)
    slam.add_odometry(0.1, [1.0, 0.0, 0.0], sigma=[0.1, 0.1, 0.01])
    slam.add_observations(0.1, [1, 2], [1.0, 2.0], [0.1, -0.2], sigma=[0.1, 0.01])
    before = slam.estimate()
    slam.save(tmp_path / "queried.ckpt")
    after = Slam.load(tmp_path / "queried.ckpt").estimate()
    np.testing.assert_array_equal(after.pose, before.pose)
    np.testing.assert_allclose(after.pose_cov, before.pose_cov, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(after.trajectory, before.trajectory)
    assert after.landmark_ids == before.landmark_ids


def saved_square(tmp_path: Path) -> tuple[Slam, Path]:
    """An EKF engine fed the whole square world, and its checkpoint ``run.ckpt`` in ``tmp_path``."""
    slam = Slam("ekf")
    for event in square_world():
        slam.add(event)
    path = tmp_path / "run.ckpt"
    slam.save(path)
    return slam, path


def test_damaged_checkpoints_raise_input_error(tmp_path: Path) -> None:
    _, path = saved_square(tmp_path)
    data = path.read_bytes()
    (tmp_path / "cut.ckpt").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="not a usable checkpoint"):
        Slam.load(tmp_path / "cut.ckpt")
    # alter one number inside the state but keep the zip valid: the checksum catches it
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    members["state.json"] = members["state.json"].replace(b'"ekf"', b'"smoother"', 1)
    with zipfile.ZipFile(tmp_path / "altered.ckpt", "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    with pytest.raises(InputError, match="altered"):
        Slam.load(tmp_path / "altered.ckpt")
    (tmp_path / "text.ckpt").write_text("hello")
    with pytest.raises(InputError):
        Slam.load(tmp_path / "text.ckpt")
    with pytest.raises(InputError, match="no such"):
        Slam.load(tmp_path / "missing.ckpt")


# -- bad input changes nothing (property-based) -----------------------------------------------------------

GOOD_ODOMETRY = {"t": 100.0, "delta": [0.5, 0.0, 0.05], "sigma": [0.05, 0.05, 0.01]}
GOOD_OBSERVATION = {"t": 100.0, "landmark": 3, "range": 2.0, "bearing": 0.2, "sigma": [0.1, 0.01]}
GOOD_START = {"t": 0.0, "pose": [0.0, 0.0, 0.0]}

junk = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.lists(st.lists(st.floats(), max_size=4), max_size=4),
    st.builds(np.array, st.lists(st.floats(allow_nan=True), max_size=4)),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


def _warm_slam(estimator: str) -> Slam:
    """A fresh copy of an engine fed the square's first 61 events (built once per estimator: hypothesis asks
    hundreds of times)."""
    return copy.deepcopy(_warmed(estimator))


@functools.cache
def _warmed(estimator: str) -> Slam:
    slam = Slam(estimator)
    for k, event in enumerate(square_world()):
        if k > 60:
            break
        slam.add(event)
    return slam


def _fingerprint(slam: Slam) -> tuple:
    e = slam.estimate()
    return (
        e.index,
        e.t,
        e.pose.tobytes(),
        e.pose_cov.tobytes(),
        e.trajectory.tobytes(),
        tuple((k, v.tobytes()) for k, v in e.landmarks.items()),
        tuple((k, v.tobytes()) for k, v in e.landmark_covs.items()),
    )


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["ekf", "smoother"])
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_bad_input_raises_input_error_and_changes_nothing(estimator: str, data: st.DataObject) -> None:
    slam = _warm_slam(estimator)
    before = _fingerprint(slam)
    method, good = data.draw(
        st.sampled_from([("add_odometry", GOOD_ODOMETRY), ("add_observation", GOOD_OBSERVATION), ("start", GOOD_START)])
    )
    kwargs = dict(good)
    field = data.draw(st.sampled_from(sorted(kwargs) + ["cov"]))
    kwargs[field] = data.draw(junk)
    try:
        getattr(slam, method)(**kwargs)
    except InputError:
        assert _fingerprint(slam) == before
        return
    # accepted: it must have been a valid value (the estimate moves on without error)
    assert method != "start"  # a start after timed events is never valid
    slam.estimate()


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda s: s.add_odometry(100.0, [0.5, 0.0], sigma=[0.1, 0.1, 0.1]), "delta"),
        (lambda s: s.add_odometry(100.0, [0.5, 0.0, 0.0]), "sigma"),
        (lambda s: s.add_odometry(100.0, [0.5, 0.0, 0.0], sigma=[0.1, 0.1, 0.1], cov=np.eye(3)), "cov"),
        (lambda s: s.add_odometry(100.0, [0.5, 0.0, 0.0], cov=np.zeros((3, 3))), "cov"),
        (lambda s: s.add_odometry(100.0, [0.5, math.nan, 0.0], sigma=[0.1, 0.1, 0.1]), "delta[1]"),
        (lambda s: s.add_odometry(1.0, [0.5, 0.0, 0.0], sigma=[0.1, 0.1, 0.1]), "t"),
        (lambda s: s.add_observation(100.0, 3, -0.01, 0.1, sigma=[0.1, 0.01]), "range"),
        (lambda s: s.add_observation(100.0, 3.5, 1.0, 0.1, sigma=[0.1, 0.01]), "landmark"),
        (lambda s: s.add_observation(100.0, 3, 1.0, 0.1, sigma=[0.1, -0.01]), "sigma[1]"),
        (lambda s: s.add_observation(100.0, 3, 1.0, 0.1, cov=[[1.0, 2.0], [2.0, 1.0]]), "cov"),
        (lambda s: s.start(0.0, [0.0, 0.0, 0.0]), "type"),
    ],
)
def test_each_kind_of_bad_input_names_its_field(call, field: str) -> None:
    slam = _warm_slam("ekf")
    before = _fingerprint(slam)
    with pytest.raises(InputError) as caught:
        call(slam)
    assert caught.value.field == field and caught.value.source.startswith("Slam.")
    assert _fingerprint(slam) == before


# -- scans ---------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_scans_equal_single_sightings() -> None:
    events = list(grid_world(GridConfig(poses=200, landmarks=40, seed=9)))
    one, scans = Slam("smoother"), Slam("smoother")
    pending: list[Observation] = []

    def flush() -> None:
        if pending:
            o = pending[0]
            scans.add_observations(
                o.t, [p.landmark for p in pending], np.array([p.range for p in pending]),
                np.array([p.bearing for p in pending]), sigma=np.array(o.sigma),
            )  # fmt: skip
            pending.clear()

    for event in events:
        if isinstance(event, Observation):
            one.add(event)
            if pending and (event.t != pending[0].t or event.sigma != pending[0].sigma):
                flush()
            pending.append(event)
        elif isinstance(event, (Odometry, Start)):
            one.add(event)
            flush()
            if isinstance(event, Odometry):
                scans.add_odometry(event.t, event.delta, sigma=event.sigma)
            else:
                scans.start(event.t, event.pose, event.sigma, event.cov)
    flush()
    np.testing.assert_array_equal(one.estimate().trajectory, scans.estimate().trajectory)


def test_a_bad_sighting_rejects_the_whole_scan() -> None:
    slam = _warm_slam("smoother")
    before = _fingerprint(slam)
    with pytest.raises(InputError) as caught:
        slam.add_observations(100.0, [1, 2, 3, 4], [1.0, 2.0, 3.0, -4.0], [0.1, 0.2, 0.3, 0.4], sigma=[0.1, 0.01])
    assert caught.value.field == "range[3]" and "range > 0" in caught.value.message
    with pytest.raises(InputError) as caught:
        slam.add_observations(100.0, [1, True], [1.0, 2.0], [0.1, 0.2], sigma=[[0.1, 0.01], [0.1, 0.0]])
    assert caught.value.field == "landmark[1]"
    with pytest.raises(InputError) as caught:
        slam.add_observations(100.0, [1, 2], [1.0, 2.0], [0.1, 0.2], sigma=[[0.1, 0.01], [0.1, 0.0]])
    assert caught.value.field == "sigma[1][1]"
    with pytest.raises(InputError, match="ranges"):
        slam.add_observations(100.0, [1, 2], [1.0], [0.1, 0.2], sigma=[0.1, 0.01])
    assert _fingerprint(slam) == before
    slam.add_observations(100.0, [1, "new"], [1.0, 2.0], [0.1, 0.2], cov=np.diag([0.01, 1e-4]))
    assert "new" not in slam.estimate().landmarks  # after the newest pose: it waits for the odometry spanning t=100
    slam.add_odometry(101.0, [0.5, 0.0, 0.0], sigma=[0.05, 0.05, 0.01])
    assert "new" in slam.estimate().landmarks


def test_a_checkpoint_that_cannot_be_written_is_an_error_of_ours_and_keeps_the_previous_one(tmp_path: Path) -> None:
    slam, path = saved_square(tmp_path)
    kept = path.read_bytes()
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    for bad in (tmp_path, blocker / "run.ckpt"):  # a folder in the way; a file where a folder should be
        with pytest.raises(OnlineSlamError, match="cannot write checkpoint"):
            slam.save(bad)
    assert path.read_bytes() == kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "run.ckpt"]  # no temporary left behind
    with pytest.raises(InputError, match="cannot read the checkpoint"):
        Slam.load(tmp_path)
    with pytest.raises(InputError, match="no such checkpoint file"):
        Slam.load(blocker / "run.ckpt")
    np.testing.assert_array_equal(Slam.load(path).estimate().pose, slam.estimate().pose)  # the engine goes on


def test_typed_configs_reach_every_field_and_survive_a_checkpoint(tmp_path: Path) -> None:
    """``Slam(config=...)``: fields no flag reaches (the consensus move here) are settable; names and types checked."""
    from online_slam.estimators import SmootherConfig
    from online_slam.estimators.ekf_config import EkfConfig
    from online_slam.estimators.smoother import RobustConfig, WindowConfig
    from online_slam.frontend import FrontEndConfig

    config = SmootherConfig(window=WindowConfig(size=7, distance=0.0), robust=RobustConfig(consensus=False))
    slam = Slam(config=config, frontend=FrontEndConfig(odometry_noise_scale=2.0))
    assert slam.estimator_name == "smoother" and slam._estimator.config is config
    slam.add_odometry(1.0, delta=[1.0, 0.0, 0.0], sigma=[0.1, 0.1, 0.01])
    slam.save(tmp_path / "typed.ckpt")
    again = Slam.load(tmp_path / "typed.ckpt")
    assert again._estimator.config == config and again.typed == slam.typed
    assert Slam(config=EkfConfig()).estimator_name == "ekf"
    with pytest.raises(ConfigError, match="or configs, not both"):
        Slam(config=config, window=5)
    with pytest.raises(ConfigError, match="config is a EkfConfig, for the ekf"):
        Slam("smoother", config=EkfConfig())
    with pytest.raises(ConfigError, match="config must be an EkfConfig or a SmootherConfig"):
        Slam(config=FrontEndConfig())
