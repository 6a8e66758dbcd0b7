"""Noise you can tune and check: scaling the source's covariances, and fitting them to its truth (--noise fit)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from online_slam import Slam
from online_slam.errors import ConfigError, OnlineSlamError
from online_slam.evaluation.noise_fit import describe, fit_noise
from online_slam.frontend import FrontEnd, FrontEndConfig
from online_slam.frontend.noise import scaled_event
from online_slam.options import replay_config
from online_slam.pipeline import replay
from online_slam.sources import square_world, write_stream
from online_slam.sources.events import Header, Observation, Odometry, Scan, Truth
from online_slam.sources.worlds import WORLDS
from tests.test_cli import cli


def _steps(events, config: FrontEndConfig | None = None):
    frontend = FrontEnd(config)
    return list(frontend.steps(events)), frontend.truth


def test_a_scale_multiplies_the_covariances_of_sigma_and_cov_events() -> None:
    odometry = Odometry(t=1.0, delta=(1.0, 0.0, 0.1), sigma=(0.1, 0.2, 0.03))
    full = Odometry(t=1.0, delta=(1.0, 0.0, 0.1), cov=((0.01, 0.002, 0.0), (0.002, 0.04, 0.0), (0.0, 0.0, 0.001)))
    sighting = Observation(t=1.0, landmark=3, range=2.0, bearing=0.5, sigma=(0.1, 0.01))
    scan = Scan(t=1.0, landmarks=(1, 2), ranges=(1.0, 2.0), bearings=(0.0, 0.1),
                noise=((0.1, 0.01), ((0.01, 0.001), (0.001, 0.0004))))  # fmt: skip
    for event in (odometry, full):
        scaled = scaled_event(event, 2.5, 7.0)
        np.testing.assert_allclose(scaled.covariance, 2.5 * event.covariance, rtol=1e-14)
    np.testing.assert_allclose(scaled_event(sighting, 2.5, 7.0).covariance, 7.0 * sighting.covariance, rtol=1e-14)
    noise = scaled_event(scan, 2.5, 7.0).noise
    np.testing.assert_allclose(np.square(noise[0]), 7.0 * np.square(scan.noise[0]), rtol=1e-14)
    np.testing.assert_allclose(noise[1], 7.0 * np.array(scan.noise[1]), rtol=1e-14)
    truth = Truth(t=1.0, pose=(0.0, 0.0, 0.0))
    assert all(scaled_event(e, 1.0, 1.0) is e for e in (odometry, full, sighting, scan))
    assert scaled_event(truth, 2.0, 2.0) is truth


def test_the_front_end_scales_every_step_and_scale_one_is_bit_identical() -> None:
    plain, _ = _steps(square_world())
    ones, _ = _steps(square_world(), FrontEndConfig(odometry_noise_scale=1.0, sensor_noise_scale=1.0))
    scaled, _ = _steps(square_world(), FrontEndConfig(odometry_noise_scale=3.0, sensor_noise_scale=0.5))
    for a, b, c in zip(plain, ones, scaled):
        if a.odometry_cov is not None:
            assert np.array_equal(a.odometry_cov, b.odometry_cov)
            np.testing.assert_allclose(c.odometry_cov, 3.0 * a.odometry_cov, rtol=1e-14)
            assert np.array_equal(a.odometry, c.odometry)
        assert np.array_equal(a.z_cov, b.z_cov) and np.array_equal(a.z, c.z)
        np.testing.assert_allclose(c.z_cov, 0.5 * a.z_cov, rtol=1e-14)
        assert a.prior_cov is None or np.array_equal(a.prior_cov, c.prior_cov)


def test_a_larger_scale_widens_the_estimated_covariance() -> None:
    small = replay("square", replay_config({"estimators": "ekf"}))
    wide = replay("square", replay_config({"estimators": "ekf", "odometry_noise_scale": 4.0}))
    assert wide.estimators["ekf"].nees_mean < small.estimators["ekf"].nees_mean


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), float("nan")])
def test_bad_scales_are_refused(bad: float) -> None:
    with pytest.raises(ConfigError, match="odometry_noise_scale"):
        replay_config({"odometry_noise_scale": bad})
    with pytest.raises(ValueError, match="sensor_noise_scale"):
        FrontEndConfig(sensor_noise_scale=bad)


def test_slam_takes_the_scales() -> None:
    slam = Slam("ekf", odometry_noise_scale=4.0, pose_covariance="linear")
    slam.start(0.0, [0.0, 0.0, 0.0])
    slam.add_odometry(1.0, [1.0, 0.0, 0.0], sigma=[0.1, 0.1, 0.01])
    assert slam.estimate().pose_cov[0, 0] == pytest.approx(4.0 * 0.01, rel=1e-12)


def test_the_fit_recovers_the_grid_worlds_noise_and_a_misdeclared_one() -> None:
    """grid draws odometry with sigma (0.05 m, 0.05 m, 0.01 rad) and sightings with (0.05 m, 0.5 deg), as declared."""
    fit = fit_noise(*_steps(WORLDS["grid"].events()))
    assert fit.increments == 1999 and fit.sightings > 20000
    truth = {"x": 0.05, "y": 0.05, "theta": 0.01, "range": 0.05, "bearing": np.radians(0.5)}
    for component in (*fit.odometry, *fit.sensor):
        assert component.sigma == pytest.approx(truth[component.name], rel=0.05)
        assert component.declared == pytest.approx(truth[component.name], rel=1e-9)
    assert fit.odometry_scale == pytest.approx(1.0, abs=0.1) and fit.sensor_scale == pytest.approx(1.0, abs=0.1)
    # the same world declaring 2x the odometry sigmas and 1/3 of the sighting sigmas: the fit undoes it
    wrong = fit_noise(*_steps(scaled_event(e, 4.0, 1 / 9) for e in WORLDS["grid"].events()))
    assert wrong.odometry_scale == pytest.approx(fit.odometry_scale / 4.0, rel=1e-6)
    assert wrong.sensor_scale == pytest.approx(fit.sensor_scale * 9.0, rel=1e-6)
    assert "--odometry-noise-scale 0.2486" in wrong.flags() and "grid" not in describe(wrong)


def test_the_fit_needs_truth(tmp_path: Path) -> None:
    no_truth = [e for e in square_world() if not isinstance(e, Truth)]
    with pytest.raises(OnlineSlamError, match="no truth to fit to"):
        replay(no_truth, replay_config({"noise": "fit"}))


def test_noise_fit_replays_with_the_fitted_scales() -> None:
    told = []
    fitted = replay("square", replay_config({"noise": "fit", "estimators": "ekf"}), on_noise_fit=told.append)
    (fit,) = told
    given = replay_config(
        {"estimators": "ekf", "odometry_noise_scale": fit.odometry_scale, "sensor_noise_scale": fit.sensor_scale}
    )
    assert fitted.estimators["ekf"].nees_mean == replay("square", given).estimators["ekf"].nees_mean


def test_noise_fit_leaves_sightings_the_source_declares_correlated_as_they_are() -> None:
    """A header ``sightings_correlated`` (MRCLAM's conversion: sigmas widened for repeated sightings' correlation):
    the sensor scale is measured and shown, the replay keeps the declared sigmas, the odometry scale applies."""
    events = [scaled_event(e, 1.0, 1 / 9) for e in square_world()]
    header, *rest = events
    assert isinstance(header, Header)
    marked = [dataclasses.replace(header, meta={**header.meta, "sightings_correlated": True}), *rest]
    told: list = []
    fitted = replay(marked, replay_config({"noise": "fit", "estimators": "ekf"}), on_noise_fit=told.append)
    (fit,) = told
    plain = fit_noise(*_steps(events))
    assert fit.sightings_correlated and fit.sensor_scale == pytest.approx(plain.sensor_scale, rel=1e-12)
    assert fit.applied_sensor_scale == 1.0 and fit.flags().endswith("--sensor-noise-scale 1")
    assert "sensor scale not applied" in describe(fit)
    given = replay_config({"estimators": "ekf", "odometry_noise_scale": fit.odometry_scale})
    assert fitted.estimators["ekf"].nees_mean == replay(events, given).estimators["ekf"].nees_mean


def test_cli_scales_and_noise_fit(tmp_path: Path) -> None:
    stream = tmp_path / "square.jsonl"
    write_stream(stream, square_world())
    plain = json.loads(cli("replay", str(stream), "--estimators", "ekf", "--json", "-").stdout)
    scaled = cli("replay", str(stream), "--estimators", "ekf", "--odometry-noise-scale", "4", "--json", "-")
    assert scaled.returncode == 0, scaled.stderr
    assert json.loads(scaled.stdout)["estimators"]["ekf"]["nees_mean"] < plain["estimators"]["ekf"]["nees_mean"]
    fitted = cli("replay", str(stream), "--estimators", "ekf", "--noise", "fit")
    assert fitted.returncode == 0, fitted.stderr
    assert "noise fit against truth: 24 odometry increments" in fitted.stdout
    assert "replaying with --odometry-noise-scale" in fitted.stdout and "estimator" in fitted.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--odometry-noise-scale", "0"), "argument --odometry-noise-scale: must be > 0, got 0"),
        (("--sensor-noise-scale", "inf"), "--sensor-noise-scale: sensor_noise_scale must be a finite number > 0"),
        (("--sensor-noise-scale", "x"), "argument --sensor-noise-scale: invalid float value: 'x'"),
        (("--noise", "fit", "--odometry-noise-scale", "2"), "--noise fit fits the scale; give one or the other"),
    ],
)
def test_cli_bad_noise_options(args: tuple[str, ...], message: str) -> None:
    result = cli("replay", "square", *args)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and message in result.stderr


def test_cli_noise_fit_refuses_stdin() -> None:
    result = cli("replay", "-", "--noise", "fit", stdin="")
    assert result.returncode == 2 and "not stdin" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_the_fit_pairs_each_robots_increments_with_its_own_previous_pose() -> None:
    """Several robots interleave their poses: pairing each increment with the previous index (another robot's pose)
    made ``--noise fit --robot all`` on MRCLAM fail with a ValueError (the start poses have no increment)."""
    steps, truth = _steps(WORLDS["meet"].events())
    robots = {s.robot for s in steps}
    fit = fit_noise(steps, truth)
    assert len(robots) >= 2 and fit.increments == len(steps) - len(robots)
    assert fit.odometry_scale == pytest.approx(1.0, abs=0.2)
    assert fit.horizon_scales and all(0.5 < scale < 2.0 for scale in fit.horizon_scales.values())
