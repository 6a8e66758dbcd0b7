"""UTIAS MRCLAM (multi-robot cooperative localization and mapping) -> stream v1, one robot at a time (all five
robots in one stream: :mod:`online_slam.importers.mrclam.robots`).

- Poses at the robot's landmark-measurement times; rows sharing a timestamp (one camera image) share a pose.
- Odometry between poses is integrated exactly from the piecewise-constant (v, w) commands (each command holds
  from its own timestamp to the next; arcs for w != 0), so long stretches without observations become one
  increment (no high-rate steps to merge).
- Barcodes are mapped through ``Barcodes.dat``; sightings of other robots and unknown barcodes are dropped and
  counted in the header. Nothing is cleaned with ground truth.
- Start pose: Vicon ground truth interpolated at the first pose time, with a small prior. Truth interpolated at
  pose times where Vicon covers them; landmark truth from ``Landmark_Groundtruth.dat``.

The model (``MrclamNoise``), every part fitted against Vicon over Dataset 6 by
:mod:`online_slam.importers.mrclam.noise` (``--refit`` repeats the fit on a folder; the evidence behind each
choice is in benchmarks/RESULTS.md, "The noise model of the conversion"):

- the commands are integrated as the robot carries them out: ``command_lag_s`` late, their speed and turn rate
  scaled by ``speed_scale`` and ``turn_scale``, and the speed slowed by turning (``speed_per_turn``:
  :func:`calibrated`);
- each increment's forward and lateral variances are ``a * dt + c * s^2 + floor`` (dt the elapsed time, s the
  commanded path) along the axes of the pose it reaches (GTSAM's between factor; written to the stream as a full
  covariance in the earlier pose's frame, :func:`increment_covariances`); its heading variance
  ``a * dt + b * |turn|`` accrues along its commands, each piece's heading noise turning the rest of its path
  (:func:`heading_levers`; ``heading_along_path``), so that a long stretch without sightings, one increment, is
  as uncertain at its end as its commands make it;
- a logged range is the barcode's depth along the camera's axis, not its distance: each robot's camera
  (:class:`Camera`) puts a sighting at a point of the robot's frame, and the stream carries that point's range and
  bearing (:func:`through_camera`), with the camera's sigmas (the range's growing with the range);
- each sighting's variance is widened for the errors it shares with the earlier sightings of its landmark
  (:func:`sighting_sigmas`): range errors 0.2 s apart correlate at about 0.55, so a landmark seen for a while is not
  counted as many independent sightings. The header then says ``sightings_correlated``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import InputError
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, rotation
from online_slam.importers._lines import table
from online_slam.importers.mrclam.sightings import CAMERAS, Camera, camera_sightings, mounting, widened_field
from online_slam.sources.events import Event, Header, LandmarkTruth, Observation, Odometry, Start, Truth


@dataclass(frozen=True)
class MrclamNoise:
    """Noise model of the MRCLAM conversion."""

    x_per_s: float = 2.34e-5
    """Forward variance per second elapsed, m^2/s."""
    x_per_m: float = 0.0
    """Forward variance per metre of commanded path, m^2/m."""
    x_per_m2: float = 0.00125
    """Forward variance per squared metre of commanded path."""
    y_per_s: float = 1.13e-6
    """Lateral variance per second, m^2/s."""
    y_per_m: float = 0.0
    """Lateral variance per metre of commanded path, m^2/m."""
    y_per_m2: float = 6.24e-4
    """Lateral variance per squared metre of commanded path."""
    theta_per_s: float = 1.51e-4
    """Heading variance per second, rad^2/s."""
    theta_per_rad: float = 0.0095
    """Heading variance per radian of commanded turn, rad^2/rad (a random walk in the angle turned)."""
    theta_per_rad2: float = 0.0
    """Heading variance per squared radian of commanded turn."""
    floor: float = 1e-6
    """Added to every variance."""
    heading_along_path: bool = True
    """Spread the heading variance (``theta_per_s``, ``theta_per_rad``) along the commands inside each increment,
    each piece's heading noise turning the rest of its path (position noise ``q J r r^T J^T`` and its cross term),
    instead of one perturbation at the increment's end. A stretch without sightings is one increment, and
    without this its end position is far more certain than the commands make it."""
    command_lag_s: float = 0.24
    """Seconds between a command's timestamp and the motion it causes (calibrated on Vicon)."""
    speed_scale: float = 1.041
    """Distance moved per commanded distance (calibrated on Vicon)."""
    turn_scale: float = 0.948
    """Angle turned per commanded angle (calibrated on Vicon)."""
    speed_per_turn: float = 1.0
    """Share of the commanded speed lost per rad/s of commanded turn rate, s/rad: a command ``(v, w)`` moves the
    robot at ``speed_scale * v * max(0, 1 - speed_per_turn * |w|)`` (calibrated on Vicon: turning at 0.35 rad/s,
    the robots cover about 60% of the distance commanded)."""
    range_correlation: tuple[float, float, float, float] = (0.236, 2.9, 0.336, 23.1)
    """Correlation of range errors of one landmark seen twice ``dt`` apart by one robot,
    ``c1 exp(-dt / tau1) + c2 exp(-dt / tau2)`` as ``(c1, tau1, c2, tau2)`` (seconds); all zero: independent."""
    bearing_correlation: tuple[float, float, float, float] = (0.158, 1.02, 0.417, 13.0)
    """The same for bearing errors."""
    own_scale_range: tuple[float, float] = (0.197, 0.509)
    """The sensor scales ``--noise self`` reads against a stream's own sighting covariances (each ``widened``
    divided out) when the stream is declared right, lowest and highest: the share of their variance the batch's
    residuals keep, the rest taken up by the landmarks and poses (errors alike over a landmark's sightings, the
    camera's errors beyond Vicon's). Dataset 6's five robots (``python -m benchmarks.noise_self own``); the
    header's ``sightings_own_scale``. A refit (``--refit``, ``--fit-half``) keeps it: it needs the batch's self-fit of
    every robot, not Vicon."""
    own_scale_spread: float = 1.6
    """The factor beyond ``own_scale_range`` (below its low end, above its high end) within which a reading still
    says nothing: each half of Dataset 6 replayed alone reads within 1.23x of the range."""
    range_sigma: float = 0.0
    """Range standard deviation at zero range, m (the sigma of a sighting is this plus ``range_sigma_per_m``
    times its measured range), pooled over the robots: a robot with a camera (``cameras``) uses the camera's."""
    range_sigma_per_m: float = 0.00978
    """Growth of the range standard deviation per metre of measured range, m/m."""
    bearing_sigma: float = 0.0112
    """Bearing standard deviation, rad."""
    cameras: tuple[Camera, ...] = CAMERAS
    """Each robot's camera, robots 1..5 in order (:class:`Camera`): the stream carries the range and bearing of
    the point the robot's camera puts a sighting at, with the camera's sigmas. Empty: the logged columns as they
    are, with the sigmas above."""
    robot_barcode_m: float = 0.0253
    """How much farther a robot reads than its Vicon centre when another robot sights it through its camera, m:
    taken off the range of robot sightings (``--robot all``; fitted as the median over every robot's sightings of
    robots, :func:`~online_slam.importers.mrclam.noise.fit_robot_barcode`: 0.022-0.042 m by observing robot)."""
    start_sigma: float = 0.01
    """Standard deviation of the start prior (x, y in m, theta in rad)."""
    odometry_bias: tuple[float, float] = (0.05, 0.01)
    """Prior standard deviations of each robot's odometry bias, the share of each logged distance that is not real
    and the heading rate it adds (rad/s), which the EKF estimates with the state (header ``odometry_bias``; (0, 0):
    none). Not fitted: wider than Dataset 6's own biases (robot 4's distances about 2% long, heading rates of
    about 2 mrad/s), because a recording's robot may drift more. Chosen on held-out figures
    (benchmarks/RESULTS.md, "The EKF's odometry bias")."""


def noise_meta(noise: MrclamNoise) -> dict:
    """The noise model as a stream header records it (JSON types: tuples as lists, cameras as objects)."""
    meta = {k: list(v) if isinstance(v, tuple) else v for k, v in noise.__dict__.items()}
    meta["cameras"] = [dict(camera.__dict__) for camera in noise.cameras]
    return meta


def own_scale_meta(noise: MrclamNoise) -> dict:
    """The header's ``sightings_own_scale`` (none when the sightings are not widened: :func:`correlates`)."""
    if not correlates(noise):
        return {}
    return {"sightings_own_scale": {"range": list(noise.own_scale_range), "spread": noise.own_scale_spread}}


def bias_meta(noise: MrclamNoise) -> dict:
    """The header's ``odometry_bias`` (none when both priors are 0)."""
    return {"odometry_bias": list(noise.odometry_bias)} if any(noise.odometry_bias) else {}


def correlates(noise: MrclamNoise) -> bool:
    """Whether the model widens repeated sightings for their correlation (the stream header says so, and
    ``--noise fit`` then leaves its sighting sigmas as they are)."""
    return (
        noise.range_correlation[0]
        + noise.range_correlation[2]
        + noise.bearing_correlation[0]
        + noise.bearing_correlation[2]
        > 0.0
    )


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


def sampled(p: Pieces) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The poses of :func:`pieces` at its sample times, and the commanded path length and |turn| accumulated since
    the first, shapes (N, 3), (N,), (N,)."""
    path = np.concatenate([[0.0], np.cumsum(np.abs(p.speed) * p.dt)])
    turn = np.concatenate([[0.0], np.cumsum(np.abs(p.turn))])
    return p.poses[p.at], path[p.at], turn[p.at]


def _dead_reckoning(commands: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact unicycle integration of piecewise-constant commands (:func:`pieces`), sampled at (sorted) times.

    Args:
        commands: (t, v, w) rows sorted by t, shape (C, 3).
        times: Sample times, shape (N,).

    Returns:
        (poses relative to the state at times[0], shape (N, 3); commanded path length and |turn| accumulated
        since times[0], each shape (N,)).
    """
    return sampled(pieces(commands, times))


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
    dropped_unknown: int
    """Sightings of barcodes not in ``Barcodes.dat``, dropped."""
    robot_rows: np.ndarray
    """Sightings of other robots (t, barcode, range, bearing), sorted by t (stable), shape (M, 4)."""
    robots_seen: np.ndarray
    """The robot (subject 1..5) each of ``robot_rows`` sees, shape (M,)."""
    dropped_self: int
    """Sightings of the robot's own barcode, dropped."""

    def span(self, start: float, end: float) -> RobotData:
        """The part of the recording from ``start`` to ``end`` (s, ``end`` excluded): its sightings, the commands
        that drive the robot between them (from the one in force :data:`COMMAND_MARGIN_S` before ``start``) and
        Vicon with a second's margin for interpolation."""
        margin = COMMAND_MARGIN_S
        first = max(int(np.searchsorted(self.odometry[:, 0], start - margin, side="right")) - 1, 0)
        odometry = self.odometry[first : int(np.searchsorted(self.odometry[:, 0], end))]
        inside = (self.measurements[:, 0] >= start) & (self.measurements[:, 0] < end)
        robots = (self.robot_rows[:, 0] >= start) & (self.robot_rows[:, 0] < end)
        truth = self.truth[(self.truth[:, 0] >= start - 1.0) & (self.truth[:, 0] <= end + 1.0)]
        return replace(
            self,
            odometry=odometry,
            measurements=self.measurements[inside],
            subjects=self.subjects[inside],
            times=np.unique(self.measurements[inside, 0]),
            truth=truth,
            robot_rows=self.robot_rows[robots],
            robots_seen=self.robots_seen[robots],
        )


COMMAND_MARGIN_S = 1.0
"""Seconds of commands kept before a part of the recording begins (the robot acts on a command ``command_lag_s``,
0.24 s, after its timestamp)."""


def recording_span(root: Path) -> tuple[float, float]:
    """First and last sighting time over every robot of a folder, s."""
    times = [load_robot(root, r).measurements[:, 0] for r in (1, 2, 3, 4, 5)]
    return min(float(t[0]) for t in times if len(t)), max(float(t[-1]) for t in times if len(t))


def half_span(root: Path, half: str) -> tuple[float, float]:
    """The ``first`` or ``second`` half of the folder's recording by time (the same cut for every robot), as
    ``(start, end)`` with ``end`` excluded."""
    return half_of(recording_span(root), half)


def half_of(recording: tuple[float, float], half: str) -> tuple[float, float]:
    """The ``first`` or ``second`` half of a recording's ``(first, last)`` sighting times (:func:`half_span`)."""
    first, last = recording
    middle = 0.5 * (first + last)
    return (first, middle) if half == "first" else (middle, float(np.nextafter(last, np.inf)))


SWAPPED_SUBJECTS = {"MRCLAM_Dataset1": (11, 17)}
"""Folders whose ``Barcodes.dat`` gives two subjects each other's barcode, by folder name (as the MRCLAM site's
archives unpack): Dataset 1 has subjects 11 and 17 swapped (the anchor, Brossard et al.'s ``esde``, swaps them
back). Not checked on data here: only Dataset 6 is at hand."""


def subjects_of_barcodes(root: Path) -> dict[int, int]:
    """Subject of each barcode, from ``Barcodes.dat`` (with a known swap of the folder's undone)."""
    barcodes = table(root / "Barcodes.dat", ("subject", "barcode"))
    subject_of = {int(b): int(s) for s, b in barcodes}
    swapped = SWAPPED_SUBJECTS.get(root.resolve().name)
    if swapped is not None:
        a, b = swapped
        subject_of = {code: {a: b, b: a}.get(subject, subject) for code, subject in subject_of.items()}
    return subject_of


def load_robot(root: Path, robot: int, span: tuple[float, float] | None = None) -> RobotData:
    """Read one robot's odometry, measurements and Vicon truth; landmark sightings apart from robot sightings; only
    ``span`` (start, end) of the recording when given (:meth:`RobotData.span`)."""
    subject_of = subjects_of_barcodes(root)
    odometry = table(root / f"Robot{robot}_Odometry.dat", ("time", "v", "w"))
    measurements = table(root / f"Robot{robot}_Measurement.dat", ("time", "barcode", "range", "bearing"))
    truth = table(root / f"Robot{robot}_Groundtruth.dat", ("time", "x", "y", "theta"))
    subjects = np.array([subject_of.get(int(b), -1) for b in measurements[:, 1]])
    is_landmark = subjects >= 6
    kept, kept_subjects = measurements[is_landmark], subjects[is_landmark]
    order = np.argsort(kept[:, 0], kind="stable")
    is_other = (subjects >= 1) & (subjects <= 5) & (subjects != robot)
    others, others_seen = measurements[is_other], subjects[is_other]
    by_time = np.argsort(others[:, 0], kind="stable")
    data = RobotData(
        odometry=odometry[np.argsort(odometry[:, 0], kind="stable")],
        measurements=kept[order],
        subjects=kept_subjects[order],
        times=np.unique(kept[:, 0]),
        truth=truth,
        dropped_unknown=int(np.sum(subjects < 0)),
        robot_rows=others[by_time],
        robots_seen=others_seen[by_time],
        dropped_self=int(np.sum(subjects == robot)),
    )
    return data if span is None else data.span(*span)


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


def calibrated(commands: np.ndarray, cfg: MrclamNoise) -> np.ndarray:
    """Commands ``(t, v, w)`` as the robot carries them out: delayed by ``command_lag_s``, speed and turn rate
    scaled by ``speed_scale`` and ``turn_scale``, speed slowed by turning (``speed_per_turn``), shape (C, 3)."""
    out = np.array(commands, dtype=float)
    out[:, 0] += cfg.command_lag_s
    out[:, 1] *= cfg.speed_scale * np.maximum(0.0, 1.0 - cfg.speed_per_turn * np.abs(out[:, 2]))
    out[:, 2] *= cfg.turn_scale
    return out


def heading_levers(commands: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per increment between ``times``, the covariance at its end (the earlier pose's frame) that unit heading
    variance per second and per radian turned, accrued along its commands, causes: each piece's heading noise
    turns the rest of the increment's path, ``[J r; 1] q [J r; 1]^T`` with r the path left (J the quarter turn).

    Args:
        commands: (t, v, w) rows sorted by t, shape (C, 3).
        times: Pose times, sorted, shape (P,).

    Returns:
        (per second, per radian turned), each shape (P - 1, 3, 3).
    """
    return levers_of(pieces(commands, times))


def levers_of(p: Pieces) -> tuple[np.ndarray, np.ndarray]:
    """:func:`heading_levers` of commands already integrated by :func:`pieces`."""
    at, (x, y, heading) = p.at, p.poses.T
    increments = len(at) - 1
    piece = np.searchsorted(at, np.arange(len(p.dt)), side="right") - 1  # the increment each piece belongs to
    inside = (piece >= 0) & (piece < increments)
    end = at[np.minimum(piece + 1, len(at) - 1)]
    start_heading = heading[at[np.clip(piece, 0, len(at) - 1)]]
    c, s = np.cos(start_heading), np.sin(start_heading)
    rx, ry = x[end] - x[1:], y[end] - y[1:]
    jr = np.stack([-(-s * rx + c * ry), c * rx + s * ry, np.ones_like(rx)], -1)  # [J r; 1], earlier frame
    outer = jr[:, :, None] * jr[:, None, :]
    levers = []
    for q in (p.dt, np.abs(p.turn)):
        total = np.zeros((increments, 3, 3))
        np.add.at(total, piece[inside], (q[:, None, None] * outer)[inside])
        levers.append(total)
    return levers[0], levers[1]


def model_covariances(
    cfg: MrclamNoise,
    increments: np.ndarray,
    spans: tuple[np.ndarray, np.ndarray, np.ndarray],
    levers: tuple[np.ndarray, np.ndarray] | None,
) -> np.ndarray:
    """The noise model's covariances of increments (the earlier pose's frame).

    Args:
        cfg: The noise model.
        increments: ``[dx, dy, dtheta]``, shape (K, 3).
        spans: Seconds, commanded path length and |turn| of each increment, each shape (K,).
        levers: :func:`levers_of` the increments' commands; needed when ``cfg.heading_along_path``.

    Returns:
        Covariances, shape (K, 3, 3).
    """
    dt, ds, da = spans
    heading = cfg.theta_per_s * dt + cfg.theta_per_rad * np.abs(da)
    variances = np.stack(
        [
            cfg.x_per_s * dt + cfg.x_per_m * np.abs(ds) + cfg.x_per_m2 * ds**2 + cfg.floor,
            cfg.y_per_s * dt + cfg.y_per_m * np.abs(ds) + cfg.y_per_m2 * ds**2 + cfg.floor,
            cfg.theta_per_rad2 * da**2 + (0.0 if cfg.heading_along_path else heading) + cfg.floor,
        ],
        -1,
    )
    covariances = increment_covariances(increments, variances)
    if not cfg.heading_along_path:
        return covariances
    if levers is None:
        raise ValueError("heading noise along the commands needs the increments' levers")
    per_s, per_rad = levers
    covariances = covariances + cfg.theta_per_s * per_s + cfg.theta_per_rad * per_rad
    return 0.5 * (covariances + np.swapaxes(covariances, 1, 2))


def odometry_increments(commands: np.ndarray, times: np.ndarray, cfg: MrclamNoise) -> tuple[np.ndarray, np.ndarray]:
    """The increments between poses at ``times``, from the calibrated commands, and their covariances.

    Args:
        commands: Velocity commands (t, v, w) as logged, sorted by t, shape (C, 3).
        times: Pose times, sorted, shape (P,).
        cfg: The noise model (and the commands' calibration).

    Returns:
        (increments ``[dx, dy, dtheta]`` in the earlier pose's frame, shape (P - 1, 3); covariances, shape
        (P - 1, 3, 3)).
    """
    p = pieces(calibrated(commands, cfg), times)
    poses, path, turn = sampled(p)
    increments = between(poses[:-1], poses[1:])
    spans = (np.diff(times), np.diff(path), np.diff(turn))
    return increments, model_covariances(cfg, increments, spans, levers_of(p) if cfg.heading_along_path else None)


def read_mrclam(
    folder: str | Path, robot: int, noise: MrclamNoise | None = None, span: tuple[float, float] | None = None
) -> Iterator[Event]:
    """Stream one MRCLAM robot as events.

    Args:
        folder: The dataset folder (``Barcodes.dat``, ``RobotN_*.dat``, ``Landmark_Groundtruth.dat``).
        robot: Robot number, 1..5.
        noise: Noise model (defaults: fitted on Dataset 6).
        span: Only this part of the recording, ``(start, end)`` in the dataset's seconds (:func:`half_span`); it
            starts at its first sighting's Vicon pose, as the whole recording does.

    Yields:
        Stream-v1 events.
    """
    root = Path(folder)
    cfg = noise or MrclamNoise()
    if not 1 <= robot <= 5:
        raise InputError(str(root), 0, "robot", f"expected a robot number 1..5, got {robot}")
    data = load_robot(root, robot, span)
    if not len(data.times):
        raise InputError(str(root), 0, "robot", f"robot {robot} has no sightings in that part of the recording")
    kept_subjects, times, truth = data.subjects, data.times, data.truth
    camera, kept, sigmas, widening = camera_sightings(cfg, robot, data.measurements, kept_subjects, mounted=True)
    sensors = {} if camera is None else {"sensors": {"camera": {"pose": mounting(camera)}}}
    landmarks = table(root / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std"))
    increments, covariances = odometry_increments(data.odometry, times, cfg)
    true_poses, covered = _interpolate_truth(truth, times)
    yield Header(
        name=f"MRCLAM {root.name.removeprefix('MRCLAM_')} robot {robot}",
        meta={
            "converted_from": str(root.name),
            "robot": robot,
            "poses": int(len(times)),
            "landmark_observations": int(len(kept)),
            "dropped_robot_observations": int(len(data.robot_rows)),
            "dropped_own_barcode": data.dropped_self,
            "dropped_unknown_barcodes": data.dropped_unknown,
            "noise": noise_meta(cfg),
            "sightings_correlated": correlates(cfg),
            **own_scale_meta(cfg),
            **bias_meta(cfg),
            **sensors,
        },
    )
    start = true_poses[0]
    yield Start(t=float(times[0]), pose=tuple(map(float, start)), sigma=(cfg.start_sigma,) * 3)
    for subject, x, y, _, _ in landmarks:
        yield LandmarkTruth(int(subject), (float(x), float(y)))
    ends: NDArray[np.float64] = np.r_[times, np.inf]
    bounds = np.searchsorted(kept[:, 0], ends)
    for k, t in enumerate(times):
        if k > 0:
            yield Odometry(
                t=float(t),
                delta=tuple(map(float, increments[k - 1])),
                cov=tuple(tuple(map(float, row)) for row in covariances[k - 1]),
            )
        if covered[k]:
            yield Truth(t=float(t), pose=tuple(map(float, true_poses[k])))
        for i in range(bounds[k], bounds[k + 1]):
            yield Observation(
                t=float(t),
                landmark=int(kept_subjects[i]),
                range=float(kept[i, 2]),
                bearing=float(kept[i, 3]),
                sigma=(float(sigmas[i, 0]), float(sigmas[i, 1])),
                sensor=None if camera is None else "camera",
                widened=widened_field(widening[i]),
            )
