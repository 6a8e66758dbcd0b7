"""Write ROS bags with ``rosbags``' writers: the raw Victoria Park log as its robot would have recorded it, and a
stream's odometry and sightings (``Odometry`` + ``MarkerArray``). Not installed with the package.

``python -m benchmarks.bags victoria-park RAW_FOLDER OUT [--until T]`` writes ``OUT.mcap`` (a ROS 2 bag in MCAP
storage, one file) and ``OUT.bag`` (ROS 1). What is written, for ``online-slam replay OUT.mcap`` with the options
of :data:`VP_OPTIONS` to give the acfr importer's events:

- ``/wheels`` (``geometry_msgs/msg/TwistStamped``, 40 Hz): ``linear.x`` the rear-left wheel's speed and
  ``angular.z`` the steering angle, as the encoders give them (``--steer 2.83,0.76``: the car's wheelbase and the
  wheel's offset);
- ``/scan`` (``sensor_msgs/msg/LaserScan``) at each laser time with trees, in frame ``laser`` (x to the car's
  right, so the scan's angles run 0..pi from right to left as the log's bearings do; ``/tf_static`` mounts it at
  (3.78, 0.50) facing -90 degrees). The raw scans are not in the log, only the detections: each scan is made
  from them, a run of returns per tree at the range and over the beams that the laser detector turns back into
  the detection printed to 5 decimals (``--scan-decimals 5``). Ranges and angles are float32 in a LaserScan; the
  scan's ``angle_min`` (within 1e-7 rad of 0) is chosen so that its float32 beam angles round to the log's
  bearings. The writer checks that the detector gives back every detection;
- ``/tf_static``: the laser's mounting, and the GPS antenna's (frame ``gps`` at the acfr importer's
  :data:`~online_slam.importers.acfr.GPS_ANTENNA`, ahead of and left of the rear axle's centre);
- ``/gps`` (``sensor_msgs/msg/NavSatFix``, frame ``gps``): the log's GPS x, y as east, north about
  :data:`VP_ORIGIN`.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from online_slam.importers.acfr import GPS_ANTENNA
from online_slam.importers.bag.reader import from_local_plane
from online_slam.importers.laser import Detector, detect
from online_slam.sources.events import Event, Observation, Odometry, Start, Truth

VP_ORIGIN = (-33.8888, 151.1930)
"""Latitude and longitude given to the log's GPS origin (Victoria Park, Sydney; the log's frame is local)."""
VP_OPTIONS = {
    "odom": "/wheels", "scan": "/scan", "truth": "/gps", "steer": (2.83, 0.76),
    "odom_sigma": (0.001, 0.001, 0.001), "odom_sigma_per_m": (0.02, 0.02, 0.005), "odom_sigma_per_rad": 0.02,
    "range_sigma": 0.2, "bearing_sigma": 0.005, "scan_range": (3.0, 25.0), "scan_bearing": (6.3, 177.0),
    "scan_decimals": 5, "sensor_to_base": True, "fix_origin": VP_ORIGIN, "truth_speed": 10.0,
    "start_from_truth": 20.0,
}  # fmt: skip
"""The bag importer's options that read the Victoria Park bag as the acfr importer reads the raw log."""
BEAMS, INCREMENT = 361, math.pi / 360
"""The ACFR laser: 361 beams over 0..pi."""
F32_INCREMENT = float(np.float32(INCREMENT))


class BagWriter:
    """One bag being written: ROS 1 (``.bag``) or ROS 2 in MCAP storage."""

    def __init__(self, writer: Any, typestore: Any, ros1: bool) -> None:
        self.writer, self.ts, self.ros1 = writer, typestore, ros1
        self.connections: dict[str, Any] = {}
        self.count = 0
        """Messages written."""

    def msg(self, name: str, **fields: Any) -> Any:
        """A message of type ``name`` (``pkg/msg/Type``)."""
        return self.ts.types[name](**fields)

    def header(self, t: float, frame: str) -> Any:
        """A header stamped ``t`` seconds."""
        ns = round(t * 1e9)
        stamp = self.msg("builtin_interfaces/msg/Time", sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        extra = {"seq": 0} if self.ros1 else {}
        return self.msg("std_msgs/msg/Header", stamp=stamp, frame_id=frame, **extra)

    def write(self, topic: str, t: float, message: Any) -> None:
        """Write ``message`` on ``topic``, recorded at ``t``."""
        msgtype = message.__msgtype__
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.ts)
        raw = self.ts.serialize_ros1(message, msgtype) if self.ros1 else self.ts.serialize_cdr(message, msgtype)
        self.writer.write(self.connections[topic], round(t * 1e9), raw)
        self.count += 1

    def vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
        """A ``geometry_msgs/msg/Vector3``."""
        return self.msg("geometry_msgs/msg/Vector3", x=x, y=y, z=z)

    def quaternion(self, theta: float) -> Any:
        """The rotation by ``theta`` about z."""
        return self.msg("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2))

    def pose(self, x: float, y: float, theta: float) -> Any:
        """A ``geometry_msgs/msg/Pose`` in the plane."""
        point = self.msg("geometry_msgs/msg/Point", x=x, y=y, z=0.0)
        return self.msg("geometry_msgs/msg/Pose", position=point, orientation=self.quaternion(theta))

    def mount(self, t: float, parent: str, child: str, pose: tuple[float, float, float]) -> None:
        """A ``/tf_static`` message mounting ``child`` at ``pose`` in ``parent``."""
        transform = self.msg("geometry_msgs/msg/Transform", translation=self.vector(pose[0], pose[1]),
                             rotation=self.quaternion(pose[2]))  # fmt: skip
        stamped = self.msg("geometry_msgs/msg/TransformStamped", header=self.header(t, parent), child_frame_id=child,
                           transform=transform)  # fmt: skip
        self.write("/tf_static", t, self.msg("tf2_msgs/msg/TFMessage", transforms=[stamped]))


@contextmanager
def open_bag(path: str | Path, ros1: bool) -> Iterator[BagWriter]:
    """A new bag at ``path`` (a ``.bag`` file, or a ``.mcap`` file written through a ROS 2 bag folder)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    target = Path(path)
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        ts = get_typestore(Stores.ROS1_NOETIC)
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
        with Writer1(target) as writer:
            yield BagWriter(writer, ts, True)
        return
    from rosbags.rosbag2 import StoragePlugin, Writer

    folder = target.with_suffix("")
    with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        yield BagWriter(writer, get_typestore(Stores.ROS2_HUMBLE), False)
    (folder / f"{folder.name}.mcap").rename(target)  # one file: rosbags reads a bare .mcap
    for leftover in folder.iterdir():
        leftover.unlink()
    folder.rmdir()


def _scan_of(rows: np.ndarray) -> tuple[np.ndarray, float]:
    """A scan (361 float32 ranges, inf where no tree) whose detections are ``rows`` (range, bearing, diameter),
    and its angle_min."""
    r, b, d = rows.T
    s = np.round(2 * b / INCREMENT)  # first + last beam of each tree
    guess = np.maximum(np.round(d / (INCREMENT * (r - d / 2))), 1)
    n = np.where(guess % 2 == (s + 1) % 2, guess, guess + 1)  # a beam count of the right parity
    ranges = np.full(BEAMS, np.inf, dtype=np.float32)
    for si, ni, ri in zip(s, n, r):
        first = int((si - ni + 1) // 2)
        ranges[first : first + int(ni)] = np.float32(ri / (1 + ni * F32_INCREMENT / 2))
    v = 0.5 * s * F32_INCREMENT
    low, high = np.max(b - 5e-6 - v), np.min(b + 5e-6 - v)
    angle_min = 0.0 if low < 0.0 < high else float(np.float32((low + high) / 2))
    return ranges, angle_min


def write_victoria_park(raw: str | Path, out: str | Path, ros1: bool, until: float | None = None) -> int:
    """Write the raw Victoria Park log (up to ``until`` seconds) as a bag; the number of messages."""
    root = Path(raw)
    inputs, measurements, gps = (np.loadtxt(root / f, ndmin=2) for f in ("inputs.dat", "measurements.dat", "gps.dat"))
    if until is not None:
        inputs, measurements, gps = (a[a[:, 0] <= until] for a in (inputs, measurements, gps))
    lat, lon = from_local_plane(gps[:, 1:3], VP_ORIGIN)
    records: list[tuple[float, int, str, Any]] = []
    with open_bag(out, ros1) as bag:
        bag.mount(0.0, "base_link", "laser", (3.78, 0.50, -math.pi / 2))
        bag.mount(0.0, "base_link", "gps", (*GPS_ANTENNA, 0.0))  # the antenna the log's GPS is the position of
        for t, speed, steer in inputs:
            twist = bag.msg("geometry_msgs/msg/Twist", linear=bag.vector(speed), angular=bag.vector(z=steer))
            stamped = bag.msg("geometry_msgs/msg/TwistStamped", header=bag.header(t, "base_link"), twist=twist)
            records.append((t, 0, "/wheels", stamped))
        times, starts = np.unique(measurements[:, 0], return_index=True)
        for t, a, z in zip(times, starts, np.r_[starts[1:], len(measurements)]):
            ranges, angle_min = _scan_of(measurements[a:z, 1:4])
            scan = bag.msg("sensor_msgs/msg/LaserScan", header=bag.header(t, "laser"), angle_min=angle_min,
                           angle_max=float(np.float32(math.pi)), angle_increment=F32_INCREMENT, time_increment=0.0,
                           scan_time=0.0, range_min=0.0, range_max=81.91, ranges=ranges,
                           intensities=np.zeros(0, dtype=np.float32))  # fmt: skip
            _check_scan(scan, measurements[a:z, 1:3])
            records.append((t, 1, "/scan", scan))
        status = bag.msg("sensor_msgs/msg/NavSatStatus", status=0, service=1)
        for (t, _, _), la, lo in zip(gps, lat, lon):
            fix = bag.msg("sensor_msgs/msg/NavSatFix", header=bag.header(t, "gps"), status=status, latitude=la,
                          longitude=lo, altitude=0.0, position_covariance=np.zeros(9),
                          position_covariance_type=0)  # fmt: skip
            records.append((t, 2, "/gps", fix))
        records.sort(key=lambda item: item[:2])
        for t, _, topic, message in records:
            bag.write(topic, t, message)
    return bag.count


def _check_scan(scan: Any, expected: np.ndarray) -> None:
    """The detector must give back the log's detections (range, bearing) from the scan made of them."""
    found, _ = detect(scan.ranges, scan.angle_min, scan.angle_increment, (scan.range_min, scan.range_max),
                      Detector(decimals=5))  # fmt: skip
    if found.shape[0] != len(expected) or np.any(found[:, :2] != expected):
        raise ValueError(f"the scan at t={scan.header.stamp.sec}.{scan.header.stamp.nanosec:09d} does not give back "
                         "its detections")  # fmt: skip


def write_stream_bag(events: Iterable[Event], out: str | Path, ros1: bool) -> int:
    """Write a one-robot stream's odometry (``/odom``: poses composed from the start, the increment's covariance
    in the pose covariance), its landmark sightings (``/landmarks``: a marker per sighting with an integer id, at
    its position in ``base_link``) and its truth (``/truth``: Odometry) as a bag; the number of messages."""
    from online_slam.geometry.se2 import compose

    pose = None
    with open_bag(out, ros1) as bag:

        def odometry(topic: str, t: float, p: Any, cov: np.ndarray) -> None:
            full = np.zeros((6, 6))
            full[np.ix_([0, 1, 5], [0, 1, 5])] = cov
            stamped = bag.msg("geometry_msgs/msg/PoseWithCovariance", pose=bag.pose(*map(float, p)),
                              covariance=full.ravel())  # fmt: skip
            twist = bag.msg("geometry_msgs/msg/TwistWithCovariance",
                            twist=bag.msg("geometry_msgs/msg/Twist", linear=bag.vector(), angular=bag.vector()),
                            covariance=np.zeros(36))  # fmt: skip
            bag.write(topic, t, bag.msg("nav_msgs/msg/Odometry", header=bag.header(t, "odom"),
                                        child_frame_id="base_link", pose=stamped, twist=twist))  # fmt: skip

        for event in events:
            if isinstance(event, Start):
                pose = np.array(event.pose)
                odometry("/odom", event.t, pose, np.zeros((3, 3)))
            elif isinstance(event, Odometry):
                pose = compose(pose, np.array(event.delta))
                odometry("/odom", event.t, pose, event.covariance)
            elif isinstance(event, Truth):
                odometry("/truth", event.t, event.pose, np.zeros((3, 3)))
            elif isinstance(event, Observation) and event.range is not None:
                x, y = event.range * math.cos(event.bearing), event.range * math.sin(event.bearing)
                marker = bag.msg(
                    "visualization_msgs/msg/Marker", **_marker_fields(bag, event.t, int(event.landmark), x, y)
                )
                bag.write("/landmarks", event.t, bag.msg("visualization_msgs/msg/MarkerArray", markers=[marker]))
    return bag.count


def _marker_fields(bag: BagWriter, t: float, landmark: int, x: float, y: float) -> dict[str, Any]:
    """A sphere marker's fields (ROS 2's Marker has texture fields that ROS 1's has not)."""
    fields = {f for f in bag.ts.types["visualization_msgs/msg/Marker"].__dataclass_fields__}
    color = bag.msg("std_msgs/msg/ColorRGBA", r=0.0, g=0.8, b=0.0, a=1.0)
    out: dict[str, Any] = {"header": bag.header(t, "base_link"), "ns": "", "id": landmark, "type": 2, "action": 0,
        "pose": bag.pose(x, y, 0.0), "scale": bag.vector(0.3, 0.3, 0.3), "color": color,
        "lifetime": bag.msg("builtin_interfaces/msg/Duration", sec=0, nanosec=0), "frame_locked": False,
        "points": [], "colors": [], "text": "", "mesh_resource": "", "mesh_use_embedded_materials": False}  # fmt: skip
    if "texture" in fields:
        empty = np.zeros(0, dtype=np.uint8)
        image = bag.msg("sensor_msgs/msg/CompressedImage", header=bag.header(t, ""), format="", data=empty)
        mesh = bag.msg("visualization_msgs/msg/MeshFile", filename="", data=empty)
        out.update(texture_resource="", texture=image, uv_coordinates=[], mesh_file=mesh)
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.bags victoria-park RAW OUT [--until T]``: OUT.mcap and OUT.bag."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.bags", description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=("victoria-park",))
    p.add_argument("raw", help="the raw Victoria Park folder (inputs.dat, measurements.dat, gps.dat)")
    p.add_argument("out", help="output path without suffix: writes OUT.mcap and OUT.bag")
    p.add_argument("--until", type=float, help="only the log up to T seconds")
    args = p.parse_args(argv)
    for suffix, ros1 in ((".mcap", False), (".bag", True)):
        n = write_victoria_park(args.raw, args.out + suffix, ros1, args.until)
        print(f"wrote {args.out}{suffix}: {n} messages")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


def time_reading(raw: str | Path, repeats: int, until: float | None = None) -> list[tuple[str, int, float, float]]:
    """Write the log's bags to a temporary folder and time reading them: per storage, the messages, the best
    seconds of reading the topics (decoding, the laser detector), and of reading them into events."""
    import tempfile
    import time

    from online_slam.importers.bag import BagOptions
    from online_slam.importers.bag.messages import read_topics
    from online_slam.importers.bag.reader import _detector, read_bag

    options = BagOptions(**VP_OPTIONS)  # type: ignore[arg-type]
    topics = {"odom": "/wheels", "scan": "/scan", "truth": "/gps"}
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name, ros1 in (("ROS 2 MCAP", False), ("ROS 1", True)):
            path = Path(folder) / ("vp.bag" if ros1 else "vp.mcap")
            write_victoria_park(raw, path, ros1, until)
            read_topics(path, topics, _detector(options))  # imports and type generation, once
            best_read, best_events, messages = math.inf, math.inf, 0
            for _ in range(repeats):
                start = time.perf_counter()
                messages = read_topics(path, topics, _detector(options)).messages
                best_read = min(best_read, time.perf_counter() - start)
                start = time.perf_counter()
                sum(1 for _ in read_bag(path, options))
                best_events = min(best_events, time.perf_counter() - start)
            rows.append((name, messages, best_read, best_events))
    return rows
