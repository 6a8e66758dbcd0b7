"""Noise calibrated without truth (--noise self): the redundancy numbers, the scales and biases it recovers on
worlds drawn with known noise and declared wrong, the front-end's bias correction, the replay and the CLI."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import REPLAY, SHARED_DATA, needs_data

from online_slam.errors import InputError, OnlineSlamError
from online_slam.evaluation.noise_self import SelfFit, describe, fit_self
from online_slam.frontend import FrontEnd, FrontEndConfig
from online_slam.frontend.noise import MIN_RANGE, scaled_event, unbiased_event
from online_slam.options import replay_config
from online_slam.pipeline import replay
from online_slam.pipeline.noise import with_noise_fit
from online_slam.solvers.redundancy import gauss_newton, group_traces
from online_slam.sources.events import Header, Observation, Scan
from online_slam.sources.meet import MeetConfig, meet_world
from online_slam.sources.stream import parse_lines
from online_slam.sources.timing import TimingConfig, timing_world
from online_slam.sources.worlds import Contamination, GridConfig, contaminate, grid_world, square_world, without_ids
from tests.test_cli import cli

MISDECLARED = {
    "odometry 0.3x": (0.09, 1.0),
    "odometry 3x": (9.0, 1.0),
    "sensor 0.3x": (1.0, 0.09),
    "sensor 3x": (1.0, 9.0),
}
"""Factors (odometry, sensor) a stream's covariances are declared with: its sigmas 0.3 or 3 times the true ones."""
MOUNT = (0.3, -0.05, math.radians(10))
BIAS = (0.1, 0.02)
"""A mounted camera's range (m) and bearing (rad) bias."""


def _fit(events) -> SelfFit:
    return fit_self(FrontEnd().steps(events))


def _declared(events, factors: tuple[float, float]) -> list:
    return [scaled_event(e, *factors) for e in events]


def _biased(events, bias: tuple[float, float] = BIAS) -> list:
    return [
        dataclasses.replace(e, range=e.range + bias[0], bearing=e.bearing + bias[1])
        if isinstance(e, Observation)
        else e
        for e in events
    ]


def test_redundancy_traces_and_step_equal_the_dense_computation() -> None:
    rng = np.random.default_rng(4)
    A = (sp.random(120, 30, density=0.15, random_state=5) + sp.vstack([sp.eye(30), sp.csr_matrix((90, 30))])).tocsr()
    rows = rng.uniform(size=120) < 0.4
    dense = A.toarray()
    N_inv = np.linalg.inv(dense.T @ dense)
    leverage = np.einsum("ij,jk,ik->i", dense, N_inv, dense)
    traces = group_traces(A, {"some": rows, "rest": ~rows})
    assert traces["some"] == pytest.approx(leverage[rows].sum(), rel=1e-6)
    assert traces["some"] + traces["rest"] == pytest.approx(30.0, rel=1e-6)
    r = rng.normal(size=120)
    step, cov = gauss_newton(A, r, 4)
    np.testing.assert_allclose(step, -N_inv @ dense.T @ r, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(cov, N_inv[-4:, -4:], rtol=1e-9, atol=1e-14)


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("name", list(MISDECLARED))
def test_the_self_fit_recovers_a_misdeclared_scale(name: str, seed: int) -> None:
    """Drawn with the grid's sigmas, declared with 0.3x or 3x of them: the fit finds the true scale within 15%
    (two seeds each; 20 seeds of 2000-pose worlds: ``python -m benchmarks.noise_self simulated``)."""
    factors = MISDECLARED[name]
    fit = _fit(_declared(grid_world(GridConfig(poses=800, landmarks=80, seed=seed)), factors))
    assert fit.converged and fit.increments == 799 and not fit.without_id
    assert fit.odometry_scale * factors[0] == pytest.approx(1.0, rel=0.15)
    assert fit.sensor_scale * factors[1] == pytest.approx(1.0, rel=0.15)
    assert 0.5 * 3 * fit.increments < fit.odometry_redundancy < 3 * fit.increments
    assert not fit.sensor_bias  # no bias drawn: none beyond noise


def test_the_self_fit_recovers_a_mounted_sensors_bias_and_the_replay_takes_it_off() -> None:
    world = TimingConfig(duration=60.0, mount=MOUNT, landmarks=80, seed=3)
    events = _biased(timing_world(world))
    fit = _fit(events)
    (bias,) = fit.biases
    assert bias.sensor == "camera" and bias.significant == (True, True)
    assert abs(bias.range_m - BIAS[0]) < 4 * bias.range_sd < 0.02
    assert abs(bias.bearing_rad - BIAS[1]) < 4 * bias.bearing_sd < 0.02
    assert fit.sensor_bias == (("camera", bias.range_m, bias.bearing_rad),)
    assert fit.odometry_scale == pytest.approx(1.0, rel=0.2) and fit.sensor_scale == pytest.approx(1.0, rel=0.15)
    config = replay_config({"estimators": "batch"})
    plain = replay(events, config).estimators["batch"].landmark_rmse_m
    fitted = replay(events, replay_config({"estimators": "batch", "noise": "self"})).estimators["batch"]
    assert fitted.landmark_rmse_m < 0.5 * plain
    clean = _fit(timing_world(world))
    assert not clean.sensor_bias and clean.biases[0].significant == (False, False)


def test_several_robots_and_their_sightings_of_each_other() -> None:
    factors = (9.0, 0.09)
    fit = _fit(_declared(meet_world(MeetConfig(poses=150, seed=4)), factors))
    assert fit.robot_sightings > 50 and fit.converged
    assert fit.odometry_scale * factors[0] == pytest.approx(1.0, rel=0.15)
    assert fit.sensor_scale * factors[1] == pytest.approx(1.0, rel=0.15)


def test_sightings_with_another_landmarks_id_are_left_out() -> None:
    """Every wrong id of a landmark also sighted right is left out (a landmark only ever sighted wrong fits its
    sightings: nothing tells them apart), with few inliers, and the scale stays right."""
    dirty = list(contaminate(grid_world(GridConfig(poses=400, landmarks=60, seed=2)), Contamination(wrong_ids=0.03)))
    sightings = [e for e in dirty if isinstance(e, Observation)]
    sighted_right = {e.landmark for e in sightings if e.truth_outlier is None}
    wrong = [e for e in sightings if e.truth_outlier == "wrong_id"]
    telling = sum(e.landmark in sighted_right for e in wrong)
    fit = _fit(_declared(dirty, (1.0, 0.09)))
    assert telling > 25 and telling <= fit.gated <= len(wrong) + 5
    assert fit.sensor_scale * 0.09 == pytest.approx(1.0, rel=0.15)


def test_only_sightings_with_ids_are_used() -> None:
    events = list(square_world())
    with pytest.raises(OnlineSlamError, match="no landmark sighting with an id"):
        _fit(without_ids(events))
    mixed = [dataclasses.replace(e, landmark=None) if isinstance(e, Observation) and e.t > 20 else e for e in events]
    fit = _fit(mixed)
    assert fit.without_id > 0 and fit.sightings + fit.without_id == 95


def test_the_front_end_takes_a_sensors_bias_off_its_range_bearing_landmark_sightings() -> None:
    biases = (("cam", 0.1, 0.2), (None, -0.05, 0.0))
    cam = Observation(t=1.0, landmark=3, range=2.0, bearing=3.1, sigma=(0.1, 0.01), sensor="cam")
    moved = unbiased_event(cam, biases)
    assert moved.range == pytest.approx(1.9) and moved.bearing == pytest.approx(2.9)
    wrapped = unbiased_event(dataclasses.replace(cam, bearing=-3.1), (("cam", 0.0, 0.2),))
    assert wrapped.bearing == pytest.approx(2 * math.pi - 3.3)
    assert unbiased_event(dataclasses.replace(cam, range=0.05), biases).range == MIN_RANGE
    robot = Observation(t=1.0, landmark=None, range=2.0, bearing=0.1, sigma=(0.1, 0.01), robot_seen=2)
    xy = Observation(t=1.0, landmark=3, sigma=(0.1, 0.1), xy=(1.0, 2.0))
    other = dataclasses.replace(cam, sensor="other")
    assert all(unbiased_event(e, biases) is e for e in (robot, xy, other))
    scan = Scan(t=1.0, landmarks=(1, 2), ranges=(1.0, 2.0), bearings=(0.0, 0.1), noise=((0.1, 0.01),) * 2)
    assert unbiased_event(scan, biases).ranges == pytest.approx((1.05, 2.05))
    with pytest.raises(ValueError, match="sensor_bias"):
        FrontEndConfig(sensor_bias=(("cam", 0.1, float("nan")),))
    with pytest.raises(ValueError, match="named twice"):
        FrontEndConfig(sensor_bias=(("cam", 0.1, 0.0), ("cam", 0.0, 0.1)))


def test_correlated_sightings_keep_their_sigmas_and_have_no_bias_taken_off() -> None:
    """A header ``sightings_correlated`` (MRCLAM): the sensor scale and biases are measured and shown, not applied."""
    header, *rest = _biased(timing_world(TimingConfig(duration=30.0, mount=MOUNT, landmarks=60, seed=4)))
    assert isinstance(header, Header)
    marked = [dataclasses.replace(header, meta={**header.meta, "sightings_correlated": True}), *rest]
    told: list = []
    replay(marked, replay_config({"noise": "self", "estimators": "ekf"}), on_noise_fit=told.append)
    (fit,) = told
    assert fit.sightings_correlated and fit.biases[0].significant == (True, True)
    assert fit.applied_sensor_scale == 1.0 and fit.sensor_bias == ()
    assert "that sensor scale and the biases not applied" in describe(fit)
    frontend = with_noise_fit(replay_config({}), fit).frontend
    assert frontend.sensor_bias == () and frontend.sensor_noise_scale == 1.0
    assert frontend.odometry_noise_scale == fit.odometry_scale


def test_cli_noise_self_prints_the_fit_and_replays() -> None:
    result = cli("replay", "square", "--noise", "self", "--estimators", "ekf,batch")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "noise self-fit (no truth): 24 odometry increments, 95 landmark sightings" in out
    assert "odometry scale" in out and "sensor scale" in out and "(centre)" in out
    assert out.index("replaying with --odometry-noise-scale") < out.index("estimator ")


@pytest.mark.parametrize(
    ("args", "stdin", "message"),
    [
        (("square", "--noise", "self", "--sensor-noise-scale", "2"), None, "--noise self fits the scale"),
        (("square", "--noise", "self", "--odometry-noise-scale", "0.09"), None, "--noise self fits the scale"),
        (("-", "--noise", "self"), "", "--noise self reads the source twice"),
    ],
)
def test_cli_noise_self_refuses_a_scale_and_stdin(args: tuple[str, ...], stdin: str | None, message: str) -> None:
    result = cli("replay", *args, stdin=stdin)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and message in result.stderr


def _widened(events, factors: tuple[float, float], own_scale: dict | None = None) -> list:
    """The events with each landmark sighting's variances widened by ``factors`` (range, bearing), as its line says,
    and the header saying ``sightings_correlated`` (MRCLAM's conversion, errors here independent), and
    ``sightings_own_scale`` when ``own_scale`` is given."""
    f = np.asarray(factors)
    own = {} if own_scale is None else {"sightings_own_scale": own_scale}
    out = []
    for e in events:
        if isinstance(e, Header):
            e = dataclasses.replace(e, meta={**e.meta, "sightings_correlated": True, **own})
        elif isinstance(e, Observation) and e.landmark is not None:
            e = dataclasses.replace(e, sigma=tuple(np.asarray(e.sigma) * np.sqrt(f)), widened=tuple(f))
        out.append(e)
    return out


OWN_SCALE = {"range": [1.0, 1.0], "spread": 2.5}
"""A declared range for the simulated widened sightings: their errors are independent, so declared right their own
reading is 1."""


@pytest.mark.slow
@pytest.mark.parametrize(
    "declared, own_scale, applied",
    [(1.0, OWN_SCALE, (1.0, 1.0)), (0.09, None, (9.4, 12.8)), (9.0, OWN_SCALE, (0.111 / 1.15, 0.111 * 1.15))],
    ids=["right", "sensor 0.3x without a range", "sensor 3x"],
)
def test_widened_sightings_read_against_their_own_covariances_rescale_a_misdeclared_sensor(
    declared: float, own_scale: dict | None, applied: tuple[float, float]
) -> None:
    """Sightings widened 25x / 16x by their lines: against the widened covariances the fit reads ~1/20 and applies
    nothing (the widening is the source's); against their own it reads the factor the sensor is off by (11.1 for
    0.3x, 0.111 for 3x: within 15%). Without a declared range a reading above 1 is applied as it is; with one, the
    reading over its low end beyond the range and its spread, and nothing within (declared right)."""
    world = _widened(_declared(grid_world(GridConfig(poses=150, seed=3)), (1.0, declared)), (25.0, 16.0), own_scale)
    told: list = []
    replay(world, replay_config({"noise": "self", "estimators": "ekf"}), on_noise_fit=told.append)
    (fit,) = told
    assert fit.sightings_correlated and fit.sensor_scale < 0.1 / declared
    assert fit.own_sensor_scale is not None and applied[0] <= fit.applied_sensor_scale <= applied[1], fit
    assert fit.own_range == (None if own_scale is None else (1.0, 1.0, 2.5))
    assert "sensor scale against the sightings' own covariances" in describe(fit)
    assert with_noise_fit(replay_config({}), fit).frontend.sensor_noise_scale == fit.applied_sensor_scale


def _own(reading: float | None, declared: tuple[float, float, float] | None) -> SelfFit:
    """A fit of correlated sightings with this own-covariance reading and declared range (the rest immaterial)."""
    return SelfFit(10, 20, 0, 0, 0, 0, 0.8, 0.02, 25.0, 30.0, (), 3, True, True, reading, declared)


RANGE = (0.2, 0.5, 1.6)


@pytest.mark.parametrize(
    "reading, declared, applied, verdict",
    [
        (None, RANGE, 1.0, None),
        (0.4, None, 1.0, "not above 1: says nothing"),
        (3.0, None, 3.0, "above 1: the sensor is declared too sure by at least that much, applied"),
        (0.5 * 1.6, RANGE, 1.0, "within 1.6x of the source's range for sightings declared right 0.2-0.5: says nothing"),
        (0.2 / 1.6, RANGE, 1.0, "says nothing, not applied"),
        (0.5 * 1.7, RANGE, 4.25, "beyond 1.6x of the source's range for sightings declared right 0.2-0.5: 4.25x its"),
        (0.02, RANGE, 0.1, "0.1x its low end applied"),
    ],
)
def test_the_own_reading_is_applied_over_the_declared_ranges_low_end_beyond_its_spread(
    reading: float | None, declared: tuple[float, float, float] | None, applied: float, verdict: str | None
) -> None:
    fit = _own(reading, declared)
    assert fit.applied_sensor_scale == pytest.approx(applied, rel=1e-12)
    assert fit.flags().endswith(f"--sensor-noise-scale {applied:.4g}")
    text = describe(fit)
    assert (verdict in text) if verdict else "own covariances" not in text


@pytest.mark.parametrize(
    "value, field",
    [
        (0.3, "sightings_own_scale"),
        ({"range": [0.2, 0.5]}, "sightings_own_scale"),
        ({"range": [0.0, 0.5], "spread": 2.0}, "sightings_own_scale.range"),
        ({"range": [0.5, 0.2], "spread": 2.0}, "sightings_own_scale.range"),
        ({"range": [0.2], "spread": 2.0}, "sightings_own_scale.range"),
        ({"range": ["a", 0.5], "spread": 2.0}, "sightings_own_scale.range"),
        ({"range": [0.2, 0.5], "spread": 0.5}, "sightings_own_scale.spread"),
        ({"range": [0.2, 0.5], "spread": float("inf")}, "sightings_own_scale.spread"),
        ({"range": [0.2, 0.5], "spread": True}, "sightings_own_scale.spread"),
    ],
)
def test_a_bad_declared_own_scale_is_one_line(value: object, field: str) -> None:
    header = json.dumps({"type": "header", "format": "online-slam", "version": 1, "sightings_own_scale": value})
    with pytest.raises(InputError) as caught:
        list(parse_lines("s.jsonl", [header]))
    assert caught.value.field == field and caught.value.line == 1


@pytest.mark.slow
@pytest.mark.parametrize("world", ["waypoint", "meet"])
def test_the_benchmark_measures_the_other_worlds_too(world: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m benchmarks.noise_self simulated --world W``: one short seed, every misdeclaration; ``meet`` is
    three robots sighting each other (their robot sightings scaled with the landmarks')."""
    from benchmarks.noise_self import main

    poses = {"waypoint": "80", "meet": "45"}[world]  # meet: three robots of 15 poses (80 took 13 s)
    main(["simulated", "--world", world, "--seeds", "1", "--first-seed", "3", "--poses", poses])
    out = capsys.readouterr().out
    assert "seed 3 declared right" in out and "worst / median over 1 seeds" in out
    errors = [float(e) for e in re.findall(r"scale error ([-+]\d\.\d+)", out)]
    assert len(errors) == 4 and max(map(abs, errors)) < 0.3, out


@pytest.mark.slow
def test_the_shipped_mrclam_stream_declared_3x_too_unsure_is_rescaled_by_its_declared_range() -> None:
    """MRCLAM robot 1 as shipped (its header declares the own readings of streams declared right, 0.197-0.509),
    sightings declared 3x too unsure: the own reading (0.039) is more than 1.6x below the range, so 0.199 is applied
    (0.111 is right); replayed so, the EKF reads about as declared right (1.05x; 1.22x with nothing applied:
    benchmarks/RESULTS.md)."""
    from online_slam.pipeline.noise import fit_source_noise
    from online_slam.sources import read_stream

    events = _declared(read_stream(REPLAY / "mrclam6_robot1.jsonl.gz"), (1.0, 9.0))
    fit, _ = fit_source_noise(events, replay_config({"estimators": "ekf", "noise": "self"}))
    assert isinstance(fit, SelfFit) and fit.own_range == (0.197, 0.509, 1.6)
    assert fit.own_sensor_scale == pytest.approx(0.039, rel=0.1)
    assert fit.applied_sensor_scale == pytest.approx(fit.own_sensor_scale / 0.197, rel=1e-12)
    assert "its low end applied" in describe(fit)


@pytest.mark.slow
@needs_data("MRCLAM_Dataset6")
def test_the_own_benchmark_reads_robot_1_inside_the_declared_range(capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m benchmarks.noise_self own`` on one robot: its reading (0.349, inside the conversion's range
    0.197-0.509 of the five)."""
    from benchmarks.noise_self import own

    readings = own(str(SHARED_DATA / "MRCLAM_Dataset6"), robots=(1,))
    assert readings[1] == pytest.approx(0.3486, rel=0.02)
    assert "range (own_scale_range) 0.3486 - 0.3486" in capsys.readouterr().out
