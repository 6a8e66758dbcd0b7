"""A ROS bag -> stream-v1 events: odometry, sightings, position fixes and truth (:mod:`.messages` reads it).

- **Times** are the messages' header stamps; each topic is sorted by them.
- **Odometry** (``nav_msgs/msg/Odometry``): a pose per message, the increment between consecutive messages' poses.
  Its noise is the message's own covariance (the pose covariance's x, y, yaw block, read as the increment's, as
  drivers that publish a constant covariance mean it) when that block is not zero; else ``--odom-sigma`` and the
  growth options. The start pose is the first message's pose (the odometry's frame).
- **Twist** (``geometry_msgs/msg/TwistStamped``): each twist holds until the next message and is integrated
  exactly (an arc); with ``--steer L,H`` it is a car's wheel speed and steering angle (:func:`.motion.ackermann`).
  Poses at each sighting time and every ``--pose-gap`` seconds between; the start at the first twist or
  sighting, at the origin.
- **Sightings**: markers (``ns/id`` or ``id``, position in the header's frame) as ``xy`` sightings, or range and
  bearing; laser landmarks (:mod:`online_slam.importers.laser`) without ids. A frame other than the robot's is a
  sensor mounted where ``/tf_static`` says: declared in the header (``sensors``), or, with ``--sensor-to-base``,
  each sighting moved to the robot's centre.
- **Fixes** (``--fix``): ``position`` records. NavSatFix is projected on the local tangent plane at an origin
  (``--fix-origin``, else the first fix): ``east = N cos(lat0) dlon``, ``north = M dlat`` with WGS84's radii of
  curvature at lat0 (meridian M, prime vertical N); good to millimetres within kilometres of the origin. Its
  covariance's east-north block when the message knows it (``position_covariance_type`` > 0), else
  ``--fix-sigma``.
- **Antenna**: a NavSatFix's frame is a sensor's: its ``/tf_static`` mounting's (x, y) is the offset of the fixes
  and truth it gives (the robot-frame point they are the position of), an error when ``/tf_static`` does not reach
  it (as for sightings); the robot's own frame or none: no offset. A PointStamped's frame is that of its
  coordinates: one mounted on the robot is an antenna (its offset), any other (a map frame) gives no offset.
- **Truth** (``--truth``): interpolated linearly at pose times between messages at most ``--truth-gap`` apart that
  do not jump (``--truth-speed``); NavSatFix and PointStamped give position-only truth, one frame per topic, and
  ``--start-from-truth`` then puts the antenna (not the robot's centre) on the first position.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import InputError
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, compose, inverse
from online_slam.importers.bag import BagOptions
from online_slam.importers.bag.messages import NAVSAT, POINT, TWIST, Bag, Table, read_topics
from online_slam.importers.laser import Detector, to_robot_frame
from online_slam.importers.motion import ackermann, integrate, pose_times, start_from_positions, truth_at, variances
from online_slam.models.fix import GPS_CORRELATION_S, fixed_point
from online_slam.sources.events import Event, Header, Observation, Odometry, Position, Start, Truth

Array = NDArray[np.float64]
WGS84_A, WGS84_E2 = 6378137.0, 6.69437999014e-3
"""WGS84's equatorial radius (m) and first eccentricity squared."""


def local_plane(lat: Array, lon: Array, origin: tuple[float, float]) -> Array:
    """Latitude and longitude (degrees) -> east and north (m) on the tangent plane at ``origin`` (n, 2)."""
    phi = math.radians(origin[0])
    w = 1.0 - WGS84_E2 * math.sin(phi) ** 2
    n, m = WGS84_A / math.sqrt(w), WGS84_A * (1.0 - WGS84_E2) / w**1.5
    east = np.radians(np.asarray(lon) - origin[1]) * n * math.cos(phi)
    north = np.radians(np.asarray(lat) - origin[0]) * m
    return np.stack([east, north], -1)


def from_local_plane(xy: Array, origin: tuple[float, float]) -> tuple[Array, Array]:
    """The inverse of :func:`local_plane`: east and north (n, 2) -> latitude and longitude, degrees."""
    phi = math.radians(origin[0])
    w = 1.0 - WGS84_E2 * math.sin(phi) ** 2
    n, m = WGS84_A / math.sqrt(w), WGS84_A * (1.0 - WGS84_E2) / w**1.5
    return origin[0] + np.degrees(xy[:, 1] / m), origin[1] + np.degrees(xy[:, 0] / (n * math.cos(phi)))


def _detector(o: BagOptions) -> Detector:
    low_r, high_r = o.scan_range or (0.0, math.inf)
    low_b, high_b = (math.radians(v) for v in o.scan_bearing) if o.scan_bearing else (-math.inf, math.inf)
    low_d, high_d = o.scan_diameter or (0.0, math.inf)
    return Detector(o.scan_jump or 1.0, low_r, high_r, low_b, high_b, low_d, high_d, o.scan_intensity, o.scan_decimals)


def read_bag(path: str | Path, options: BagOptions) -> Iterator[Event]:
    """Stream a bag's topics as events (``position`` records only with ``--fix``).

    Raises:
        InputError: One line naming the topic or option: a missing topic, a type its option does not read, a
            missing option (noise), a sensor frame /tf_static does not mount.
    """
    p = Path(path)
    if options.odom is None:
        raise InputError(str(p), 0, "odom", "a ROS bag needs --odom TOPIC (nav_msgs/msg/Odometry or TwistStamped)")
    names = ("odom", "landmarks", "scan", "fix", "truth")
    topics = {n: getattr(options, n) for n in names if getattr(options, n) is not None}
    bag = read_topics(p, topics, _detector(options))
    yield from _events(p, bag, options)


def _events(path: Path, bag: Bag, o: BagOptions) -> Iterator[Event]:
    odom = bag.tables["odom"]
    if len(odom.array) == 0:
        raise InputError(str(path), 0, "odom", f"topic {o.odom} has no messages")
    base = o.base_frame or "base_link"
    sensors: dict[str, tuple[float, float, float]] = {}
    sightings = _sightings(path, bag, o, base, sensors)
    if odom.msgtype == TWIST:
        times, poses, path_m, turn, cov = _twist(path, odom, o, sightings, bag.tables)
    else:
        times, poses, path_m, turn, cov = _odometry(path, odom, o)
    origin = _origin(bag.tables, o)
    truth, covered = _truth(bag.tables.get("truth"), times, o, origin)
    antenna = _truth_offset(path, bag, base)
    start = poses[0]
    if o.start_from_truth is not None:
        start = _start_from_truth(path, poses, path_m, truth, covered, o.start_from_truth, antenna)
    first = times[0]
    before = sum(1 for t, _ in sightings if t < first)
    meta: dict[str, Any] = {"converted_from": path.name, "topics": {n: getattr(o, n) for n in
                            ("odom", "landmarks", "scan", "fix", "truth") if getattr(o, n)},
                            "messages": bag.messages, "poses": len(times), "before_first_pose": before}  # fmt: skip
    if sensors:
        meta["sensors"] = {name: {"pose": list(pose)} for name, pose in sensors.items()}
    if (fixes := bag.tables.get("fix")) is not None and fixes.msgtype == NAVSAT:
        meta["fix_correlation_s"] = GPS_CORRELATION_S  # a GPS's errors wander (docs/formats.md, absolute fixes)
    yield Header(name=f"ROS bag {path.name}", meta=meta)
    yield Start(t=float(first), pose=tuple(map(float, start)))
    timed: list[tuple[float, int, int, Event]] = []
    increments = between(poses[:-1], poses[1:])
    for k in range(1, len(times)):
        c = cov[k - 1]
        timed.append((float(times[k]), 0, k, Odometry(t=float(times[k]), delta=tuple(map(float, increments[k - 1])),
                                                      cov=tuple(tuple(map(float, row)) for row in c))))  # fmt: skip
    for j in np.flatnonzero(covered).tolist():
        timed.append((float(times[j]), 1, j, Truth(t=float(times[j]), pose=tuple(map(float, truth[j])),
                                                   offset=antenna)))  # fmt: skip
    for i, fix in enumerate(_fixes(path, bag, o, base, origin)):
        timed.append((fix.t, 2, i, cast("Event", fix)))  # Position joins Event with the fixes' estimators
    for i, (t, observation) in enumerate(sightings):
        if t >= first:
            timed.append((t, 3, i, observation))
    timed.sort(key=lambda item: item[:3])
    for _, _, _, event in timed:
        yield event


def _mount(
    path: Path, bag: Bag, frame: str, base: str, option: str, strict: bool = True
) -> tuple[float, float, float] | None:
    """A frame's pose in the robot frame through /tf_static (None: the robot's own frame, or, not ``strict``, a
    frame /tf_static does not mount on it)."""
    if frame in ("", base):
        return None
    pose, at, seen = np.zeros(3), frame, set()
    while at != base:
        if at not in bag.tf or at in seen:
            if not strict:
                return None
            raise InputError(str(path), 0, option, f"frame {frame!r} has no /tf_static mounting on {base!r}")
        seen.add(at)
        parent, x, y, theta = bag.tf[at]
        pose = compose(np.array([x, y, theta]), pose)
        at = parent
    return (float(pose[0]), float(pose[1]), float(pose[2]))


def _sightings(path: Path, bag: Bag, o: BagOptions, base: str, sensors: dict) -> list[tuple[float, Observation]]:
    out: list[tuple[float, Observation]] = []
    markers, scan = bag.tables.get("landmarks"), bag.tables.get("scan")
    if markers is not None and len(markers.array):
        xy = o.xy_sigma is not None
        if not xy and (o.range_sigma is None or o.bearing_sigma is None):
            raise InputError(str(path), 0, "landmarks", f"topic {o.landmarks}: give --xy-sigma S (position "
                             "sightings) or --range-sigma and --bearing-sigma")  # fmt: skip
        a = markers.array
        z = a[:, 1:3] if xy else np.column_stack([np.hypot(a[:, 1], a[:, 2]), np.arctan2(a[:, 2], a[:, 1])])
        frames = np.array([frame for frame, _ in markers.labels], dtype=object)
        for frame in dict.fromkeys(frames.tolist()):
            rows = np.flatnonzero(frames == frame)
            mount = _mount(path, bag, frame, base, "landmarks")
            landmarks = [markers.labels[i][1] for i in rows]
            out += _batch(a[rows, 0], landmarks, z[rows], xy, o, mount, frame, sensors)
    if scan is not None and len(scan.array):
        if o.range_sigma is None or o.bearing_sigma is None:
            raise InputError(str(path), 0, "scan", f"topic {o.scan}: give --range-sigma and --bearing-sigma")
        a = scan.array
        frames = np.array(scan.labels, dtype=object)
        for frame in dict.fromkeys(frames.tolist()):
            rows = np.flatnonzero((frames == frame) & (a[:, 3] > 0))
            mount = _mount(path, bag, frame, base, "scan")
            out += _batch(a[rows, 0], [None] * len(rows), a[rows, 1:3], False, o, mount, frame, sensors)
    out.sort(key=lambda item: item[0])
    return out


def _batch(
    t: Array, landmarks: list, z: Array, xy: bool, o: BagOptions, mount: tuple[float, float, float] | None,
    frame: str, sensors: dict,
) -> list[tuple[float, Observation]]:  # fmt: skip
    """The sightings of one frame: ``z`` (k, 2) as ``xy`` or range and bearing, at times ``t`` (k,)."""
    sigma = cast("tuple[float, float]", (o.xy_sigma, o.xy_sigma) if xy else (o.range_sigma, o.bearing_sigma))
    times = t.tolist()
    if mount is not None and o.sensor_to_base:
        if xy:
            c, s = math.cos(mount[2]), math.sin(mount[2])
            rot = np.array([[c, -s], [s, c]])
            p = z @ rot.T + np.array(mount[:2])
            cov = _tuples(rot @ np.diag(np.square(sigma)) @ rot.T)
            return [(ti, Observation(t=ti, landmark=lm, xy=(pi[0], pi[1]), cov=cov))
                    for ti, lm, pi in zip(times, landmarks, p.tolist())]  # fmt: skip
        zr, covs = to_robot_frame(z, mount, sigma)
        return [(ti, Observation(t=ti, landmark=lm, range=zi[0], bearing=zi[1], cov=(tuple(ci[0]), tuple(ci[1]))))
                for ti, lm, zi, ci in zip(times, landmarks, zr.tolist(), covs.tolist())]  # fmt: skip
    sensor = None
    if mount is not None:
        sensors[frame] = mount
        sensor = frame
    if xy:
        return [(ti, Observation(t=ti, landmark=lm, xy=(zi[0], zi[1]), sigma=sigma, sensor=sensor))
                for ti, lm, zi in zip(times, landmarks, z.tolist())]  # fmt: skip
    return [(ti, Observation(t=ti, landmark=lm, range=zi[0], bearing=zi[1], sigma=sigma, sensor=sensor))
            for ti, lm, zi in zip(times, landmarks, z.tolist())]  # fmt: skip


def _tuples(matrix: Array) -> tuple[tuple[float, ...], ...]:
    return tuple(map(tuple, np.asarray(matrix, dtype=float).tolist()))


def _noise(path: Path, o: BagOptions, ds: Array, da: Array) -> Array:
    """Diagonal increment covariances from the options (n, 3, 3)."""
    if o.odom_sigma is None and o.odom_sigma_per_m is None:
        raise InputError(str(path), 0, "odom_sigma", f"topic {o.odom}: no covariance in its messages: give "
                         "--odom-sigma SX,SY,STH")  # fmt: skip
    sigma = np.array(o.odom_sigma or (0.0, 0.0, 0.0), dtype=float)
    per_m = np.array(o.odom_sigma_per_m or (0.0, 0.0, 0.0), dtype=float)
    v = variances(ds, da, sigma, per_m, o.odom_sigma_per_rad or 0.0)
    out = np.zeros((len(v), 3, 3))
    out[:, [0, 1, 2], [0, 1, 2]] = v
    return out


def _odometry(path: Path, table: Table, o: BagOptions) -> tuple[Array, Array, Array, Array, Array]:
    a = table.array
    times, poses = a[:, 0], a[:, 1:4]
    if np.any(np.diff(times) <= 0):
        k = int(np.flatnonzero(np.diff(times) <= 0)[0])
        raise InputError(str(path), 0, "odom", f"topic {o.odom}: two messages stamped {times[k]:.9g}")
    increments = between(poses[:-1], poses[1:])
    ds, da = np.hypot(increments[:, 0], increments[:, 1]), np.abs(increments[:, 2])
    given = a[1:, 4:].reshape(-1, 3, 3)
    has = np.any(given != 0.0, axis=(1, 2))
    cov = given.copy()
    if not np.all(has):
        cov[~has] = _noise(path, o, ds[~has], da[~has])
    if np.any(np.linalg.eigvalsh(0.5 * (cov + np.swapaxes(cov, 1, 2)))[:, 0] <= 0):
        raise InputError(str(path), 0, "odom", f"topic {o.odom}: a message's covariance is not positive definite")
    relative = between(np.broadcast_to(poses[0], poses.shape), poses)
    path_m = np.r_[0.0, np.cumsum(ds)]
    return times, poses if o.start_from_truth is None else relative, path_m, np.r_[0.0, np.cumsum(da)], cov


def _twist(
    path: Path, table: Table, o: BagOptions, sightings: list[tuple[float, Observation]], tables: dict[str, Table]
) -> tuple[Array, Array, Array, Array, Array]:
    a = table.array
    t_in = a[:, 0]
    v, w = ackermann(a[:, 1], a[:, 2], o.steer[0], o.steer[1]) if o.steer else (a[:, 1], a[:, 2])
    first_seen = [tables[n].times[0] for n in ("landmarks", "scan") if n in tables and tables[n].times]
    seen = np.array([t for t, _ in sightings])
    start = float(min([t_in[0], *first_seen]))
    end = float(max(t_in[-1], seen[-1] if len(seen) else start))
    times = pose_times(start, np.unique(seen), end, o.pose_gap or 1.0)
    poses, path_m, turn = integrate(t_in, v, w, times)
    return times, poses, path_m, turn, _noise(path, o, np.diff(path_m), np.diff(turn))


def _origin(tables: dict[str, Table], o: BagOptions) -> tuple[float, float] | None:
    if o.fix_origin is not None:
        return (o.fix_origin[0], o.fix_origin[1])
    for name in ("fix", "truth"):
        table = tables.get(name)
        if table is not None and table.msgtype == NAVSAT and len(table.array):
            return (float(table.array[0, 1]), float(table.array[0, 2]))
    return None


def _truth(table: Table | None, times: Array, o: BagOptions, origin: Any) -> tuple[Array, NDArray[np.bool_]]:
    if table is None or len(table.array) == 0:
        return np.zeros((len(times), 3)), np.zeros(len(times), dtype=bool)
    a = table.array
    gap, speed = o.truth_gap or 0.5, o.truth_speed or math.inf
    if table.msgtype in (NAVSAT, POINT):
        plane = local_plane(a[:, 1], a[:, 2], origin) if table.msgtype == NAVSAT else a[:, 1:3]
        xy, ok = truth_at(np.column_stack([a[:, 0], plane]), times, gap, speed)
        return np.column_stack([xy, np.full(len(times), math.nan)]), ok
    fixes = np.column_stack([a[:, 0:3], np.unwrap(a[:, 3])])
    pose, ok = truth_at(fixes, times, gap, speed)
    return np.column_stack([pose[:, :2], wrap(pose[:, 2])]), ok


def _start_from_truth(
    path: Path, poses: Array, path_m: Array, truth: Array, covered: NDArray[np.bool_], distance: float,
    antenna: tuple[float, float] | None,
) -> Array:  # fmt: skip
    if not covered.any():
        raise InputError(str(path), 0, "start_from_truth", "no truth at any pose")
    if np.isnan(truth[covered][0, 2]):  # positions of the antenna: its dead-reckoned track onto them
        track = poses if antenna is None else fixed_point(poses, antenna)
        return start_from_positions(track, path_m, truth[:, :2], covered, distance)
    k = int(np.flatnonzero(covered)[0])
    return compose(truth[k], inverse(between(poses[0], poses[k])))


def _fixes(path: Path, bag: Bag, o: BagOptions, base: str, origin: Any) -> list[Position]:
    table = bag.tables.get("fix")
    if table is None or len(table.array) == 0:
        return []
    a = table.array
    if table.msgtype == POINT:
        xy = a[:, 1:3]
        known = np.zeros(len(a), dtype=bool)
        given = np.zeros((len(a), 2, 2))
    else:
        xy = local_plane(a[:, 1], a[:, 2], origin)
        known, given = a[:, 3] > 0, a[:, 4:8].reshape(-1, 2, 2)
    if not known.all() and o.fix_sigma is None:
        raise InputError(str(path), 0, "fix_sigma", f"topic {o.fix}: fixes without a covariance: give --fix-sigma S")
    out = []
    for k in range(len(a)):
        offset = _offset(path, bag, table.msgtype, table.labels[k], base, "fix")
        noise: dict[str, Any] = {"cov": _tuples(given[k])} if known[k] else {"sigma": (o.fix_sigma, o.fix_sigma)}
        out.append(Position(t=float(a[k, 0]), xy=(float(xy[k, 0]), float(xy[k, 1])), offset=offset, **noise))
    return out


def _offset(path: Path, bag: Bag, msgtype: str, frame: str, base: str, option: str) -> tuple[float, float] | None:
    """The antenna a position message is of: its frame's mounting (x, y), or None (the robot's centre); a
    NavSatFix's frame must be mounted, a PointStamped's may be a map frame (none)."""
    mount = _mount(path, bag, frame, base, option, strict=msgtype == NAVSAT)
    return None if mount is None else (mount[0], mount[1])


def _truth_offset(path: Path, bag: Bag, base: str) -> tuple[float, float] | None:
    """The antenna of position-only truth (one frame per topic: interpolating between two points means nothing)."""
    table = bag.tables.get("truth")
    if table is None or table.msgtype not in (NAVSAT, POINT) or not table.labels:
        return None
    frames = sorted(set(table.labels))
    if len(frames) > 1:
        raise InputError(str(path), 0, "truth", f"truth messages in frames {', '.join(map(repr, frames))}: one frame "
                         "per topic")  # fmt: skip
    return _offset(path, bag, table.msgtype, frames[0], base, "truth")
