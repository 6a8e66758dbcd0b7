"""The raw Victoria Park importer: kinematics, laser geometry and GPS truth on a simulated log; the real log."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA, needs_data

from online_slam.geometry.se2 import compose
from online_slam.importers.acfr import GPS_ANTENNA
from online_slam.importers.acfr.reader import AcfrNoise, AcfrVehicle, read_acfr
from online_slam.importers.registry import detect as detect_format
from online_slam.models.fix import fixed_point
from online_slam.models.range_bearing import range_bearing
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources.events import Observation, Odometry, Start, Truth
from online_slam.sources.stream import read_stream, write_stream

VICTORIA_RAW = SHARED_DATA / "victoria_park_acfr_ascii"
CAR = AcfrVehicle()


def _simulate(folder: Path, seconds: float = 30.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """A car log as the ACFR files have it: (input times, true rear-axle poses at them, trees, trees seen in at
    least three scans)."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, seconds, 0.025) + 0.973
    steer = 0.25 * np.sin(t / 3.0)
    v_c = 2.0 + 0.5 * np.sin(t / 5.0)
    speed = v_c * (1.0 - np.tan(steer) * CAR.encoder_offset / CAR.wheelbase)  # what the rear-left encoder reads
    poses = [np.zeros(3)]
    for k in range(len(t) - 1):  # exact arcs, input k held over [t_k, t_k+1)
        dt, w = t[k + 1] - t[k], v_c[k] * np.tan(steer[k]) / CAR.wheelbase
        dx, dy = v_c[k] / w * np.sin(w * dt), v_c[k] / w * (1 - np.cos(w * dt))
        poses.append(compose(poses[-1], np.array([dx, dy, w * dt])))
    poses = np.array(poses)
    trees = rng.uniform(-40, 80, (80, 2))
    rows, seen_in = [], np.zeros(len(trees), dtype=int)
    for k in range(0, len(t), 8):  # a scan every 0.2 s, at an input time
        laser = compose(poses[k], np.array([CAR.laser_x, CAR.laser_y, 0.0]))
        z = range_bearing(np.broadcast_to(laser, (len(trees), 3)), trees)
        seen = (z[:, 0] > 3.5) & (z[:, 0] < 24.0) & (np.abs(z[:, 1]) < 1.4)
        rows += [(t[k], r, b + math.pi / 2, 0.3) for r, b in z[seen]]
        seen_in += seen
    np.savetxt(folder / "inputs.dat", np.c_[t, speed, steer], fmt="%.10f")
    np.savetxt(folder / "measurements.dat", np.array(rows), fmt="%.10f")
    gps_t = np.arange(0.0, seconds, 0.2)
    at = np.clip(np.searchsorted(t, gps_t), 0, len(t) - 1)
    antenna = fixed_point(poses[at], GPS_ANTENNA)  # GPS is of the antenna, ahead of the rear axle
    np.savetxt(folder / "gps.dat", np.c_[t[at], 10 + antenna[:, 0], -5 + antenna[:, 1]], fmt="%.10f")
    return t, poses, trees, int(np.sum(seen_in >= 3))


def test_simulated_log_converts_exactly(tmp_path: Path) -> None:
    t, poses, trees, _ = _simulate(tmp_path)
    assert detect_format(tmp_path) == "acfr"
    events = list(read_acfr(tmp_path))
    pose, at = None, {}
    for event in events:
        if isinstance(event, Start):
            pose = np.array(event.pose)
            at[event.t] = pose
        elif isinstance(event, Odometry):
            pose = compose(pose, np.array(event.delta))
            at[event.t] = pose
    # dead reckoning from the stream's increments is the true rear-axle path (same zero-order hold)
    times = np.array(sorted(at))
    k = np.clip(np.searchsorted(t, times - 1e-9), 0, len(t) - 1)
    on_input = np.abs(t[k] - times) < 1e-9  # scan times (fillers between scans fall inside a sample)
    times, k = times[on_input], k[on_input]
    assert len(times) > 100
    start = next(e for e in events if isinstance(e, Start)).pose  # in the GPS frame: offset by (10, -5) here
    np.testing.assert_allclose(start, (10.0, -5.0, 0.0), atol=2e-3)
    relative = np.array([compose(-np.array([10.0, -5.0, 0.0]) * (1, 1, 0), at[s] - (0, 0, start[2])) for s in times])
    np.testing.assert_allclose(relative[:, :2], poses[k, :2], atol=0.05)
    # every sighting is the range and bearing of a tree from the rear axle (laser offset undone)
    at = {s: compose(np.zeros(3), poses[np.argmin(np.abs(t - s))]) for s in at}
    sightings = [e for e in events if isinstance(e, Observation)]
    assert sightings and all(e.landmark is None for e in sightings)
    for event in sightings[::7]:
        z = range_bearing(np.broadcast_to(at[event.t], (len(trees), 3)), trees)
        d = np.hypot(z[:, 0] - event.range, np.angle(np.exp(1j * (z[:, 1] - event.bearing))) * event.range)
        assert d.min() < 1e-6
        assert np.all(np.linalg.eigvalsh(np.array(event.cov)) > 0)
    # GPS truth: position only, of the antenna, in its own frame (offset by (10, -5) here)
    truth = [e for e in events if isinstance(e, Truth)]
    assert truth and all(math.isnan(e.pose[2]) and e.offset == GPS_ANTENNA for e in truth)
    for event in truth[::10]:
        np.testing.assert_allclose(np.array(event.pose[:2]) - (10, -5), fixed_point(at[event.t], GPS_ANTENNA), atol=0.2)


def test_limits_drop_detections_and_stream_round_trips(tmp_path: Path) -> None:
    _simulate(tmp_path, seconds=10.0)
    strict = list(read_acfr(tmp_path, AcfrNoise(max_range=10.0)))
    header = strict[0]
    assert header.meta["dropped_by_limits"] > 0
    assert all(e.range < 10.0 + CAR.laser_x + 1 for e in strict if isinstance(e, Observation))
    path = tmp_path / "vp.jsonl"
    write_stream(path, read_acfr(tmp_path))
    again = list(read_stream(path))
    assert [type(e) for e in again] == [type(e) for e in read_acfr(tmp_path)]
    assert sum(isinstance(e, Truth) for e in again) > 0


@pytest.mark.slow
def test_simulated_log_replays_without_ids(tmp_path: Path) -> None:
    *_, trees_seen = _simulate(tmp_path)
    results = replay(tmp_path, ReplayConfig(estimators=("ekf", "smoother", "batch")))
    assert results.alignment == "anchor"  # position-only truth is aligned rigidly anyway
    for name in ("ekf", "smoother", "batch"):
        assert results.estimators[name].final_rmse_m < 0.3, name
        mapped = len(results.estimates[name].landmark_ids)
        assert 0.8 * trees_seen <= mapped <= 1.1 * trees_seen, (name, mapped)


@pytest.mark.slow
@needs_data("victoria_park_acfr_ascii")
def test_real_victoria_park_log_first_minutes() -> None:
    header = next(iter(read_acfr(VICTORIA_RAW)))
    assert header.meta["detections"] == 52974 and header.meta["scans"] <= 7230
    events = list(itertools.islice(read_acfr(VICTORIA_RAW), 4500))  # the first 145 s: ekf 1.01 m, smoother 1.00 m
    results = replay(events, ReplayConfig(estimators=("ekf", "smoother")), name="vp")
    odometry = results.odometry.rmse_m
    for name in ("ekf", "smoother"):
        assert results.estimators[name].final_rmse_m < 0.25 * odometry, (name, odometry)
