"""Dataset importers: GTSAM/iSAM text, g2o (both ways), MRCLAM; malformed files; the real datasets when present."""

from __future__ import annotations

import io
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA, needs_data
from inprocess import run_cli

from online_slam.errors import InputError
from online_slam.importers import open_dataset
from online_slam.importers._lines import numbered_lines, numbers, table
from online_slam.importers.g2o.reader import read_g2o, write_g2o
from online_slam.importers.mrclam.noise import (
    WINDOWS_S,
    IncrementErrors,
    fit_camera,
    fit_command_calibration,
    fit_increment_terms,
    fit_mrclam_noise,
    fit_robot_barcode,
    fit_sighting_correlation,
    fit_sighting_sigma,
    increment_errors,
    window_errors,
)
from online_slam.importers.mrclam.reader import (
    MrclamNoise,
    RobotData,
    _dead_reckoning,
    calibrated,
    heading_levers,
    model_covariances,
    odometry_increments,
)
from online_slam.importers.mrclam.sightings import (
    Camera,
    correlation,
    information_factors,
    sighting_sigmas,
    through_camera,
)
from online_slam.sources import LandmarkTruth, Observation, Odometry, Truth, read_stream, square_world, write_stream

MRCLAM = SHARED_DATA / "MRCLAM_Dataset6"
CITY = SHARED_DATA / "isam_citytrees10000_synthetic"
VICTORIA = SHARED_DATA / "gtsam_victoria_park" / "victoria_park.txt"


def events_of(kind: type, events: list) -> list:
    return [e for e in events if isinstance(e, kind)]


def test_gtsam_convention_victoria_style(tmp_path: Path) -> None:
    path = tmp_path / "vp.txt"
    path.write_text(
        "ODOMETRY 0 1 1.0 0.0 0.1 0.0001 0 0 4e-06 0 4e-06\n"
        "LANDMARK 1 2 3.0 4.0 0.4 0 0.4\n"
        "ODOMETRY 1 3 0.5 0.01 -0.02 0.0001 0 0 4e-06 0 4e-06\n"  # id 2 went to the landmark
        "LANDMARK 3 2 2.0 -1.0 0.4 0 0.4\n"
    )
    events = list(open_dataset(path))
    odo, obs = events_of(Odometry, events), events_of(Observation, events)
    assert [o.t for o in odo] == [1.0, 2.0]
    assert np.allclose(odo[0].covariance, np.diag([1e-4, 4e-6, 4e-6]))
    assert obs[0].range == pytest.approx(5.0) and obs[0].bearing == pytest.approx(np.arctan2(4, 3))
    assert np.allclose(obs[0].covariance, np.diag([0.4, 0.04]))  # range sigma sqrt(0.4), bearing sqrt(0.4/10)
    assert obs[1].t == 2.0 and obs[1].landmark == 2


def test_isam_convention_with_truth(tmp_path: Path) -> None:
    noisy, truth = tmp_path / "c.txt", tmp_path / "c_gt.txt"
    noisy.write_text("EDGE2 0 1 1.1 0 0 50 0 0 50 0 100\nLANDMARK 1 0 3.0 0.0 10 0 10\n")
    truth.write_text("EDGE2 0 1 1.0 0 0 50 0 0 50 0 100\nLANDMARK 1 0 3.0 0.0 10 0 10\n")
    events = list(open_dataset(noisy, truth=truth))
    odo, obs = events_of(Odometry, events)[0], events_of(Observation, events)[0]
    assert np.allclose(odo.covariance, np.diag([1 / 2500, 1 / 2500, 1 / 10000]))
    assert np.allclose(obs.covariance, np.diag([0.01, 0.01 / 9]))  # sigma 0.1 m carried to range and bearing at 3 m
    assert events_of(Truth, events)[-1].pose == (1.0, 0.0, 0.0)
    assert events_of(LandmarkTruth, events)[0].position == pytest.approx((4.0, 0.0))


@pytest.mark.parametrize(
    ("content", "where"),
    [
        ("ODOMETRY 0 1 1.0 0.0\n", ":1: expected 11 columns"),
        ("EDGE2 0 1 1 0 0 50 0 0 50 0 100\nFOO 1 2\n", ":2: tag: unknown line type"),
        ("EDGE2 0 1 1 0 zero 50 0 0 50 0 100\n", ":1: dtheta: expected a number"),
        ("EDGE2 0 1 1 0 0 50 0 0 50 0 100\nLANDMARK 0 1 2 2 10 0 10\n", ":2: i: sighting from pose 0"),
    ],
)
def test_malformed_dataset_lines_are_one_line_errors(tmp_path: Path, content: str, where: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(content)
    with pytest.raises(InputError) as info:
        list(open_dataset(path))
    assert f"{path}{where}" in str(info.value)
    done = run_cli("convert", "gtsam", str(path), "-o", str(tmp_path / "o.jsonl"))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and where in done.stderr


def test_g2o_round_trip_of_the_square_world(tmp_path: Path) -> None:
    stream = list(square_world())
    g2o = tmp_path / "square.g2o"
    write_g2o(g2o, stream)
    back = list(read_g2o(g2o))
    a, b = events_of(Odometry, stream), events_of(Odometry, back)
    assert len(a) == len(b) == 24
    assert all(
        np.allclose(x.delta, y.delta, atol=1e-12) and np.allclose(x.covariance, y.covariance, rtol=1e-9)
        for x, y in zip(a, b)
    )
    a, b = events_of(Observation, stream), events_of(Observation, back)
    assert len(a) == len(b) == 95
    for x, y in zip(a, b):
        assert abs(x.range - y.range) < 1e-12 and abs(np.angle(np.exp(1j * (x.bearing - y.bearing)))) < 1e-12
        assert np.allclose(x.covariance, y.covariance, rtol=1e-9, atol=1e-15) and x.t == y.t
    buffer = io.StringIO()
    write_stream(buffer, back)  # what g2o gives back is a valid stream


def test_g2o_rejects_loop_closures(tmp_path: Path) -> None:
    path = tmp_path / "loop.g2o"
    path.write_text("EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\nEDGE_SE2 0 2 2 0 0 1 0 0 1 0 1\n")
    with pytest.raises(InputError, match=r"loop.g2o:3: j: .*loop closures"):
        list(read_g2o(path))


def test_exact_integration_of_piecewise_constant_commands() -> None:
    commands = np.array([[0.0, 1.0, 0.5], [2.0, 0.5, 0.0], [3.0, 0.0, -1.0]])
    poses, path, turn = _dead_reckoning(commands, np.array([0.0, 1.0, 2.5, 4.0]))
    # first second: arc of radius 2 through 0.5 rad
    assert np.allclose(poses[1], [2 * np.sin(0.5), 2 * (1 - np.cos(0.5)), 0.5])
    end_of_arc = np.array([2 * np.sin(1.0), 2 * (1 - np.cos(1.0)), 1.0])
    straight = end_of_arc + [0.25 * np.cos(1.0), 0.25 * np.sin(1.0), 0.0]  # 0.5 s at 0.5 m/s
    assert np.allclose(poses[2], straight)
    assert np.allclose(path, [0, 1.0, 2.25, 2.5]) and np.allclose(turn, [0, 0.5, 1.0, 2.0])


needs_mrclam = needs_data("MRCLAM_Dataset6")


@needs_mrclam
def test_mrclam_robot_counts_match_the_provenance() -> None:
    events = list(open_dataset(MRCLAM, robot=1))
    header = events[0]
    assert header.meta["poses"] == 1012 and header.meta["landmark_observations"] == 1534
    assert header.meta["dropped_robot_observations"] == 407 and header.meta["dropped_unknown_barcodes"] == 1
    assert header.meta["dropped_own_barcode"] == 0
    assert len(events_of(LandmarkTruth, events)) == 15 and len(events_of(Observation, events)) == 1534


@pytest.mark.slow
@needs_mrclam
def test_mrclam_batch_equals_gtsam_from_the_same_initial_values() -> None:
    pytest.importorskip("gtsam", reason="the 'peers' extra (gtsam) is not installed")
    from online_slam import gtsam_peer
    from online_slam.estimators import BatchEstimator, EkfSlam
    from online_slam.frontend import FrontEnd

    fe, batch, ekf = FrontEnd(), BatchEstimator(), EkfSlam()
    for step in fe.steps(open_dataset(MRCLAM, robot=4, half="first")):  # half the work of the whole run
        batch.step(step)
        ekf.step(step)
    start = ekf.finish()
    ours = batch.finish(start)
    graph = batch.log.graph()
    order = [start.landmark_ids.index(lid) for lid in batch.log.landmark_ids]
    peer = gtsam_peer.levenberg_marquardt(graph, start.poses, start.landmarks[order], exact=True, tight=True)
    assert ours.info["converged"]
    assert np.max(np.linalg.norm(ours.poses[:, :2] - peer.poses[:, :2], axis=1)) <= 1e-4


@pytest.mark.slow
@needs_data("isam_citytrees10000_synthetic")
def test_citytrees_truth_is_the_noise_free_twin() -> None:
    events = list(open_dataset(CITY / "cityTrees10000.txt", truth=CITY / "cityTrees10000_groundtruth.txt"))
    assert len(events_of(Truth, events)) == 10_000 and len(events_of(LandmarkTruth, events)) == 100
    assert len(events_of(Observation, events)) == 4443


@needs_data("gtsam_victoria_park/victoria_park.txt")
def test_victoria_park_shape() -> None:
    events = list(open_dataset(VICTORIA))
    assert len(events_of(Odometry, events)) == 6968 and len(events_of(Observation, events)) == 3640
    assert len({e.landmark for e in events_of(Observation, events)}) == 151


def test_shipped_streams_read(tmp_path: Path) -> None:
    folder = Path(__file__).resolve().parents[1] / "replay"
    for path in folder.glob("*.jsonl*"):
        assert sum(1 for _ in read_stream(path)) > 10


def _increments(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Piecewise-constant (t, v, w) commands at 5 Hz and pose times every 1-20 commands."""
    t = np.arange(n) * 0.2
    turning = rng.random(n) < 0.5  # half of the commands go straight, so that time and turn are told apart
    commands = np.stack([t, rng.uniform(0.0, 0.2, n), np.where(turning, rng.uniform(-1.0, 1.0, n), 0.0)], -1)
    at = np.concatenate([[0], np.cumsum(rng.integers(1, 20, n // 10))])
    return commands, t[at[at < n]], t


def test_heading_noise_along_the_commands_is_the_propagated_covariance() -> None:
    """One increment of two pieces: straight 1 m, then 1 m more. Heading noise q accrued over the first piece
    turns the second piece's metre: the end's lateral variance gains q * 1^2 and its cross term q * 1."""
    commands = np.array([[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    per_s, per_rad = heading_levers(commands, np.array([0.0, 2.0]))
    # the first second's unit heading variance: lever [J r; 1] = [0, 1, 1]; the second's: [0, 0, 1]
    assert per_s[0] == pytest.approx(np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.0, 1.0, 2.0]]), abs=1e-12)
    assert per_rad[0] == pytest.approx(np.zeros((3, 3)), abs=1e-12)  # no turn
    noise = MrclamNoise(command_lag_s=0.0, speed_scale=1.0, turn_scale=1.0)
    _, cov = odometry_increments(commands, np.array([0.0, 2.0]), noise)
    assert cov[0, 1, 2] == pytest.approx(noise.theta_per_s * 1.0, rel=1e-9)
    assert cov[0, 2, 2] == pytest.approx(2.0 * noise.theta_per_s + noise.floor, rel=1e-9)


def test_heading_noise_along_the_commands_matches_monte_carlo_on_a_turning_path() -> None:
    rng = np.random.default_rng(5)
    commands = np.stack([np.arange(10) * 0.5, np.full(10, 0.3), np.linspace(-0.6, 0.6, 10)], -1)
    times = np.array([0.0, 5.0])
    per_s, per_rad = heading_levers(commands, times)
    q = 0.002  # heading variance per second, accrued as a random walk along the commands
    fine = 200  # sub-steps per command
    dt = 0.5 / fine
    w = np.repeat(commands[:, 2], fine)
    v = np.repeat(commands[:, 1], fine)
    ends = []
    for _ in range(4000):
        heading = np.cumsum(w * dt) - w * dt + np.cumsum(rng.normal(0.0, np.sqrt(q * dt), len(w)))
        x, y = np.sum(v * dt * np.cos(heading)), np.sum(v * dt * np.sin(heading))
        ends.append([x, y, heading[-1] + w[-1] * dt])
    sample = np.cov(np.array(ends).T)
    assert q * per_s[0] == pytest.approx(sample, abs=0.08 * np.max(np.abs(sample)))


def test_calibrated_commands_are_delayed_and_scaled() -> None:
    commands = np.array([[0.0, 0.2, 0.1], [1.0, 0.1, -0.3]])
    out = calibrated(commands, MrclamNoise(command_lag_s=0.25, speed_scale=0.9, turn_scale=0.8, speed_per_turn=0.0))
    assert out == pytest.approx(np.array([[0.25, 0.18, 0.08], [1.25, 0.09, -0.24]]))
    assert commands[0, 0] == 0.0  # the input is left alone
    # turning slows the robot: 0.2 * 0.9 * (1 - 1.0 * 0.1), 0.1 * 0.9 * (1 - 1.0 * 0.3); a fast turn stops it
    slowed = calibrated(commands, MrclamNoise(command_lag_s=0.25, speed_scale=0.9, turn_scale=0.8, speed_per_turn=1.0))
    assert slowed[:, 1] == pytest.approx([0.162, 0.063])
    assert calibrated(np.array([[0.0, 0.2, -1.5]]), MrclamNoise(speed_per_turn=1.0))[0, 1] == 0.0


def _robot_data(
    commands: np.ndarray, vicon: np.ndarray, sightings: np.ndarray | None = None, subjects: np.ndarray | None = None
) -> RobotData:
    """A robot's tables from commands ``(t, v, w)``, Vicon ``(t, x, y, theta)`` and landmark sightings
    ``(t, barcode, range, bearing)`` with their subjects (none by default), no robot sightings."""
    rows = np.zeros((0, 4)) if sightings is None else sightings
    return RobotData(
        odometry=commands,
        measurements=rows,
        subjects=np.zeros(0, dtype=int) if subjects is None else subjects,
        times=np.unique(rows[:, 0]) if len(rows) else vicon[:1, 0],
        truth=vicon,
        dropped_unknown=0,
        robot_rows=np.zeros((0, 4)),
        robots_seen=np.zeros(0, dtype=int),
        dropped_self=0,
    )


def test_command_calibration_recovers_lag_scales_and_the_speed_lost_turning() -> None:
    """Vicon at 100 Hz along commands carried out 0.2 s late, 5% slower, turning 10% less, and 80% of the speed
    kept per rad/s turned: the fit finds all four."""
    rng = np.random.default_rng(5)
    n = 3000
    t = np.arange(n) * 0.2
    commands = np.stack(
        [t, rng.uniform(0.05, 0.2, n), np.where(rng.random(n) < 0.5, rng.uniform(-0.5, 0.5, n), 0.0)], -1
    )
    truth_model = MrclamNoise(command_lag_s=0.2, speed_scale=0.95, turn_scale=0.9, speed_per_turn=0.8)
    vicon_t = np.arange(1.0, t[-1] - 1.0, 0.01)
    poses, _, _ = _dead_reckoning(calibrated(commands, truth_model), vicon_t)
    data = _robot_data(commands, np.column_stack([vicon_t, poses]))
    lag, speed, turn, loss = fit_command_calibration([data])
    assert lag == pytest.approx(0.2, abs=0.011)
    assert speed == pytest.approx(0.95, rel=0.01) and turn == pytest.approx(0.9, rel=0.01)
    assert loss == pytest.approx(0.8, abs=0.051)


def test_windows_make_the_increments_fit_honest_over_longer_stretches() -> None:
    """Commands carried out with white turn-rate noise and a turn-rate bias that changes every 100 s, poses every
    0.2-1 s: fitted on the pose increments alone, the model is 1.7 times too sure of the heading over 40 s
    windows; with the windows beside them, the four window spans read closer to 1, at a small cost on the
    increments."""
    rng = np.random.default_rng(7)
    n = 20_000
    t = np.arange(n) * 0.2
    commands = np.stack(
        [t, rng.uniform(0.05, 0.2, n), np.where(rng.random(n) < 0.5, rng.uniform(-0.5, 0.5, n), 0.0)], -1
    )
    carried_out = commands.copy()
    carried_out[:, 2] += np.repeat(rng.normal(0.0, 0.004, n // 500 + 1), 500)[:n] + rng.normal(0.0, 0.05, n)
    vicon, _, _ = _dead_reckoning(carried_out, t[:-1])
    at = np.cumsum(rng.integers(1, 6, n // 2))
    data = replace(_robot_data(commands, np.column_stack([t[:-1], vicon])), times=t[at[at < n - 1]])
    increments = increment_errors(data, commands)
    windows = [window_errors(data, commands, width) for width in WINDOWS_S]

    def heading_chi2(noise: MrclamNoise, part: IncrementErrors) -> float:
        cov = model_covariances(noise, part.commanded, (part.dt, part.path, part.turn), (part.per_s, part.per_rad))
        return float(np.mean(part.errors[:, 2] ** 2 / cov[:, 2, 2]))

    alone = fit_increment_terms(increments, MrclamNoise())
    beside = fit_increment_terms(increments, MrclamNoise(), windows)
    alone_chi2 = np.array([heading_chi2(alone, w) for w in windows])
    beside_chi2 = np.array([heading_chi2(beside, w) for w in windows])
    assert alone_chi2[-1] > 1.6 and beside_chi2[-1] < alone_chi2[-1] - 0.2
    assert np.all(np.abs(beside_chi2 - 1.0) < np.abs(alone_chi2 - 1.0))
    assert heading_chi2(beside, increments) > 0.85


def test_increment_terms_fit_recovers_the_terms_of_simulated_increments() -> None:
    rng = np.random.default_rng(3)
    commands, times, _ = _increments(rng, 20_000)
    truth = MrclamNoise(
        x_per_s=2e-5,
        x_per_m2=0.02,
        y_per_s=1e-6,
        y_per_m2=1e-3,
        theta_per_s=2e-4,
        theta_per_rad=0.01,
        command_lag_s=0.0,
        speed_scale=1.0,
        turn_scale=1.0,
        speed_per_turn=0.0,
    )
    increments, cov = odometry_increments(commands, times, truth)
    errors = np.einsum("kij,kj->ki", np.linalg.cholesky(cov), rng.standard_normal(increments.shape))
    poses, path, turn = _dead_reckoning(commands, times)
    per_s, per_rad = heading_levers(commands, times)
    data = IncrementErrors(errors, increments, np.diff(times), np.diff(path), np.diff(turn), per_s, per_rad)
    fitted = fit_increment_terms(data, MrclamNoise())
    for name, rel in (("x_per_m2", 0.1), ("y_per_m2", 0.15), ("theta_per_s", 0.25), ("theta_per_rad", 0.25)):
        assert getattr(fitted, name) == pytest.approx(getattr(truth, name), rel=rel), name


def test_sightings_of_one_landmark_are_widened_by_the_information_they_add() -> None:
    noise = MrclamNoise(range_correlation=(0.5, 2.0, 0.3, 30.0), bearing_correlation=(0.0, 1.0, 0.0, 1.0))
    times = np.array([0.0, 0.0, 0.2, 10.0, 10.0])
    subjects = np.array([6, 7, 6, 6, 8])
    camera = noise.cameras[0]
    sigmas = sighting_sigmas(noise, times, subjects, np.full(5, 2.0), camera)
    base = np.array([camera.range_sigma + 2.0 * camera.range_sigma_per_m, camera.bearing_sigma])
    first = [0, 1, 4]  # each landmark's first sighting keeps its sigma
    assert sigmas[first] == pytest.approx(np.tile(base, (3, 1)))
    assert sigmas[[2, 3], 1] == pytest.approx([base[1]] * 2)  # no bearing correlation: independent
    assert np.all(sigmas[[2, 3], 0] > base[0])
    assert sighting_sigmas(noise, times, subjects, np.full(5, 2.0))[0] == pytest.approx(
        [noise.range_sigma + 2.0 * noise.range_sigma_per_m, noise.bearing_sigma]
    )  # without a camera, the model's own sigmas
    assert correlation((0.5, 2.0, 0.3, 30.0), np.array([np.inf]))[0] == 0.0


def test_information_factors_add_up_to_what_correlated_sightings_tell_about_a_constant() -> None:
    """For every prefix of one landmark's sightings, the information the widened sightings carry (sum of 1 /
    factor) is exactly ``1^T C^-1 1`` of their correlation matrix C: what least squares with the full
    correlation learns about a constant. Two landmarks interleave at irregular times."""
    rng = np.random.default_rng(2)
    terms = (0.4, 1.5, 0.35, 25.0)
    times = np.sort(rng.uniform(0.0, 120.0, 160))
    subjects = rng.choice([6, 9], 160)
    factors = information_factors(times, subjects, terms)
    for subject in (6, 9):
        at = times[subjects == subject]
        c = correlation(terms, np.abs(at[:, None] - at[None, :]))
        np.fill_diagonal(c, 1.0)
        exact = [np.sum(np.linalg.inv(c[: k + 1, : k + 1])) for k in range(len(at))]
        assert np.cumsum(1.0 / factors[subjects == subject]) == pytest.approx(exact, rel=1e-6)
    # one exponential, dense: each sighting adds (1 - rho) / (1 + rho), the first-order autoregressive figure
    dense = information_factors(np.arange(0.0, 100.0, 0.2), np.zeros(500, dtype=int), (1.0 - 1e-9, 1.0, 0.0, 1.0))
    rho = np.exp(-0.2)
    assert dense[0] == 1.0 and dense[-1] == pytest.approx((1 + rho) / (1 - rho), rel=1e-4)
    # independent errors keep every sigma
    assert np.all(information_factors(times, subjects, (0.0, 1.0, 0.0, 1.0)) == 1.0)


def test_the_camera_puts_a_logged_depth_and_bearing_where_the_barcode_is() -> None:
    rows = np.array([[0.0, 11.0, 3.0, 0.3], [1.0, 12.0, 2.0, -0.5]])
    plain = through_camera(rows, Camera(1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0))
    # a logged range is the depth along the axis: the distance is depth / cos(bearing), the bearing unchanged
    assert plain[:, 2] == pytest.approx(rows[:, 2] / np.cos(rows[:, 3]))
    assert plain[:, 3] == pytest.approx(rows[:, 3]) and plain[:, :2] == pytest.approx(rows[:, :2])
    # scale 0.9, 0.1 m back, 0.05 m left, bearing scale 1.1: the point (2.6, 2.7 tan 0.33 + 0.05)
    moved = through_camera(rows[:1], Camera(0.9, -0.1, 0.05, 1.1, 0.0, 0.0, 0.0))
    x, y = 2.6, 2.7 * np.tan(0.33) + 0.05
    assert moved[0, 2:] == pytest.approx([np.hypot(x, y), np.arctan2(y, x)])
    assert through_camera(rows, None) is rows


def test_the_camera_fit_recovers_a_simulated_camera() -> None:
    """Sightings of surveyed landmarks from Vicon poses, logged as a camera (0.96 depth scale, 5 cm back, 2 cm
    left, 0.98 bearing scale) would log them with 1% range and 0.01 rad bearing noise and 2% wrong barcodes."""
    rng = np.random.default_rng(4)
    landmark_xy = {s: rng.uniform(-4.0, 4.0, 2) for s in range(6, 21)}
    n = 6000
    t = np.arange(n) * 0.1
    pose = np.column_stack([rng.uniform(-3.0, 3.0, n), rng.uniform(-3.0, 3.0, n), rng.uniform(-np.pi, np.pi, n)])
    subjects = rng.integers(6, 21, n)
    xy = np.array([landmark_xy[s] for s in subjects]) - pose[:, :2]
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    x, y = c * xy[:, 0] + s * xy[:, 1], -s * xy[:, 0] + c * xy[:, 1]
    ahead = (x > 0.8) & (np.abs(np.arctan2(y, x)) < 0.5)
    camera = Camera(0.96, -0.05, 0.02, 0.98, 0.0, 0.01, 0.01)
    depth = (x - camera.forward_m) / camera.scale  # invert the camera's placement
    bearing = np.arctan((y - camera.left_m) / (x - camera.forward_m)) / camera.bearing_scale
    depth *= 1.0 + 0.01 * rng.standard_normal(n)
    bearing += 0.01 * rng.standard_normal(n)
    wrong = rng.random(n) < 0.02
    subjects = np.where(wrong, rng.integers(6, 21, n), subjects)
    rows = np.column_stack([t, subjects, depth, bearing])[ahead]
    data = _robot_data(np.zeros((1, 3)), np.column_stack([t, pose]), rows, subjects[ahead])
    fitted = fit_camera(data, landmark_xy)
    assert fitted.scale == pytest.approx(0.96, rel=0.003) and fitted.bearing_scale == pytest.approx(0.98, rel=0.01)
    assert fitted.forward_m == pytest.approx(-0.05, abs=0.01) and fitted.left_m == pytest.approx(0.02, abs=0.01)
    assert fitted.range_sigma_per_m == pytest.approx(0.01, rel=0.2) and fitted.bearing_sigma == pytest.approx(
        0.01, rel=0.2
    )


def test_robot_barcode_fit_finds_how_much_farther_a_seen_robot_reads() -> None:
    """Robot 1 drives along y = 0 and sights robot 2, parked at (3, 1), 4 cm too far (a camera with no offset,
    exact bearings), and once robot 3, which is not in the fit: the median residual is 4 cm."""
    t = np.linspace(0.0, 10.0, 101)
    robot1 = np.column_stack([t, 0.1 * t, np.zeros_like(t), np.zeros_like(t)])
    robot2 = np.column_stack([t, np.full_like(t, 3.0), np.ones_like(t), np.zeros_like(t)])
    seen_at = t[1:-1:5]
    d = np.column_stack([3.0 - 0.1 * seen_at, np.ones_like(seen_at)])
    bearing = np.arctan2(d[:, 1], d[:, 0])
    depth = (np.hypot(d[:, 0], d[:, 1]) + 0.04) * np.cos(bearing)  # a logged range is a depth (Camera)
    rows = np.column_stack([seen_at, np.full_like(seen_at, 14), depth, bearing])
    first = replace(_robot_data(np.zeros((1, 3)), robot1), robot_rows=np.r_[rows, [[5.0, 41, 9.0, 0.0]]],
                    robots_seen=np.r_[np.full(len(rows), 2), 3])  # fmt: skip
    second = _robot_data(np.zeros((1, 3)), robot2)
    camera = Camera(1.0, 0.0, 0.0, 1.0, 0.0, 0.01, 0.01)
    assert fit_robot_barcode({1: first, 2: second}, {1: camera, 2: camera}) == pytest.approx(0.04, abs=1e-9)


def test_sighting_correlation_fit_recovers_two_time_scales() -> None:
    """Residuals of three landmarks as a sum of two Ornstein-Uhlenbeck processes and white noise, sampled at
    irregular times: the fit finds the weights and time constants."""
    rng = np.random.default_rng(11)
    times, subjects, residuals = [], [], []
    for subject in (6, 7, 8):
        t = np.cumsum(rng.exponential(0.5, 6000))
        slow = fast = 0.0
        out = []
        for gap in np.diff(t, prepend=t[0]):
            a, b = np.exp(-gap / 1.5), np.exp(-gap / 40.0)
            fast = a * fast + np.sqrt(1 - a**2) * rng.normal(0.0, np.sqrt(0.5))
            slow = b * slow + np.sqrt(1 - b**2) * rng.normal(0.0, np.sqrt(0.3))
            out.append(fast + slow + rng.normal(0.0, np.sqrt(0.2)))
        times.append(t), subjects.append(np.full(len(t), subject)), residuals.append(np.array(out))
    c1, tau1, c2, tau2 = fit_sighting_correlation(*(np.concatenate(x) for x in (times, subjects, residuals)))
    assert c1 == pytest.approx(0.5, abs=0.08) and tau1 == pytest.approx(1.5, rel=0.3)
    assert c2 == pytest.approx(0.3, abs=0.08) and tau2 == pytest.approx(40.0, rel=0.4)


def test_the_sighting_sigma_fit_recovers_a_range_dependent_sigma_beside_outliers() -> None:
    rng = np.random.default_rng(7)
    ranges = rng.uniform(0.5, 7.0, 20000)
    residuals = rng.normal(0.0, 0.02 + 0.05 * ranges)
    wrong = rng.random(20000) < 0.02
    residuals[wrong] = rng.uniform(-2.0, 2.0, wrong.sum())
    a, b = fit_sighting_sigma(residuals, ranges)
    assert a == pytest.approx(0.02, abs=0.005) and b == pytest.approx(0.05, rel=0.05)
    constant, growth = fit_sighting_sigma(rng.normal(0.0, 0.01, 5000))
    assert constant == pytest.approx(0.01, rel=0.05) and growth == 0.0


@pytest.mark.slow
@needs_mrclam
def test_mrclam_noise_fit_reproduces_the_builtin_odometry_coefficients(tmp_path: Path) -> None:
    fit = fit_mrclam_noise(MRCLAM)
    builtin = MrclamNoise()
    assert fit.increments > 8000 and fit.measurements > 15000
    names = ("x_per_s", "x_per_m2", "y_per_m2", "theta_per_s", "theta_per_rad", "command_lag_s", "speed_scale")
    for name in (*names, "turn_scale", "speed_per_turn", "robot_barcode_m"):
        assert getattr(fit.noise, name) == pytest.approx(getattr(builtin, name), rel=0.02), name
    assert fit.noise.range_correlation == pytest.approx(builtin.range_correlation, rel=0.02)
    assert fit.noise.bearing_correlation == pytest.approx(builtin.bearing_correlation, rel=0.02)
    for fitted, camera in zip(fit.noise.cameras, builtin.cameras):
        assert fitted == camera  # the built-in cameras are this fit's, to its digits
    # the robots move a quarter second late, about 4% farther than commanded going straight, and lose their
    # speed turning (a share of 1 per rad/s); one landmark's range errors 0.2 s apart correlate at about 0.55
    assert 0.2 <= fit.noise.command_lag_s <= 0.3 and 1.0 < fit.noise.speed_scale < 1.08
    assert 0.8 < fit.noise.speed_per_turn < 1.2
    assert 0.45 < float(correlation(fit.noise.range_correlation, np.array([0.2]))[0]) < 0.65
    # a logged range is a depth: placed by the camera, a sighting's range errs by about 1% of the range
    assert fit.noise.range_sigma < 0.01 and 0.005 < fit.noise.range_sigma_per_m < 0.015
    assert abs(fit.range_bias_m) < 0.01  # the cameras remove the logged ranges' 0.1-0.2 m bias
    assert max(c.range_sigma_per_m for c in fit.noise.cameras) > 1.5 * min(
        c.range_sigma_per_m for c in fit.noise.cameras
    )
    out = tmp_path / "robot2.jsonl"
    done = run_cli("convert", "mrclam", str(MRCLAM), "--robot", "2", "--refit", "-o", str(out))
    assert done.returncode == 0, done.stderr
    header = next(iter(read_stream(out)))
    assert header.meta["noise"]["range_sigma"] == pytest.approx(fit.noise.range_sigma, rel=1e-12)


def test_a_numeric_table_reads_as_line_by_line_and_names_the_line_at_fault(tmp_path: Path) -> None:
    """The fast reader (numpy's) and the line-by-line one give the same doubles; what the fast one refuses is read
    line by line for the error naming file, line and column."""
    good = tmp_path / "good.dat"
    good.write_text("# header\n#  time  v\n\n1248444175.103 \t 1.41277290\n  2.5e-3\t-0.0 \n7 1E+2\n")
    names = ("time", "v")
    line_by_line = np.array([numbers(str(good), n, fields, names) for n, fields in numbered_lines(good)])
    assert np.array_equal(table(good, names), line_by_line) and table(good, names).shape == (3, 2)
    for content, where in [
        ("# h\n1 2\n3 x\n", ":3: v: expected a number, got 'x'"),
        ("1 2\n1 nan\n", ":2: v: expected a finite number"),
        ("1 2\n1 2 3\n", ":2: expected 2 columns (time v), got 3"),
        ("1 2 # a note\n", ":1: expected 2 columns (time v), got 5"),
        ("# only a header\n", ": no data rows"),
        ("1 2\n\xff\n", ": not UTF-8 text"),
    ]:
        bad = tmp_path / "bad.dat"
        bad.write_bytes(content.encode("latin-1"))
        with pytest.raises(InputError) as info:
            table(bad, names)
        assert f"{bad}{where}" in str(info.value), str(info.value)
