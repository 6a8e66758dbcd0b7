"""The EKF's odometry bias state: its model and Jacobians, its recovery of a simulated bias (one robot and
several), its checkpoint, and how a stream or the options ask for it."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA, needs_data
from hypothesis import given, settings
from hypothesis import strategies as st
from inprocess import run_cli

from online_slam.checkpoint import read_checkpoint, write_checkpoint
from online_slam.errors import InputError
from online_slam.estimators.ekf import EkfSlam
from online_slam.frontend.steps import FrontEnd, FrontEndConfig
from online_slam.geometry.se2 import compose
from online_slam.models.motion import unbiased_increment
from online_slam.options import replay_config
from online_slam.pipeline.api import replay
from online_slam.sources.events import Header, Odometry, Start
from online_slam.sources.meet import MeetConfig, meet_world
from online_slam.sources.odometry_bias import biased_odometry
from online_slam.sources.stream import read_stream, write_stream
from online_slam.sources.worlds import GridConfig, grid_world

finite = st.floats(-2.0, 2.0, allow_nan=False)
PRIOR = {"odometry_bias_scale": 0.1, "odometry_bias_rate": 0.02}


def numerical(f, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central differences of f at x, shape (len(f(x)), len(x))."""
    columns = []
    for i in range(len(x)):
        d = np.zeros(len(x))
        d[i] = eps
        columns.append((f(x + d) - f(x - d)) / (2 * eps))
    return np.stack(columns, axis=1)


@given(st.tuples(finite, finite, finite), st.tuples(st.floats(-0.2, 0.2), st.floats(-0.05, 0.05)),
       st.floats(0.01, 5.0))  # fmt: skip
@settings(max_examples=50, deadline=None)
def test_unbiased_increment_inverts_the_bias_and_its_jacobian_is_numerical(delta, bias, dt) -> None:
    logged = next(e.delta for e in biased_odometry([Start(0.0, (0, 0, 0)), Odometry(dt, delta)], bias)
                  if isinstance(e, Odometry))  # fmt: skip
    moved, J = unbiased_increment(logged, bias, dt)
    assert np.allclose(moved, delta, atol=1e-12)
    assert np.allclose(J, numerical(lambda b: unbiased_increment(logged, b, dt)[0], np.array(bias)), atol=1e-7)


def _filter_with_bias(sigmas: tuple[float, float]) -> EkfSlam:
    """An EKF after its first step, with a bias state of the given prior sigmas (the standard linearization)."""
    frontend = FrontEnd(FrontEndConfig(odometry_bias_scale=sigmas[0], odometry_bias_rate=sigmas[1]))
    events = [Start(0.0, (0.0, 0.0, 0.0), sigma=(0.1, 0.1, 0.05)), Odometry(1.0, (0.5, 0.0, 0.0), sigma=(0.1,) * 3)]
    ekf = EkfSlam(replay_config({"ekf_linearization": "standard"}).ekf)
    ekf.step(next(iter(frontend.steps(events))))
    return ekf


def test_prediction_carries_the_bias_covariance_as_its_jacobian_says() -> None:
    ekf = _filter_with_bias((0.05, 0.01))
    rng = np.random.default_rng(3)
    A = rng.normal(size=(5, 5))
    ekf.x[:, 0] = [1.0, -2.0, 0.7, 0.03, -0.004]
    ekf.P = A @ A.T * 0.01
    before, P = ekf.x[:, 0].copy(), ekf.P.copy()
    u, Q, dt = np.array([0.8, 0.1, 0.3]), np.diag([0.01, 0.02, 0.003]), 2.5

    def moved(state: np.ndarray) -> np.ndarray:
        return np.r_[compose(state[:3], unbiased_increment(u, state[3:5], dt)[0]), state[3:5]]

    ekf.predict(u, Q, dt)
    J = numerical(moved, before)
    G = numerical(lambda v: compose(before[:3], v), unbiased_increment(u, before[3:5], dt)[0])
    expected = J @ P @ J.T
    expected[:3, :3] += G @ Q @ G.T
    assert np.allclose(ekf.x[:, 0], moved(before), atol=1e-12)
    assert np.allclose(ekf.P, expected, atol=1e-8)


def _grid(bias: tuple[float, float], seed: int = 3) -> list:
    """The grid world of 400 poses seeing landmarks within 6 m (a few per pose), its odometry biased."""
    return list(biased_odometry(grid_world(GridConfig(poses=400, seed=seed, sensor_range=6.0)), bias))


@pytest.fixture(scope="module")
def biased_grid() -> dict:
    """The grid world with its odometry 4% long and turning 5 mrad/s, replayed with and without the bias state."""
    events = _grid((0.04, 0.005))
    plain = replay(events, replay_config({"estimators": "ekf"}))
    modelled = replay(events, replay_config({"estimators": "ekf", **PRIOR}))
    return {"plain": plain, "modelled": modelled}


def test_the_ekf_recovers_a_simulated_bias_and_stays_consistent(biased_grid: dict) -> None:
    s, w, sd_s, sd_w = biased_grid["modelled"].estimates["ekf"].info["odometry_bias"][None]
    assert abs(s - 0.04) < 4 * sd_s and sd_s < 0.01
    assert abs(w - 0.005) < 4 * sd_w and sd_w < 0.002
    plain, modelled = biased_grid["plain"].estimators["ekf"], biased_grid["modelled"].estimators["ekf"]
    assert modelled.online_rmse_m < 0.5 * plain.online_rmse_m  # 0.298 against 0.812 m
    assert modelled.nees_mean < 4.0 < 6.0 < plain.nees_mean  # 2.64 against 7.57


def test_without_the_option_nothing_changes() -> None:
    events = list(grid_world(GridConfig(poses=60, seed=5)))
    a = replay(events, replay_config({"estimators": "ekf"})).estimates["ekf"]
    off = {"odometry_bias_scale": 0.0, "odometry_bias_rate": 0.0}
    b = replay(events, replay_config({"estimators": "ekf", **off})).estimates["ekf"]
    assert np.array_equal(a.poses, b.poses) and "odometry_bias" not in a.info
    assert a.info["state_size"] == b.info["state_size"]


def test_several_robots_each_get_their_own_bias() -> None:
    biases = {1: (0.05, 0.0), 2: (-0.04, 0.004), 3: (0.0, -0.006)}
    events = list(biased_odometry(meet_world(MeetConfig(poses=250)), biases))
    plain = replay(events, replay_config({"estimators": "ekf"}))
    result = replay(events, replay_config({"estimators": "ekf", **PRIOR}))
    found = result.estimates["ekf"].info["odometry_bias"]
    assert set(found) == set(biases)
    for robot, (s, w) in biases.items():
        fs, fw, _, sd_w = found[robot]
        # each increment is 0.5 m with 0.05 m sigmas: the scale reads 1-2% high, unbiased streams alike
        assert abs(fs - s) < 0.035 and abs(fw - w) < 4 * sd_w, (robot, found[robot])
    assert result.estimators["ekf"].online_rmse_m < 0.7 * plain.estimators["ekf"].online_rmse_m  # 0.073, 0.134 m


def test_a_checkpointed_bias_state_continues_bit_for_bit(tmp_path: Path) -> None:
    frontend = FrontEnd(FrontEndConfig(odometry_bias_scale=0.1, odometry_bias_rate=0.02))
    steps = list(frontend.steps(_grid((0.04, 0.005), seed=4)[:200]))
    config = replay_config({"estimators": "ekf"}).ekf
    whole, first = EkfSlam(config), EkfSlam(config)
    for step in steps:
        whole.step(step)
    for step in steps[:80]:
        first.step(step)
    write_checkpoint(tmp_path / "ekf.ckpt", "ekf", first.state_dict())
    resumed = EkfSlam(config)
    resumed.load_state(read_checkpoint(tmp_path / "ekf.ckpt", "ekf"))
    for step in steps[80:]:
        resumed.step(step)
    assert resumed.state.biased
    assert np.array_equal(resumed.x, whole.x) and np.array_equal(resumed.P, whole.P)


def _write(path: Path, header: dict) -> Path:
    lines = [{"type": "header", "format": "online-slam", "version": 1, **header},
             {"type": "start", "t": 0.0, "pose": [0, 0, 0], "sigma": [0.01, 0.01, 0.01]},
             {"type": "odometry", "t": 1.0, "delta": [1.0, 0.0, 0.0], "sigma": [0.1, 0.1, 0.01]}]  # fmt: skip
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def test_a_header_declares_the_prior_and_the_option_overrides_it(tmp_path: Path) -> None:
    path = _write(tmp_path / "s.jsonl", {"odometry_bias": [0.02, 0.003]})
    events = list(read_stream(path))
    assert isinstance(events[0], Header)
    first = next(iter(FrontEnd().steps(events)))
    assert np.array_equal(first.odometry_bias, [0.02, 0.003])
    off = FrontEndConfig(odometry_bias_scale=0.0, odometry_bias_rate=0.0)
    assert next(iter(FrontEnd(off).steps(events))).odometry_bias is None
    one = FrontEndConfig(odometry_bias_scale=0.1)  # the rate's from the header
    assert np.array_equal(next(iter(FrontEnd(one).steps(events))).odometry_bias, [0.1, 0.003])
    assert replay(path, replay_config({"estimators": "ekf"})).estimates["ekf"].info["odometry_bias"]


@pytest.mark.parametrize("value", [[0.02], [0.02, -1.0], "0.02,0.003", [0.02, float("nan")]])
def test_a_bad_header_prior_names_its_field(tmp_path: Path, value: object) -> None:
    path = _write(tmp_path / "bad.jsonl", {"odometry_bias": value})
    with pytest.raises(InputError) as info:
        list(read_stream(path))
    assert (info.value.line, info.value.field) == (1, "odometry_bias")


@pytest.mark.parametrize("value", [-0.1, float("inf"), float("nan")])
def test_a_bad_option_is_refused(value: float) -> None:
    with pytest.raises(ValueError, match="odometry_bias_rate must be"):
        FrontEndConfig(odometry_bias_rate=value)


def test_the_command_line_reports_the_bias_it_found(tmp_path: Path) -> None:
    path = tmp_path / "biased.jsonl"
    write_stream(path, _grid((0.04, 0.005))[:1500])
    done = run_cli("replay", str(path), "--estimators", "ekf", "--odometry-bias-scale", "0.1",
                   "--odometry-bias-rate", "0.02")  # fmt: skip
    assert done.returncode == 0, done.stderr
    line = next(line for line in done.stdout.splitlines() if "odometry bias" in line)
    assert re.search(r"ekf: odometry bias: distances read [3-5]\.\d\d \+- \d\.\d\d% long, turns [45]\.\d\d \+- "
                     r"\d\.\d\d mrad/s counter-clockwise", line)  # fmt: skip
    both = run_cli("replay", str(path), "--estimators", "ekf,smoother", "--odometry-bias-scale", "0.1")
    assert "turns not modelled" in both.stdout
    assert "smoother: odometry taken as logged (only the EKF estimates its bias)" in both.stdout


def test_the_estimate_stream_carries_the_bias_as_estimated(tmp_path: Path) -> None:
    source, out = tmp_path / "biased.jsonl", tmp_path / "estimates.jsonl"
    write_stream(source, _grid((0.04, 0.005))[:1500])
    done = run_cli("replay", str(source), "--estimators", "ekf", "--odometry-bias-scale", "0.1",
                   "--odometry-bias-rate", "0.02", "--emit", str(out), "--quiet")  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    first, last = lines[1], lines[-1]
    assert first["odometry_bias_sd"][0] > 0.05 > last["odometry_bias_sd"][0]  # it learns as the robot drives
    (s, w), (sd_s, sd_w) = last["odometry_bias"], last["odometry_bias_sd"]
    assert abs(s - 0.04) < 4 * sd_s and abs(w - 0.005) < 4 * sd_w
    plain = tmp_path / "plain.jsonl"
    assert run_cli("replay", str(source), "--estimators", "ekf", "--emit", str(plain), "--quiet").returncode == 0
    assert "odometry_bias" not in json.loads(plain.read_text().splitlines()[-1])


@pytest.mark.slow
@needs_data("MRCLAM_Dataset6")
def test_a_biased_mrclam_robot_stays_found_with_the_importers_defaults() -> None:
    """MRCLAM robot 4 with its odometry 6% long and 8 mrad/s added: the plain EKF is lost (0.873 m, mean NEES 12.7);
    the header's bias prior holds it (0.105 m, 3.30)."""
    from online_slam.importers.mrclam.reader import read_mrclam

    events = list(biased_odometry(read_mrclam(SHARED_DATA / "MRCLAM_Dataset6", 4), (1.0 - 1.0 / 1.06, 0.008)))
    assert events[0].meta["odometry_bias"] == [0.05, 0.01]
    held = replay(events, replay_config({"estimators": "ekf"})).estimators["ekf"]
    assert held.online_rmse_m < 0.15 and held.nees_mean < 5.0
    plain = replay(events, replay_config({"estimators": "ekf", "odometry_bias_scale": 0.0, "odometry_bias_rate": 0.0}))
    assert plain.estimators["ekf"].online_rmse_m > 4 * held.online_rmse_m


def test_a_recording_holds_the_bias_as_it_was_learnt(tmp_path: Path) -> None:
    pytest.importorskip("datafusion", reason="rerun-sdk[catalog] is not installed")
    from online_slam.sinks.recording import Recording

    source, rrd = tmp_path / "biased.jsonl", tmp_path / "biased.rrd"
    write_stream(source, _grid((0.04, 0.005))[:1500])
    done = run_cli("replay", str(source), "--estimators", "ekf", "--odometry-bias-scale", "0.1",
                   "--odometry-bias-rate", "0.02", "--rrd", str(rrd), "--quiet")  # fmt: skip
    assert done.returncode == 0, done.stderr
    with Recording(rrd) as recording:
        steps, scale = recording.metric("ekf", "odometry_bias_scale")
        _, rate = recording.metric("ekf", "odometry_bias_rate")
    assert len(steps) == len(scale) == len(rate) > 100 and scale[0] == 0.0
    assert abs(scale[-1] - 0.04) < 0.02 and abs(rate[-1] - 0.005) < 0.002
