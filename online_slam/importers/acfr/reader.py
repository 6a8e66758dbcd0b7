"""ACFR Victoria Park, timestamped ASCII (``inputs.dat``, ``measurements.dat``, ``gps.dat``) -> stream v1.

The raw log of a utility truck driving ~4 km through Victoria Park, Sydney (see the folder's PROVENANCE.md): wheel
speed and steering at 40 Hz, tree detections (range, bearing, diameter) from a 2D laser, GPS. The detections
carry no landmark ids, so the stream's sightings have none (the estimators associate them).

- Vehicle model (Ackermann, ACFR's car): the robot pose is the centre of the rear axle, heading along the car.
  The speed encoder sits on the rear left wheel: ``v_c = v / (1 - tan(steer) H / L)``; ``dtheta/dt = v_c
  tan(steer) / L``. Inputs hold from their own time to the next (zero-order hold); each 25 ms sample is integrated
  exactly (an arc).
- Poses at the scan times (detections sharing a time form one scan) and every ``max_gap`` seconds in between, so
  long stretches without trees still have poses (and truth); the increment between two poses is the exact
  composition of the samples between them.
- Odometry noise per increment (documented in :class:`AcfrNoise`): variances grow with the distance driven and
  the angle turned (independent errors per metre and per radian), plus a floor.
- Laser: mounted ``laser_x`` ahead of the rear axle and ``laser_y`` to the left, axes along the car; the file's
  bearing is measured from the laser's right (0) to its left (pi), so the vehicle-frame bearing is ``bearing -
  pi/2`` at the laser. Each detection is moved to the rear-axle frame (range and bearing from the robot pose)
  and its noise propagated through that transform (a full 2x2 covariance per sighting).
- Clutter limits: detections outside ``[min_range, max_range]`` or outside ``[min_bearing, max_bearing]`` (laser
  frame) are dropped and counted in the header.
- Truth: GPS positions (no heading), interpolated linearly at pose times bracketed by two fixes at most
  ``truth_gap`` apart that do not jump (speed between them at most ``truth_speed``); evaluation aligns them
  rigidly. Poses without such fixes have no truth. The start pose (held fixed) is put in the GPS frame: the
  first GPS position, and the heading that turns the first ``start_distance`` metres of dead reckoning onto GPS;
  so recordings draw the path over GPS (errors are still computed after rigid alignment).
- GPS fixes (``fixes``: every S seconds, sigma): the first GPS reading at or after each multiple of S seconds that
  agrees with both neighbours (no jump, no gap) becomes a ``position`` fix at its own time (the front-end gives it
  a pose of its own on the split odometry); those readings are left out of the truth, so that the score is taken
  against the GPS held back only.
- GPS antenna (``antenna``, default :data:`GPS_ANTENNA`): GPS is the position of a point ahead of the rear axle,
  not of the axle centre. Fixes and truth carry it as their ``offset`` (scoring compares that point of the
  estimated pose), and the start pose puts the antenna, not the axle, on the first GPS position. The files state
  no antenna position; it was measured on the log (docs/datasets.md): dead reckoning fitted rigidly to GPS over
  20 s windows, with one antenna offset for all windows, gives (3.88, 0.67) m on the first half of the log and
  (4.11, 0.54) m on the second (median residual 0.40 -> 0.19 m and 0.28 -> 0.16 m). No stamp needs a shift:
  the delay that best matches GPS speed to wheel speed is 0.0 s on both halves, and so is the laser's
  (``python -m benchmarks.gps_clock``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import InputError
from online_slam.geometry.se2 import between
from online_slam.importers._lines import table
from online_slam.importers.acfr import FILES, GPS_ANTENNA
from online_slam.importers.laser import to_robot_frame
from online_slam.importers.motion import ackermann, integrate, pose_times, start_from_positions, truth_at
from online_slam.models.fix import GPS_CORRELATION_S, fixed_point
from online_slam.sources.events import Event, Header, Observation, Odometry, Position, Start, Truth

Array = NDArray[np.float64]


@dataclass(frozen=True)
class AcfrVehicle:
    """Geometry of ACFR's truck (metres)."""

    wheelbase: float = 2.83
    """L: rear to front axle."""
    encoder_offset: float = 0.76
    """H: lateral distance from the rear axle centre to the wheel whose speed is measured (rear left)."""
    laser_x: float = 3.78
    """Laser ahead of the rear axle centre."""
    laser_y: float = 0.50
    """Laser left of the rear axle centre."""


@dataclass(frozen=True)
class AcfrNoise:
    """Noise model of the conversion: odometry per increment, laser per detection, and the clutter limits.

    The sigmas are about twice the residual spread at the batch solution of the whole log (JCBB associations):
    with the fitted spread itself the EKF turns overconfident on this log and its association fails, with twice
    it (up to five times) it holds (benchmarks/RESULTS.md, "Raw Victoria Park").
    """

    x_per_m: float = 0.02**2
    """Forward variance per metre driven (m^2/m)."""
    y_per_m: float = 0.02**2
    """Lateral variance per metre driven (m^2/m)."""
    theta_per_m: float = 0.005**2
    """Heading variance per metre driven (rad^2/m): steering and wheel-slip errors."""
    theta_per_rad: float = 0.02**2
    """Heading variance per radian turned (rad^2/rad)."""
    floor: float = 1e-6
    """Added to every variance (an increment of a standing car stays well conditioned)."""
    range_sigma: float = 0.2
    """Laser range to the tree centre, metres."""
    bearing_sigma: float = 0.005
    """Laser bearing, radians."""
    min_range: float = 3.0
    """Detections nearer than this are dropped, metres."""
    max_range: float = 25.0
    """Detections farther than this are dropped, metres: far trees are seen in few scans and poorly resolved, and
    each becomes a landmark of its own more often; 25 m maps the fewest spurious landmarks at the same error and
    runs fastest (benchmarks/RESULTS.md, "Raw Victoria Park")."""
    min_bearing: float = math.radians(6.3)
    """Laser-frame bearing limits (0 = laser's right, pi = its left): detections at the edges are dropped."""
    max_bearing: float = math.radians(177.0)
    """Upper laser-frame bearing limit."""
    max_gap: float = 1.0
    """Longest time between two poses, seconds (poses are added in scan-free stretches)."""
    truth_gap: float = 0.5
    """GPS fixes bracketing a pose time at most this far apart give it a truth position, seconds."""
    truth_speed: float = 10.0
    """Two fixes implying a faster motion are a GPS jump: no truth between them, m/s."""
    start_distance: float = 20.0
    """The start pose's heading is taken from GPS over this much driving (so maps are drawn over GPS), metres."""


def _table(path: Path, names: tuple[str, ...]) -> Array:
    rows = table(path, names)
    if np.any(np.diff(rows[:, 0]) < 0):
        line = int(np.flatnonzero(np.diff(rows[:, 0]) < 0)[0]) + 2
        raise InputError(str(path), line, "t", "time goes backwards")
    return rows


def _fix_rows(gps: Array, every: float, noise: AcfrNoise) -> NDArray[np.bool_]:
    """Which GPS readings become fixes: per multiple of ``every`` seconds, the first reading at or after it whose
    neighbours are at most ``truth_gap`` away in time and agree with it in speed (at most ``truth_speed``)."""
    t, xy = gps[:, 0], gps[:, 1:]
    span, step = np.diff(t), np.linalg.norm(np.diff(xy, axis=0), axis=1)
    smooth = (span <= noise.truth_gap) & (step <= noise.truth_speed * span + 1e-9)  # reading i to i + 1
    good = np.r_[False, smooth] & np.r_[smooth, False]
    chosen = np.zeros(len(t), dtype=bool)
    candidates = np.flatnonzero(good)
    for due in t[0] + every * np.arange(1, int((t[-1] - t[0]) / every) + 1):
        k = np.searchsorted(t[candidates], due)
        if k < len(candidates) and t[candidates[k]] < due + every:
            chosen[candidates[k]] = True
    return chosen


def _fix_meta(fixes: int, every: float | None, sigma: float) -> dict[str, float]:
    """The header's fields on GPS fixes (none without): how many, how often, their sigma, their errors' time
    constant (:data:`GPS_CORRELATION_S`, read by the front-end)."""
    if not every:
        return {}
    return {"gps_fixes": fixes, "gps_fix_every": every, "gps_sigma": sigma, "fix_correlation_s": GPS_CORRELATION_S}


def _positions(rows: Array, sigma: float, offset: tuple[float, float] | None) -> Iterator[Position]:
    """GPS readings ``[t, x, y]`` (k, 3) as position fixes of the antenna (``offset``; None: the axle centre)."""
    for row in rows:
        yield Position(t=float(row[0]), xy=(float(row[1]), float(row[2])), sigma=(sigma, sigma), offset=offset)


def _variances(path: Array, turn: Array, cfg: AcfrNoise) -> Array:
    """Odometry variances ``[x, y, theta]`` of each increment (N - 1, 3), from the distance driven and turned."""
    ds, da = np.diff(path), np.diff(turn)
    x, y = cfg.x_per_m * ds + cfg.floor, cfg.y_per_m * ds + cfg.floor
    return np.stack([x, y, cfg.theta_per_m * ds + cfg.theta_per_rad * da + cfg.floor], -1)


def read_acfr(
    folder: str | Path,
    noise: AcfrNoise | None = None,
    vehicle: AcfrVehicle | None = None,
    fixes: tuple[float | None, float] = (None, 0.5),
    antenna: tuple[float, float] = GPS_ANTENNA,
) -> Iterator[Event]:
    """Stream the Victoria Park log as events (sightings without ids, GPS as position-only truth).

    Args:
        folder: The folder with ``inputs.dat``, ``measurements.dat`` and ``gps.dat``.
        noise: Noise model and clutter limits.
        vehicle: Car geometry.
        fixes: (seconds between GPS readings turned into ``position`` fixes, None: none; their sigma, metres).
        antenna: The GPS antenna ``[forward, left]`` of the rear axle centre, metres (fixes and truth are of it).

    Yields:
        Stream-v1 events.
    """
    root = Path(folder)
    cfg, car = noise or AcfrNoise(), vehicle or AcfrVehicle()
    for name in FILES:
        if not (root / name).is_file():
            raise InputError(str(root / name), 0, "", "missing file of the ACFR folder")
    inputs = _table(root / "inputs.dat", ("t", "speed", "steering"))
    measurements = _table(root / "measurements.dat", ("t", "range", "bearing", "diameter"))
    gps = _table(root / "gps.dat", ("t", "x", "y"))
    every, gps_sigma = fixes
    fixed = _fix_rows(gps, every, cfg) if every else np.zeros(len(gps), dtype=bool)
    gps, fix_rows = gps[~fixed], gps[fixed]
    r, b = measurements[:, 1], measurements[:, 2]
    keep = (r >= cfg.min_range) & (r <= cfg.max_range) & (b >= cfg.min_bearing) & (b <= cfg.max_bearing)
    kept = measurements[keep]
    scan_times = np.unique(kept[:, 0])
    start = float(min(inputs[0, 0], measurements[0, 0]))
    end = float(max(inputs[-1, 0], kept[-1, 0] if len(kept) else start))
    times = pose_times(start, scan_times, end, cfg.max_gap)
    v, w = ackermann(inputs[:, 1], inputs[:, 2], car.wheelbase, car.encoder_offset)
    poses, path, turn = integrate(inputs[:, 0], v, w, times)
    increments = between(poses[:-1], poses[1:])
    variances = _variances(path, turn, cfg)
    mount = (car.laser_x, car.laser_y, -math.pi / 2)  # the file's bearing 0 is the laser's right
    z, z_cov = to_robot_frame(kept[:, 1:3], mount, (cfg.range_sigma, cfg.bearing_sigma))
    truth, covered = truth_at(gps, times, cfg.truth_gap, cfg.truth_speed)
    offset = (float(antenna[0]), float(antenna[1])) if any(antenna) else None
    start_pose = start_from_positions(fixed_point(poses, antenna), path, truth, covered, cfg.start_distance)
    yield Header(
        name="Victoria Park (ACFR raw log)",
        meta={
            "converted_from": root.name,
            "poses": int(len(times)),
            "scans": int(len(scan_times)),
            "detections": int(len(measurements)),
            "detections_kept": int(keep.sum()),
            "dropped_by_limits": int((~keep).sum()),
            "truth": "GPS position only, linearly interpolated at pose times; align rigidly",
            **_fix_meta(int(fixed.sum()), every, gps_sigma),
            "gps_antenna": list(antenna),
            "start": "GPS position at the first pose, heading from GPS and dead reckoning over the first "
            f"{cfg.start_distance:g} m (the start pose is held fixed)",
            "vehicle": asdict(car),
            "noise": asdict(cfg),
        },
    )
    yield Start(t=start, pose=tuple(map(float, start_pose)))
    ends: NDArray[np.float64] = np.r_[times, np.inf]
    bounds = np.searchsorted(kept[:, 0], ends, side="left")
    fix_rows = fix_rows[(fix_rows[:, 0] > start) & (fix_rows[:, 0] <= end)]
    fix_at = np.searchsorted(times, fix_rows[:, 0], side="left")  # the pose at or after each fix
    for k, t in enumerate(times):
        yield from _positions(fix_rows[(fix_at == k) & (fix_rows[:, 0] < t)], gps_sigma, offset)  # before the odometry
        if k > 0:
            v = variances[k - 1]
            yield Odometry(
                t=float(t),
                delta=tuple(map(float, increments[k - 1])),
                cov=((float(v[0]), 0.0, 0.0), (0.0, float(v[1]), 0.0), (0.0, 0.0, float(v[2]))),
            )
        if covered[k]:
            yield Truth(t=float(t), pose=(float(truth[k, 0]), float(truth[k, 1]), math.nan), offset=offset)
        for i in range(bounds[k], bounds[k + 1]):
            if kept[i, 0] != t:
                continue
            c = z_cov[i]
            yield Observation(
                t=float(t),
                landmark=None,
                range=float(z[i, 0]),
                bearing=float(z[i, 1]),
                cov=((float(c[0, 0]), float(c[0, 1])), (float(c[1, 0]), float(c[1, 1]))),
            )
        yield from _positions(fix_rows[(fix_at == k) & (fix_rows[:, 0] == t)], gps_sigma, offset)  # at the pose's time
