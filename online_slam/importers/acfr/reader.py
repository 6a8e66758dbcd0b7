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
from online_slam.importers._lines import numbered_lines, numbers
from online_slam.importers.acfr import FILES
from online_slam.importers.laser import to_robot_frame
from online_slam.importers.motion import ackermann, integrate, pose_times, start_from_positions, truth_at
from online_slam.sources.events import Event, Header, Observation, Odometry, Start, Truth

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
    rows = [numbers(str(path), line, fields, names) for line, fields in numbered_lines(path)]
    if not rows:
        raise InputError(str(path), 0, "", "no data rows")
    table = np.array(rows, dtype=float)
    if np.any(np.diff(table[:, 0]) < 0):
        line = int(np.flatnonzero(np.diff(table[:, 0]) < 0)[0]) + 2
        raise InputError(str(path), line, "t", "time goes backwards")
    return table


def read_acfr(
    folder: str | Path, noise: AcfrNoise | None = None, vehicle: AcfrVehicle | None = None
) -> Iterator[Event]:
    """Stream the Victoria Park log as events (sightings without ids, GPS as position-only truth).

    Args:
        folder: The folder with ``inputs.dat``, ``measurements.dat`` and ``gps.dat``.
        noise: Noise model and clutter limits.
        vehicle: Car geometry.

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
    ds, da = np.diff(path), np.diff(turn)
    variances = np.stack(
        [
            cfg.x_per_m * ds + cfg.floor,
            cfg.y_per_m * ds + cfg.floor,
            cfg.theta_per_m * ds + cfg.theta_per_rad * da + cfg.floor,
        ],
        -1,
    )
    mount = (car.laser_x, car.laser_y, -math.pi / 2)  # the file's bearing 0 is the laser's right
    z, z_cov = to_robot_frame(kept[:, 1:3], mount, (cfg.range_sigma, cfg.bearing_sigma))
    truth, covered = truth_at(gps, times, cfg.truth_gap, cfg.truth_speed)
    start_pose = start_from_positions(poses, path, truth, covered, cfg.start_distance)
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
            "start": "GPS position at the first pose, heading from GPS and dead reckoning over the first "
            f"{cfg.start_distance:g} m (the start pose is held fixed)",
            "vehicle": asdict(car),
            "noise": asdict(cfg),
        },
    )
    yield Start(t=start, pose=tuple(map(float, start_pose)))
    ends: NDArray[np.float64] = np.r_[times, np.inf]
    bounds = np.searchsorted(kept[:, 0], ends, side="left")
    for k, t in enumerate(times):
        if k > 0:
            v = variances[k - 1]
            yield Odometry(
                t=float(t),
                delta=tuple(map(float, increments[k - 1])),
                cov=((float(v[0]), 0.0, 0.0), (0.0, float(v[1]), 0.0), (0.0, 0.0, float(v[2]))),
            )
        if covered[k]:
            yield Truth(t=float(t), pose=(float(truth[k, 0]), float(truth[k, 1]), math.nan))
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
