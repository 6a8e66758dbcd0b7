"""UTIAS MRCLAM (multi-robot cooperative localization and mapping) -> stream v1, one robot at a time (all five
robots in one stream: :mod:`online_slam.importers.mrclam_robots`).

- Poses at the robot's landmark-measurement times; rows sharing a timestamp (one camera image) share a pose.
- Odometry between poses is integrated exactly from the piecewise-constant (v, w) commands (each command holds
  from its own timestamp to the next; arcs for w != 0), so long stretches without observations become one
  increment (no high-rate steps to merge).
- Barcodes are mapped through ``Barcodes.dat``; sightings of other robots and unknown barcodes are dropped and
  counted in the header. Nothing is cleaned with ground truth.
- Start pose: Vicon ground truth interpolated at the first pose time, with a small prior. Truth interpolated at
  pose times where Vicon covers them; landmark truth from ``Landmark_Groundtruth.dat``.

Noise model (``MrclamNoise``): per-increment variances ``var = a * dt + b * |s| + c * s^2 + floor`` with dt
the elapsed time, s the commanded path length (x, y) or turned angle (theta), of a perturbation at the end of the
increment (forward and lateral along the axes of the pose it reaches, as GTSAM's between factor has it; written
to the stream as a full covariance in the earlier pose's frame, see :func:`increment_covariances`); range and
bearing sigmas, the range's optionally growing with the measured range (``--noise fit`` finds 0.011 m + 0.044 m
per metre on Dataset 6; the default stays a constant 0.178 m: the growing one helps all five robots together,
batch 0.117 -> 0.106 m, but costs the EKF on robots 3 and 4 alone, see benchmarks/RESULTS.md). The end-frame
axes are chosen because they fit Dataset 6's Vicon data better than the earlier pose's axes. The default
coefficients are maximum-likelihood fits against Vicon over Dataset 6; the floor keeps 1-ms-apart poses well
conditioned. The data choose the form per axis: forward and lateral variances grow with the
squared path, the heading variance with the angle turned (a random walk in the angle). An earlier squared-turn
heading term is not used: it predicted far too wide a heading after long turns, which let association pair a
cluster of tubes with another cluster a large turn away. :mod:`online_slam.importers.mrclam_noise` repeats the fit
on a folder (``--noise fit``). The figures behind these choices are in benchmarks/RESULTS.md ("MRCLAM Dataset 6").
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from online_slam.errors import InputError
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, rotation
from online_slam.importers._lines import numbered_lines, numbers
from online_slam.sources.events import Event, Header, LandmarkTruth, Observation, Odometry, Start, Truth


@dataclass(frozen=True)
class MrclamNoise:
    """Noise model of the MRCLAM conversion."""

    x_per_s: float = 2.9e-5
    """Forward variance per second elapsed, m^2/s."""
    x_per_m: float = 0.0
    """Forward variance per metre of commanded path, m^2/m."""
    x_per_m2: float = 0.019
    """Forward variance per squared metre of commanded path."""
    y_per_s: float = 4.7e-7
    """Lateral variance per second, m^2/s."""
    y_per_m: float = 0.0
    """Lateral variance per metre of commanded path, m^2/m."""
    y_per_m2: float = 0.0011
    """Lateral variance per squared metre of commanded path."""
    theta_per_s: float = 3.0e-4
    """Heading variance per second, rad^2/s."""
    theta_per_rad: float = 0.020
    """Heading variance per radian of commanded turn, rad^2/rad (a random walk in the angle turned)."""
    theta_per_rad2: float = 0.0
    """Heading variance per squared radian of commanded turn."""
    floor: float = 1e-6
    """Added to every variance."""
    range_sigma: float = 0.178
    """Range standard deviation at zero range, m (the sigma of a sighting is this plus ``range_sigma_per_m``
    times its measured range)."""
    range_sigma_per_m: float = 0.0
    """Growth of the range standard deviation per metre of measured range, m/m."""
    bearing_sigma: float = 0.0125
    """Bearing standard deviation, rad."""
    start_sigma: float = 0.01
    """Standard deviation of the start prior (x, y in m, theta in rad)."""


def sighting_sigma(noise: MrclamNoise, measured_range: float) -> tuple[float, float]:
    """Range and bearing standard deviations of a sighting at its measured range (m, rad)."""
    return (noise.range_sigma + noise.range_sigma_per_m * float(measured_range), noise.bearing_sigma)


def _table(path: Path, columns: tuple[str, ...]) -> np.ndarray:
    rows = [numbers(str(path), number, fields, columns) for number, fields in numbered_lines(path)]
    if not rows:
        raise InputError(str(path), 0, "", "no data rows")
    return np.array(rows)


@dataclass(frozen=True)
class Pieces:
    """Piecewise-constant commands integrated exactly between breakpoints (every command and sample time)."""

    at: np.ndarray
    """Breakpoint index of each sample time, shape (N,)."""
    dt: np.ndarray
    """Duration of each piece, shape (B - 1,)."""
    speed: np.ndarray
    """Commanded speed over each piece, shape (B - 1,)."""
    turn: np.ndarray
    """Commanded turn over each piece (signed), shape (B - 1,)."""
    poses: np.ndarray
    """Pose at each breakpoint relative to the state at times[0], shape (B, 3)."""


def pieces(commands: np.ndarray, times: np.ndarray) -> Pieces:
    """Exact unicycle integration of piecewise-constant commands, from times[0] to times[-1] (sorted).

    Args:
        commands: (t, v, w) rows sorted by t, shape (C, 3).
        times: Sample times, shape (N,).
    """
    t_cmd, v, w = commands[:, 0], commands[:, 1], commands[:, 2]
    # Breakpoints: every command time and every sample time, from times[0] on.
    grid = np.unique(np.concatenate([t_cmd[(t_cmd > times[0]) & (t_cmd < times[-1])], times]))
    k = np.searchsorted(t_cmd, grid[:-1], side="right") - 1  # command in force on [grid[i], grid[i+1])
    vi = np.where(k >= 0, v[np.maximum(k, 0)], 0.0)
    wi = np.where(k >= 0, w[np.maximum(k, 0)], 0.0)
    dt = np.diff(grid)
    dth = wi * dt
    heading = np.concatenate([[0.0], np.cumsum(dth)])
    h0 = heading[:-1]
    small = np.abs(wi) < 1e-9
    safe_w = np.where(small, 1.0, wi)
    # Displacement over each piece in the world frame of times[0]: exact arc.
    dx = np.where(small, vi * dt * np.cos(h0), (vi / safe_w) * (np.sin(h0 + dth) - np.sin(h0)))
    dy = np.where(small, vi * dt * np.sin(h0), (vi / safe_w) * (np.cos(h0) - np.cos(h0 + dth)))
    x = np.concatenate([[0.0], np.cumsum(dx)])
    y = np.concatenate([[0.0], np.cumsum(dy)])
    return Pieces(np.searchsorted(grid, times), dt, vi, dth, np.stack([x, y, heading], -1))


def _dead_reckoning(commands: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact unicycle integration of piecewise-constant commands (:func:`pieces`), sampled at (sorted) times.

    Args:
        commands: (t, v, w) rows sorted by t, shape (C, 3).
        times: Sample times, shape (N,).

    Returns:
        (poses relative to the state at times[0], shape (N, 3); commanded path length and |turn| accumulated
        since times[0], each shape (N,)).
    """
    p = pieces(commands, times)
    path = np.concatenate([[0.0], np.cumsum(np.abs(p.speed) * p.dt)])
    turn = np.concatenate([[0.0], np.cumsum(np.abs(p.turn))])
    return p.poses[p.at], path[p.at], turn[p.at]


def _interpolate_truth(gt: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vicon poses linearly interpolated at times (heading unwrapped first); mask of covered times."""
    inside = (times >= gt[0, 0]) & (times <= gt[-1, 0])
    theta = np.unwrap(gt[:, 3])
    poses = np.stack(
        [
            np.interp(times, gt[:, 0], gt[:, 1]),
            np.interp(times, gt[:, 0], gt[:, 2]),
            wrap(np.interp(times, gt[:, 0], theta)),
        ],
        -1,
    )
    return poses, inside


@dataclass(frozen=True)
class RobotData:
    """One robot's raw tables, its landmark sightings selected and sorted by time."""

    odometry: np.ndarray
    """Velocity commands (t, v, w), sorted by t, shape (C, 3)."""
    measurements: np.ndarray
    """Landmark sightings (t, barcode, range, bearing), sorted by t (stable), shape (N, 4)."""
    subjects: np.ndarray
    """Landmark subject number of each sighting, shape (N,)."""
    times: np.ndarray
    """Distinct sighting times: the pose times, shape (P,)."""
    truth: np.ndarray
    """Vicon poses (t, x, y, theta), shape (G, 4)."""
    dropped_robots: int
    """Sightings of other robots (dropped when the robot is converted alone)."""
    dropped_unknown: int
    """Sightings of barcodes not in ``Barcodes.dat``, dropped."""
    robot_rows: np.ndarray
    """Sightings of other robots (t, barcode, range, bearing), sorted by t (stable), shape (M, 4)."""
    robots_seen: np.ndarray
    """The robot (subject 1..5) each of ``robot_rows`` sees, shape (M,)."""
    dropped_self: int
    """Sightings of the robot's own barcode, dropped."""


SWAPPED_SUBJECTS = {"MRCLAM_Dataset1": (11, 17)}
"""Folders whose ``Barcodes.dat`` gives two subjects each other's barcode, by folder name (as the MRCLAM site's
archives unpack): Dataset 1 has subjects 11 and 17 swapped (the anchor, Brossard et al.'s ``esde``, swaps them
back). Not checked on data here: only Dataset 6 is at hand."""


def subjects_of_barcodes(root: Path) -> dict[int, int]:
    """Subject of each barcode, from ``Barcodes.dat`` (with a known swap of the folder's undone)."""
    barcodes = _table(root / "Barcodes.dat", ("subject", "barcode"))
    subject_of = {int(b): int(s) for s, b in barcodes}
    swapped = SWAPPED_SUBJECTS.get(root.resolve().name)
    if swapped is not None:
        a, b = swapped
        subject_of = {code: {a: b, b: a}.get(subject, subject) for code, subject in subject_of.items()}
    return subject_of


def load_robot(root: Path, robot: int) -> RobotData:
    """Read one robot's odometry, measurements and Vicon truth; landmark sightings apart from robot sightings."""
    subject_of = subjects_of_barcodes(root)
    odometry = _table(root / f"Robot{robot}_Odometry.dat", ("time", "v", "w"))
    measurements = _table(root / f"Robot{robot}_Measurement.dat", ("time", "barcode", "range", "bearing"))
    truth = _table(root / f"Robot{robot}_Groundtruth.dat", ("time", "x", "y", "theta"))
    subjects = np.array([subject_of.get(int(b), -1) for b in measurements[:, 1]])
    is_landmark = subjects >= 6
    kept, kept_subjects = measurements[is_landmark], subjects[is_landmark]
    order = np.argsort(kept[:, 0], kind="stable")
    is_other = (subjects >= 1) & (subjects <= 5) & (subjects != robot)
    others, others_seen = measurements[is_other], subjects[is_other]
    by_time = np.argsort(others[:, 0], kind="stable")
    return RobotData(
        odometry=odometry[np.argsort(odometry[:, 0], kind="stable")],
        measurements=kept[order],
        subjects=kept_subjects[order],
        times=np.unique(kept[:, 0]),
        truth=truth,
        dropped_robots=int(np.sum((subjects >= 1) & (subjects <= 5))),
        dropped_unknown=int(np.sum(subjects < 0)),
        robot_rows=others[by_time],
        robots_seen=others_seen[by_time],
        dropped_self=int(np.sum(subjects == robot)),
    )


def increment_covariances(increments: np.ndarray, variances: np.ndarray) -> np.ndarray:
    """Covariances of the increments in the stream's ``[dx, dy, dtheta]`` (the earlier pose's frame).

    The fitted variances are those of a perturbation at the end of the increment, ``d = d_measured * Exp(e)``,
    ``e ~ N(0, diag(variances))`` (GTSAM's between factor, where the fit was made): forward and lateral noise
    along the axes of the pose the increment reaches. To first order ``d ~ [t + R(theta) e_xy, theta + e_theta]``,
    so the translation block is rotated by the increment's turn: after a quarter turn the large forward variance
    lies across the earlier pose's x axis.

    Args:
        increments: ``[dx, dy, dtheta]``, shape (K, 3).
        variances: Diagonal variances ``[forward, lateral, heading]``, shape (K, 3).

    Returns:
        Covariances, shape (K, 3, 3).
    """
    R = rotation(increments[:, 2])
    cov = np.zeros((len(increments), 3, 3))
    cov[:, :2, :2] = np.einsum("kij,kj,klj->kil", R, variances[:, :2], R)
    cov[:, 2, 2] = variances[:, 2]
    return 0.5 * (cov + np.swapaxes(cov, 1, 2))


def odometry_increments(commands: np.ndarray, times: np.ndarray, cfg: MrclamNoise) -> tuple[np.ndarray, np.ndarray]:
    """The commanded increments between poses at ``times`` and their covariances (the noise model).

    Args:
        commands: Velocity commands (t, v, w), sorted by t, shape (C, 3).
        times: Pose times, sorted, shape (P,).
        cfg: The noise model.

    Returns:
        (increments ``[dx, dy, dtheta]`` in the earlier pose's frame, shape (P - 1, 3); covariances, shape
        (P - 1, 3, 3)).
    """
    poses, path, turn = _dead_reckoning(commands, times)
    increments = between(poses[:-1], poses[1:])
    dt, ds, da = np.diff(times), np.diff(path), np.diff(turn)
    variances = np.stack(
        [
            cfg.x_per_s * dt + cfg.x_per_m * np.abs(ds) + cfg.x_per_m2 * ds**2 + cfg.floor,
            cfg.y_per_s * dt + cfg.y_per_m * np.abs(ds) + cfg.y_per_m2 * ds**2 + cfg.floor,
            cfg.theta_per_s * dt + cfg.theta_per_rad * np.abs(da) + cfg.theta_per_rad2 * da**2 + cfg.floor,
        ],
        -1,
    )
    return increments, increment_covariances(increments, variances)


def read_mrclam(folder: str | Path, robot: int, noise: MrclamNoise | None = None) -> Iterator[Event]:
    """Stream one MRCLAM robot as events.

    Args:
        folder: The dataset folder (``Barcodes.dat``, ``RobotN_*.dat``, ``Landmark_Groundtruth.dat``).
        robot: Robot number, 1..5.
        noise: Noise model (defaults: fitted on Dataset 6).

    Yields:
        Stream-v1 events.
    """
    root = Path(folder)
    cfg = noise or MrclamNoise()
    if not 1 <= robot <= 5:
        raise InputError(str(root), 0, "robot", f"expected a robot number 1..5, got {robot}")
    data = load_robot(root, robot)
    kept, kept_subjects, times, truth = data.measurements, data.subjects, data.times, data.truth
    landmarks = _table(root / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std"))
    increments, covariances = odometry_increments(data.odometry, times, cfg)
    true_poses, covered = _interpolate_truth(truth, times)
    yield Header(
        name=f"MRCLAM Dataset6 robot {robot}",
        meta={
            "converted_from": str(root.name),
            "robot": robot,
            "poses": int(len(times)),
            "landmark_observations": int(len(kept)),
            "dropped_robot_observations": data.dropped_robots,
            "dropped_unknown_barcodes": data.dropped_unknown,
            "noise": cfg.__dict__,
        },
    )
    start = true_poses[0]
    yield Start(t=float(times[0]), pose=tuple(map(float, start)), sigma=(cfg.start_sigma,) * 3)
    for subject, x, y, _, _ in landmarks:
        yield LandmarkTruth(int(subject), (float(x), float(y)))
    bounds = np.searchsorted(kept[:, 0], np.r_[times, np.inf])
    for k, t in enumerate(times):
        if k > 0:
            yield Odometry(
                t=float(t),
                delta=tuple(map(float, increments[k - 1])),
                cov=tuple(tuple(map(float, row)) for row in covariances[k - 1]),
            )
        if covered[k]:
            yield Truth(t=float(t), pose=tuple(map(float, true_poses[k])))
        for row, subject in zip(kept[bounds[k] : bounds[k + 1]], kept_subjects[bounds[k] : bounds[k + 1]]):
            yield Observation(
                t=float(t),
                landmark=int(subject),
                range=float(row[2]),
                bearing=float(row[3]),
                sigma=sighting_sigma(cfg, row[2]),
            )
