"""Absolute fixes (``position`` and ``heading`` lines): the model, the stream rules, the front-end, every estimator
on a sparse world, the GTSAM peer's refusal and the raw Victoria Park importer's GPS fixes."""

from __future__ import annotations

import io
import json
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import numerical_jacobian
from inprocess import run_cli

from online_slam.errors import InputError, OnlineSlamError
from online_slam.estimators import BatchEstimator, EkfSlam, SlidingWindowSmoother, SmootherConfig
from online_slam.estimators.smoother import WindowConfig
from online_slam.factors.fixes import fix_rows, with_fixes
from online_slam.factors.graph import FactorGraph, evaluate, layout, linearize
from online_slam.frontend import FrontEnd, FrontEndConfig
from online_slam.geometry import wrap
from online_slam.models.fix import correlated_widening, fix_factors, fix_residual_with_jacobians, fixed_point
from online_slam.sources import GridConfig, Truth, grid_world
from online_slam.sources.events import Event, Header, Heading, Odometry, Position, Start
from online_slam.sources.stream import parse_lines, read_stream, write_stream
from online_slam.sources.validate import validate_events

ROOT = Path(__file__).resolve().parents[1]
SPARSE = GridConfig(poses=200, seed=3, landmarks=12, sensor_range=5.0, odometry_sigma=(0.05, 0.05, 0.02))
"""A world whose few landmarks leave the path to drift by metres: fixes have something to correct."""


def fixed_world(
    every: int, sigma: float = 0.3, heading: float | None = None, offset: tuple[float, float] | None = None
) -> Iterator[Event]:
    """The sparse world with a position fix (and a heading fix) drawn from truth half a step after every
    ``every``-th pose (between odometry ticks: the front-end splits the increment)."""
    rng = np.random.default_rng(0)
    n = 0
    pending: list[Event] = []
    for event in grid_world(SPARSE):
        if isinstance(event, Odometry):
            yield from (e for e in pending if e.t < event.t)
            pending = [e for e in pending if e.t >= event.t]
        yield event
        if isinstance(event, Truth):
            n += 1
            if n % every:
                continue
            pose = np.array(event.pose)  # half a step later the robot is about there: its truth is of the pose
            o = np.zeros(2) if offset is None else np.array(offset)
            xy = fixed_point(pose, o) + rng.normal(0.0, sigma, 2)
            pending.append(Position(event.t, tuple(map(float, xy)), (sigma, sigma), offset=offset))
            if heading is not None:
                pending.append(Heading(event.t, float(wrap(pose[2] + rng.normal(0.0, heading))), heading))
    yield from pending


def run(events: Iterable[Event], config: FrontEndConfig | None = None) -> dict[str, float]:
    """RMSE of the final positions (no alignment: fixes give the frame) per estimator, and the EKF's mean pose
    NEES over its online poses."""
    fe = FrontEnd(config)
    estimators = [EkfSlam(), SlidingWindowSmoother(SmootherConfig(window=WindowConfig(size=10))), BatchEstimator()]
    nees = []
    for step in fe.steps(events):
        snaps = [e.step(step) for e in estimators]
        true = fe.truth.poses.get(step.index)
        if true is not None and step.index > 0:
            e = snaps[0].pose - true
            e[2] = wrap(e[2])
            nees.append(float(e @ np.linalg.solve(snaps[0].pose_cov, e)))
    out = {}
    for estimator in estimators:
        poses = estimator.finish().poses
        truth = np.array([fe.truth.poses[i] for i in range(len(poses))])
        out[estimator.name] = float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth[:, :2]) ** 2, axis=1))))
    out["ekf_nees"] = float(np.mean(nees))
    out["fixes"] = fe.counts.get("position", 0) + fe.counts.get("heading", 0)
    return out


def test_fix_jacobians_match_numerical(rng: np.random.Generator) -> None:
    for _ in range(30):
        pose, offset, mean = rng.normal(size=3) * [5, 5, 3], rng.normal(size=2), rng.normal(size=3) * [5, 5, 3]
        e, J = fix_residual_with_jacobians(pose, offset, mean)
        assert -np.pi <= e[2] < np.pi
        numeric = numerical_jacobian(lambda p: fix_residual_with_jacobians(p, offset, mean)[0], pose, (2,))
        assert np.allclose(J, numeric, atol=1e-6)


def test_fix_is_the_offset_point_and_vectorises() -> None:
    pose = np.array([[1.0, 2.0, np.pi / 2], [0.0, 0.0, 0.0]])
    assert np.allclose(fixed_point(pose, [1.0, 0.5]), [[0.5, 3.0], [1.0, 0.5]])
    e, J = fix_residual_with_jacobians(pose, np.zeros(2), np.zeros(3))
    assert e.shape == (2, 3) and J.shape == (2, 3, 3) and np.allclose(J, np.eye(3))


def test_fix_factors_measure_what_the_fix_gives() -> None:
    mean, offset, W = fix_factors([Position(0.0, (1.0, 2.0), (0.5, 0.25), offset=(0.3, 0.0)), Heading(0.0, 0.4, 0.1)])
    assert np.allclose(mean, [[1.0, 2.0, 0.0], [0.0, 0.0, 0.4]]) and np.allclose(offset, [[0.3, 0.0], [0.0, 0.0]])
    assert np.allclose(W[0], np.diag([2.0, 4.0, 0.0])) and np.allclose(W[1], np.diag([0.0, 0.0, 10.0]))


def test_fix_rows_in_a_graph_have_analytic_jacobians(rng: np.random.Generator) -> None:
    base = FactorGraph.build(3, 0, prior_pose=[0], prior_mean=[[0.0, 0.0, 0.0]], prior_cov=[np.eye(3)])
    mean, offset, W = fix_factors([Position(0.0, (1.0, 2.0), (0.5, 0.5), offset=(1.0, -0.5)), Heading(0.0, 3.0, 0.1)])
    graph = with_fixes(base, np.array([1, 2]), mean, offset, W)
    assert fix_rows(graph).tolist() == [False, True, True]
    poses = rng.normal(size=(3, 3))
    r, J = linearize(graph, layout(graph), poses, np.zeros((0, 2)))
    numeric = numerical_jacobian(lambda x: evaluate(graph, x.reshape(3, 3), np.zeros((0, 2))), poses.reshape(-1))
    assert np.allclose(J.toarray(), numeric, atol=1e-6)
    assert np.allclose(r, evaluate(graph, poses, np.zeros((0, 2))))


def test_fixes_round_trip_through_a_stream() -> None:
    events = [
        Start(0.0, (0.0, 0.0, 0.0)),
        Position(0.5, (1.0, 2.0), cov=((1.0, 0.1), (0.1, 2.0)), offset=(0.2, -0.1)),
        Heading(0.5, 0.3, 0.05),
        Position(1.0, (1.5, 2.5), (0.4, 0.4)),
    ]
    buffer = io.StringIO()
    write_stream(buffer, events)
    assert '"type": "position"' in buffer.getvalue() and '"type": "heading"' in buffer.getvalue()
    assert list(validate_events(events)) == events


@pytest.mark.parametrize(
    ("record", "field", "message"),
    [
        ({"type": "position", "t": 1.0, "sigma": [1.0, 1.0]}, "xy", "missing required field"),
        ({"type": "position", "t": 1.0, "xy": [1.0], "sigma": [1.0, 1.0]}, "xy", "a list of 2 numbers"),
        ({"type": "position", "t": 1.0, "xy": [1.0, 2.0]}, "sigma", "missing noise"),
        ({"type": "position", "t": 1.0, "xy": [1.0, 2.0], "sigma": [1.0, 0.0]}, "sigma[1]", "standard deviation"),
        ({"type": "position", "t": 1.0, "xy": [1.0, 2.0], "cov": [[1.0, 2.0], [2.0, 1.0]]}, "cov", "positive defin"),
        (
            {"type": "position", "t": 1.0, "xy": [1.0, 2.0], "sigma": [1.0, 1.0], "offset": [1.0, "a"]},
            "offset[1]",
            "a number",
        ),  # fmt: skip
        ({"type": "position", "t": 1.0, "xy": [1.0, 2.0], "sigma": [1.0, 1.0], "theta": 1.0}, "theta", "unknown"),
        ({"type": "heading", "t": 1.0, "sigma": 0.1}, "theta", "missing required field"),
        ({"type": "heading", "t": 1.0, "theta": 90.0, "sigma": 0.1}, "theta", "in degrees"),
        ({"type": "heading", "t": 1.0, "theta": 0.5, "sigma": -0.1}, "sigma", "standard deviation"),
        ({"type": "heading", "t": 1.0, "theta": 0.5}, "sigma", "missing required field"),
        ({"type": "heading", "t": 1.0, "theta": 0.5, "sigma": 0.1, "robot": 7}, "robot", "unknown robot"),
        ({"type": "heading", "t": -1.0, "theta": 0.5, "sigma": 0.1}, "t", "time goes backwards"),
    ],
)
def test_bad_fixes_give_one_line_naming_the_field(record: dict, field: str, message: str) -> None:
    with pytest.raises(InputError) as caught:
        list(validate_events([{"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0]}, record], name="s.jsonl"))
    text = str(caught.value)
    assert "\n" not in text and "s.jsonl:2" in text and field in text and message in text


def test_a_fix_between_ticks_gets_a_pose_of_its_own() -> None:
    events = [
        Start(0.0, (0.0, 0.0, 0.0)),
        Position(0.0, (0.1, 0.0), (1.0, 1.0)),
        Heading(0.5, 0.05, 0.1),
        Odometry(1.0, (1.0, 0.0, 0.1), (0.1, 0.1, 0.01)),
        Position(1.0, (1.0, 0.0), (1.0, 1.0)),
    ]
    steps = list(FrontEnd().steps(events))
    assert [s.t for s in steps] == [0.0, 0.5, 1.0]
    assert [len(s.fixes) for s in steps] == [1, 1, 1]
    assert isinstance(steps[1].fixes[0], Heading) and np.allclose(steps[1].odometry, [0.5, 0.0, 0.05], atol=0.02)


@pytest.mark.slow
def test_position_fixes_bring_every_estimator_close_and_the_ekf_stays_consistent() -> None:
    without, fixed = run(grid_world(SPARSE)), run(fixed_world(10))
    assert fixed["fixes"] == 20
    for name in ("ekf", "smoother", "batch"):
        assert fixed[name] < 0.2 * without[name], (name, fixed[name], without[name])
    assert fixed["ekf_nees"] < 6.0  # 3 for a consistent filter; drift without fixes reads far higher
    # the smoother folds marginalised fixes into its prior once: it ends where the batch does
    assert fixed["smoother"] == pytest.approx(fixed["batch"], rel=0.05)
    assert fixed["ekf"] == pytest.approx(fixed["batch"], rel=0.5)


@pytest.mark.slow
def test_heading_fixes_and_an_antenna_offset() -> None:
    plain = run(fixed_world(10))
    both = run(fixed_world(10, heading=0.02, offset=(0.8, 0.3)))
    assert both["fixes"] == 40
    for name in ("ekf", "smoother", "batch"):  # the offset is modelled: no worse than fixes of the centre
        assert both[name] < 1.2 * plain[name], (name, both[name], plain[name])
    assert both["smoother"] == pytest.approx(both["batch"], rel=0.05)


def test_an_ignored_offset_would_show() -> None:
    """The offset reaches the estimators: the same fixes read as of the robot's centre put the path elsewhere."""
    events = list(fixed_world(5, sigma=0.1, offset=(3.0, 0.0)))
    centred = [Position(e.t, e.xy, e.sigma) if isinstance(e, Position) else e for e in events]
    finals = []
    for stream in (events, centred):
        ekf = EkfSlam()
        for step in FrontEnd().steps(stream):
            ekf.step(step)
        finals.append(ekf.finish().poses)
    assert np.median(np.linalg.norm(finals[0][:, :2] - finals[1][:, :2], axis=1)) > 1.0


def test_a_live_pose_shown_early_takes_a_later_fix_once() -> None:
    from online_slam.engine import Engine

    events = [
        Start(0.0, (0.0, 0.0, 0.0), (0.5, 0.5, 0.1)),
        Odometry(1.0, (1.0, 0.0, 0.0), (0.1, 0.1, 0.01)),
        Position(1.0, (1.5, 0.0), (0.2, 0.2)),
    ]
    once, twice = Engine([EkfSlam()]), Engine([EkfSlam()])
    for event in events:
        once.push(event)
    for event in events[:2]:
        twice.push(event)
    twice.sync()  # the pose is shown before its fix arrives
    twice.push(events[2])
    assert once.sync()["ekf"].pose == pytest.approx(twice.sync()["ekf"].pose, abs=1e-9)
    assert twice.sync()["ekf"].pose[0] > 1.2


def test_the_gtsam_peer_refuses_fixes() -> None:
    gtsam_peer = pytest.importorskip("online_slam.gtsam_peer")
    if not gtsam_peer.available():
        pytest.skip("gtsam is not installed")
    base = FactorGraph.build(2, 0, fixed_poses=[0])
    mean, offset, W = fix_factors([Heading(0.0, 0.1, 0.1)])
    with pytest.raises(OnlineSlamError, match="absolute fixes"):
        gtsam_peer.to_gtsam(with_fixes(base, np.array([1]), mean, offset, W), np.zeros((2, 3)), np.zeros((0, 2)))


def test_acfr_gps_fixes_leave_the_truth(tmp_path: Path) -> None:
    from test_acfr import _simulate

    from online_slam.importers.acfr.reader import read_acfr
    from online_slam.models.fix import GPS_CORRELATION_S

    _simulate(tmp_path, seconds=30.0)
    plain = list(read_acfr(tmp_path))
    fixed = list(read_acfr(tmp_path, fixes=(5.0, 2.0)))
    fixes = [e for e in fixed if isinstance(e, Position)]
    assert len(fixes) == 5 and all(f.sigma == (2.0, 2.0) and f.offset == (4.0, 0.6) for f in fixes)
    assert not any(isinstance(e, Position) for e in plain)
    headers = [e for e in (*plain, *fixed) if isinstance(e, Header)]  # the GPS's wander declared with its fixes
    assert "fix_correlation_s" not in headers[0].meta and headers[1].meta["fix_correlation_s"] == GPS_CORRELATION_S
    times = [e.t for e in fixed if hasattr(e, "t")]
    assert times == sorted(times)
    truth_plain = {e.t: e.pose for e in plain if isinstance(e, Truth)}
    truth_fixed = {e.t: e.pose for e in fixed if isinstance(e, Truth)}
    # the truth no longer reads the fix readings: it changes at the poses beside each fix, nowhere else
    changed = [t for t, pose in truth_plain.items() if t not in truth_fixed or truth_fixed[t][:2] != pose[:2]]
    near = [min(abs(t - f.t) for f in fixes) for t in changed]
    assert len(changed) >= len(fixes) and max(near) < 0.2 + 1e-9
    buffer = tmp_path / "fixed.jsonl"
    write_stream(buffer, fixed)
    assert sum(1 for e in read_stream(buffer) if isinstance(e, Position)) == 5


@pytest.mark.slow
def test_a_recording_draws_fixes_and_reads_back(tmp_path: Path) -> None:
    pytest.importorskip("rerun", reason="rerun-sdk is not installed")
    pytest.importorskip("datafusion", reason="rerun-sdk[catalog] is not installed")
    from online_slam.pipeline import ReplayConfig, replay
    from online_slam.sinks.recording import Recording, RerunConfig, RerunSink
    from online_slam.sinks.recording.layout import Layout

    stream, rrd = tmp_path / "fixed.jsonl", tmp_path / "fixed.rrd"
    write_stream(stream, [e for e in fixed_world(10, heading=0.05, offset=(0.5, 0.0)) if getattr(e, "t", 0.0) <= 60.0])
    config = ReplayConfig(estimators=("ekf", "smoother"))
    sink = RerunSink(RerunConfig(path=str(rrd)), str(stream), Layout(online=("odometry", "ekf", "smoother")))
    results = replay(stream, config, sinks=[sink])
    with Recording(rrd) as recording:
        steps, errors = recording.metric("ekf", "position_error_m")
        assert len(steps) == len(errors) > 0
        entities = set(recording.entity_paths())
    assert {"/world/fixes/position", "/world/fixes/position_cov", "/world/fixes/heading"} <= entities
    assert results.error is None


def test_truth_of_an_antenna_is_scored_at_that_point(rng: np.random.Generator) -> None:
    from online_slam.estimators.protocol import Estimate
    from online_slam.evaluation.scoring import evaluate as score
    from online_slam.evaluation.scoring import position_errors
    from online_slam.frontend.pose import GroundTruth

    poses = np.c_[np.cumsum(rng.normal(0, 1, (50, 2)), axis=0), rng.uniform(-np.pi, np.pi, 50)]
    c, s = np.cos(0.4), np.sin(0.4)
    antenna = fixed_point(poses, (4.0, 0.6)) @ np.array([[c, s], [-s, c]]) + (10.0, -3.0)  # another frame
    known = {i: np.r_[antenna[i], np.nan] for i in range(50)}
    estimate = Estimate("x", poses, (), np.zeros((0, 2)))
    offsets = {i: np.array([4.0, 0.6]) for i in range(50)}
    assert score(estimate, GroundTruth(poses=known, offsets=offsets)).rmse_m < 1e-9
    assert score(estimate, GroundTruth(poses=known)).rmse_m > 1.0  # the axle is not where the antenna is
    rows = np.array([known[i] for i in range(50)])
    assert np.nanmax(position_errors(poses, rows, "anchor", offsets)) < 1e-9


def test_truth_offsets_round_trip_and_go_with_positions_only(tmp_path: Path) -> None:
    events = [Start(0.0, (0.0, 0.0, 0.0)), Truth(0.0, (1.0, 2.0, float("nan")), offset=(4.0, 0.6))]
    write_stream(tmp_path / "s.jsonl", events)
    again = list(read_stream(tmp_path / "s.jsonl"))
    assert isinstance(again[1], Truth) and again[1].offset == (4.0, 0.6)
    fe = FrontEnd()
    list(fe.steps(events + [Odometry(1.0, (1.0, 0.0, 0.0), sigma=(0.1, 0.1, 0.1))]))
    np.testing.assert_allclose(fe.truth.offsets[0], (4.0, 0.6))
    bad = {"type": "truth", "t": 1.0, "pose": [0.0, 0.0, 0.0], "offset": [1.0, 0.0]}
    with pytest.raises(InputError, match="offset"):
        list(validate_events([{"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0]}, bad], name="s.jsonl"))


def test_slam_takes_position_and_heading_fixes() -> None:
    from online_slam import Slam

    slam = Slam("ekf")
    slam.add_odometry(1.0, delta=[1.0, 0.0, 0.0], sigma=[0.3, 0.3, 0.1])
    slam.add_position(1.0, xy=[2.3, 0.5], sigma=[0.02, 0.02], offset=[0.3, 0.0])  # the antenna 0.3 m ahead
    slam.add_heading(1.0, theta=0.2, sigma=0.01)
    slam.add_odometry(2.0, delta=[1.0, 0.0, 0.0], sigma=[0.05, 0.05, 0.01])
    estimate = slam.estimate()
    assert estimate.snapshot.info["fixes_used"] == 2 and estimate.snapshot.info["fixes_rejected"] == 0
    np.testing.assert_allclose(
        estimate.trajectory[1], (2.0 - 0.3 * (np.cos(0.2) - 1), 0.5 - 0.3 * np.sin(0.2), 0.2), atol=0.1
    )
    before = slam.poses
    with pytest.raises(InputError, match="Slam.add_position.*sigma"):
        slam.add_position(2.5, xy=[1.0, 1.0])
    with pytest.raises(InputError, match="Slam.add_heading.*theta"):
        slam.add_heading(2.5, theta=90.0, sigma=0.1)  # degrees
    assert slam.poses == before


def jumped(jump: np.ndarray) -> tuple[list[Event], list[int]]:
    """The fixed world (position and heading fixes) with one fix jumped by ``jump`` ``[dx, dy, dtheta]`` (a position
    fix when dtheta is 0, else a heading fix) midway; and where its fixes are."""
    events = list(fixed_world(every=10, sigma=0.3, heading=0.05))
    fixes = [i for i, e in enumerate(events) if isinstance(e, (Position, Heading))]
    k = fixes[len(fixes) // 2] if jump[2] == 0 else fixes[len(fixes) // 2 + 1]
    bad = events[k]
    if isinstance(bad, Position):
        events[k] = Position(bad.t, tuple(map(float, np.array(bad.xy) + jump[:2])), bad.sigma, offset=bad.offset)
    else:
        assert isinstance(bad, Heading)
        events[k] = Heading(bad.t, float(wrap(bad.theta + jump[2])), bad.sigma)
    return events, fixes


@pytest.mark.parametrize("jump", [np.array([30.0, -20.0, 0.0]), np.array([0.0, 0.0, 2.5])])
def test_the_ekf_gates_a_fix_that_jumps(jump: np.ndarray) -> None:
    events, fixes = jumped(jump)
    from online_slam.estimators import EkfConfig

    def final(events: Iterable[Event], gate: float = 0.9999) -> tuple[np.ndarray, dict]:
        fe, ekf = FrontEnd(), EkfSlam(EkfConfig(gate_probability=gate))
        for step in fe.steps(events):
            ekf.step(step)
        estimate = ekf.finish()
        return estimate.poses, dict(estimate.info)

    poses, info = final(events)
    assert info["fixes_rejected"] == 1 and info["fixes_used"] == len(fixes) - 1
    clean, clean_info = final(fixed_world(every=10, sigma=0.3, heading=0.05))
    assert clean_info["fixes_rejected"] == 0 and clean_info["fixes_used"] == len(fixes)
    assert np.abs(poses[:, :2] - clean[:, :2]).max() < 0.5  # the jump did not drag it
    ungated, ungated_info = final(events, gate=1.0)  # without the gate it does
    assert ungated_info["fixes_rejected"] == 0 and np.abs(ungated[:, :2] - clean[:, :2]).max() > 1.0


def correlated_fixes(tau: float, sigma: float = 0.3) -> Iterator[Event]:
    """The sparse world with a position fix at every pose whose errors are first-order Markov (time constant
    ``tau`` seconds): a GPS whose error wanders."""
    rng = np.random.default_rng(5)
    error, last = rng.normal(0.0, sigma, 2), None
    for event in grid_world(SPARSE):
        yield event
        if isinstance(event, Truth) and event.t > 0.0:
            rho = np.exp(-(event.t - last) / tau) if last is not None else 0.0
            error = rho * error + np.sqrt(1.0 - rho**2) * rng.normal(0.0, sigma, 2)
            last = event.t
            xy = np.array(event.pose[:2]) + error
            yield Position(event.t, tuple(map(float, xy)), (sigma, sigma))


@pytest.mark.parametrize("tau", [0.5, 3.0, 20.0])
def test_the_widening_is_the_information_correlated_fixes_hold(tau: float) -> None:
    # The mean of n AR(1) samples (one every dt) has variance sigma^2 / n (1 + 2 sum_k (1 - k/n) rho^k): as n
    # grows, that of n independent samples widened by (1 + rho) / (1 - rho).
    dt, n = 1.0, 20_000
    rho = np.exp(-dt / tau)
    k = np.arange(1, n)
    exact = 1.0 + 2.0 * np.sum((1.0 - k / n) * rho**k)
    assert correlated_widening(dt, tau) == pytest.approx(exact, rel=5e-3)  # the rest: the sum's finite n
    assert correlated_widening(100.0 * tau, tau) == pytest.approx(1.0, abs=1e-12)
    assert correlated_widening(0.0, tau) >= 1e12


def test_the_front_end_widens_each_fix_by_its_correlation_with_the_one_before() -> None:
    events: list[Event] = [
        Start(0.0, (0.0, 0.0, 0.0)),
        Position(0.0, (0.0, 0.0), (0.5, 0.5)),
        Heading(0.0, 0.0, 0.1),
        Odometry(1.0, (1.0, 0.0, 0.0), (0.1, 0.1, 0.01)),
        Position(1.0, (1.0, 0.0), cov=((0.25, 0.0), (0.0, 0.25))),
        Heading(1.0, 0.0, 0.1),
        Odometry(2.0, (1.0, 0.0, 0.0), (0.1, 0.1, 0.01)),
    ]
    steps = list(FrontEnd(FrontEndConfig(fix_correlation=2.0)).steps(events))
    widen = correlated_widening(1.0, 2.0)
    first, second = steps[0].fixes, steps[1].fixes
    assert first[0].sigma == (0.5, 0.5) and first[1].sigma == 0.1  # the first of each kind: as given
    assert np.allclose(second[0].cov, 0.25 * widen * np.eye(2))  # its kind's previous fix 1 s before
    assert second[1].sigma == pytest.approx(0.1 * np.sqrt(widen))
    unset = list(FrontEnd().steps(events))  # no header, no option: independent
    assert unset[1].fixes[0].cov == ((0.25, 0.0), (0.0, 0.25))
    declared = [Header(name="gps", meta={"fix_correlation_s": 2.0}), *events]
    assert np.allclose(list(FrontEnd().steps(declared))[1].fixes[0].cov, 0.25 * widen * np.eye(2))
    off = FrontEndConfig(fix_correlation=0.0)  # the option overrides the header
    assert list(FrontEnd(off).steps(declared))[1].fixes[0].cov == ((0.25, 0.0), (0.0, 0.25))


def test_fixes_with_wandering_errors_keep_the_ekf_consistent_once_widened() -> None:
    tau = 20.0
    plain = run(correlated_fixes(tau))
    widened = run(correlated_fixes(tau), FrontEndConfig(fix_correlation=tau))
    assert plain["fixes"] == widened["fixes"] == 199
    assert plain["ekf_nees"] > 6.0  # each fix taken as news: far too sure
    assert widened["ekf_nees"] < 0.5 * plain["ekf_nees"]
    for name in ("smoother", "batch"):  # they weigh the whole run's fixes: more accurate for it
        assert widened[name] < plain[name]
    # The filter trades accuracy for it (0.53 against 0.39 m here): a fix too sure pulls the estimate to the
    # newest reading, which is close; widened, it follows the odometry more between readings.
    assert widened["ekf"] < 1.5 * plain["ekf"]


@pytest.mark.parametrize("jump", [np.array([36.0, 0.0, 0.0]), np.array([0.0, 0.0, 2.5])])
def test_the_smoother_and_the_batch_refuse_a_fix_that_jumps(jump: np.ndarray) -> None:
    events, _ = jumped(jump)
    clean, moved = run(fixed_world(every=10, sigma=0.3, heading=0.05)), run(events)
    for name in ("smoother", "batch"):  # before the gate: 3.67 / 4.03 m (position), 0.80 / 0.82 m (heading)
        assert moved[name] < clean[name] + 0.02, (name, moved[name], clean[name])
    fe = FrontEnd()
    smoother, batch = SlidingWindowSmoother(SmootherConfig(window=WindowConfig(size=10))), BatchEstimator()
    for step in fe.steps(events):
        smoother.step(step)
        batch.step(step)
    assert smoother.finish().info["fixes_rejected"] == 1 and batch.finish().info["fixes_rejected"] == 1
    started = BatchEstimator()  # from the smoother's estimate, as a replay starts it: refused there at once
    for step in FrontEnd().steps(events):
        started.step(step)
    assert started.finish(smoother.finish()).info["fixes_rejected"] == 1


def test_a_fix_widened_for_its_correlation_is_still_judged_by_its_own_covariance(tmp_path: Path) -> None:
    events, _ = jumped(np.array([30.0, 0.0, 0.0]))
    path = tmp_path / "jump.jsonl"
    write_stream(path, events)
    done = run_cli("replay", str(path), "--fix-correlation", "20", "--json", str(tmp_path / "out.json"))
    assert done.returncode == 0, done.stderr
    for name in ("ekf", "smoother", "batch"):  # widened, the jump would read within the gate (30 m / 4.2 sigma)
        assert f"{name}: fixes 39 used, 1 refused by the gate" in done.stdout
    figures = json.loads((tmp_path / "out.json").read_text())["estimators"]
    assert all(figures[name]["fixes_rejected"] == 1 for name in ("ekf", "smoother", "batch"))


@pytest.mark.parametrize("value", [-1, "abc", [20], True, float("inf")])
def test_a_bad_declared_fix_correlation_is_one_line(value: object) -> None:
    header = json.dumps({"type": "header", "format": "online-slam", "version": 1, "fix_correlation_s": value})
    with pytest.raises(InputError) as caught:
        list(parse_lines("s.jsonl", [header]))
    assert caught.value.field == "fix_correlation_s" and "expected seconds >= 0" in str(caught.value)
