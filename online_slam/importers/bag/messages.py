"""Reading a bag's topics into arrays with ``rosbags``: one table per topic, sorted by header stamp.

Each message's time is its header's stamp (a marker's own header), never the bag's record time. Messages of one
topic are sorted by that stamp (stable), so a topic recorded out of order reads as if it had not been.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import InputError
from online_slam.importers.laser import Detector, detect_many

Array = NDArray[np.float64]

ODOMETRY, TWIST, MARKERS, SCAN = "nav_msgs/msg/Odometry", "geometry_msgs/msg/TwistStamped", \
    "visualization_msgs/msg/MarkerArray", "sensor_msgs/msg/LaserScan"  # fmt: skip
NAVSAT, POINT, POSE, TF = "sensor_msgs/msg/NavSatFix", "geometry_msgs/msg/PointStamped", \
    "geometry_msgs/msg/PoseStamped", "tf2_msgs/msg/TFMessage"  # fmt: skip
TYPES = {
    "odom": (ODOMETRY, TWIST),
    "landmarks": (MARKERS,),
    "scan": (SCAN,),
    "fix": (NAVSAT, POINT),
    "truth": (ODOMETRY, POSE, NAVSAT, POINT),
}
"""The message types each topic option reads."""
TF_STATIC = "/tf_static"
"""The topic of the sensors' mountings."""


@dataclass
class Table:
    """One topic's messages as rows (lists while reading, sorted arrays after :meth:`done`)."""

    msgtype: str
    rows: list[tuple[float, ...]] = field(default_factory=list)
    """Numbers per row; the first is the time."""
    labels: list[Any] = field(default_factory=list)
    """Per row, what is not a number (a frame, a landmark id), or nothing."""
    times: list[float] = field(default_factory=list)
    """Every message's time (a scan without landmarks too)."""
    scans: list[tuple] = field(default_factory=list)
    """A LaserScan topic's scans until the detector runs (:func:`detect_scans`)."""
    array: Array = field(default_factory=lambda: np.zeros((0, 1)))

    def done(self, width: int) -> None:
        """Sort the rows by time (stable) into :attr:`array`."""
        table = np.array(self.rows, dtype=float).reshape(-1, width)
        order = np.argsort(table[:, 0], kind="stable")
        self.array = table[order]
        self.labels = [self.labels[i] for i in order] if self.labels else []
        self.rows = []


def stamp(header: Any) -> float:
    """A header's stamp, seconds."""
    return (header.stamp.sec * 1_000_000_000 + header.stamp.nanosec) / 1e9


def yaw(q: Any) -> float:
    """The heading of a quaternion (rotation about z), radians."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _odometry(table: Table, msg: Any) -> None:
    pose = msg.pose.pose
    cov = np.asarray(msg.pose.covariance, dtype=float).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])]
    table.rows.append((stamp(msg.header), pose.position.x, pose.position.y, yaw(pose.orientation), *cov.ravel()))


def _pose(table: Table, msg: Any) -> None:
    table.rows.append((stamp(msg.header), msg.pose.position.x, msg.pose.position.y, yaw(msg.pose.orientation)))


def _twist(table: Table, msg: Any) -> None:
    table.rows.append((stamp(msg.header), msg.twist.linear.x, msg.twist.angular.z))


def _twist_row(raw: bytes, cdr: bool) -> tuple[float, float, float]:
    """A TwistStamped's time, linear.x and angular.z, read by layout (the hot path: wheel odometry at 40-100 Hz).

    Both encodings put the stamp at bytes 4..12 (after CDR's encapsulation header, after ROS 1's ``seq``) and the
    twist's six float64 last; little-endian (checked against ``rosbags`` on each connection's first message).
    """
    sec, nanosec = struct.unpack_from("<iI" if cdr else "<II", raw, 4)
    vx, _, _, _, _, wz = struct.unpack_from("<6d", raw, len(raw) - 48)
    return ((sec * 1_000_000_000 + nanosec) / 1e9, vx, wz)


def _twist_layout(reader: Any, connection: Any, raw: bytes) -> bool:
    """Whether a connection's TwistStamped messages read by :func:`_twist_row` as ``rosbags`` reads them."""
    if reader.is2 and raw[1] != 1:  # big-endian CDR
        return False
    try:
        msg = reader.deserialize(raw, connection.msgtype)
    except Exception:  # noqa: BLE001 - the slow path reports it
        return False
    return _twist_row(raw, reader.is2) == (stamp(msg.header), msg.twist.linear.x, msg.twist.angular.z)


def _scan_layout(reader: Any, connection: Any, raw: bytes) -> bool:
    """Whether a connection's LaserScans read by :func:`_scan_row` as ``rosbags`` reads them."""
    if reader.is2 and raw[1] != 1:
        return False
    try:
        return _same_scan(_scan_row(raw, reader.is2), _scan_fields(reader.deserialize(raw, connection.msgtype)))
    except Exception:  # noqa: BLE001 - not this layout: the slow path reads (or reports) it
        return False


def _markers(table: Table, msg: Any) -> None:
    for marker in msg.markers:
        if marker.action != 0:  # DELETE, DELETEALL: no sighting
            continue
        t = stamp(marker.header)
        table.times.append(t)
        table.rows.append((t, marker.pose.position.x, marker.pose.position.y))
        landmark = f"{marker.ns}/{marker.id}" if marker.ns else int(marker.id)
        table.labels.append((marker.header.frame_id, landmark))


def _navsat(table: Table, msg: Any) -> None:
    if msg.status.status < 0:  # STATUS_NO_FIX
        return
    cov = np.asarray(msg.position_covariance, dtype=float).reshape(3, 3)[:2, :2]  # east, north
    known = float(msg.position_covariance_type > 0)
    table.rows.append((stamp(msg.header), msg.latitude, msg.longitude, known, *cov.ravel()))
    table.labels.append(msg.header.frame_id)


def _point(table: Table, msg: Any) -> None:
    table.rows.append((stamp(msg.header), msg.point.x, msg.point.y))
    table.labels.append(msg.header.frame_id)


def _scan_fields(msg: Any) -> tuple[float, str, tuple[float, ...], Array, Array]:
    """A LaserScan's time, frame, (angle_min, angle_increment, range_min, range_max), ranges and intensities."""
    values = (msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max)
    return stamp(msg.header), msg.header.frame_id, values, np.asarray(msg.ranges), np.asarray(msg.intensities)


def _scan_row(raw: bytes, cdr: bool) -> tuple[float, str, tuple[float, ...], Array, Array]:
    """A LaserScan read by layout (the heavy path: a scan is hundreds of floats): the header (stamp at bytes 4..12,
    then the frame's length and text, NUL-terminated in CDR), seven float32, then the ranges and the intensities
    as float32 sequences; little-endian, CDR aligned from byte 4 (checked against ``rosbags`` per connection)."""
    sec, nanosec, size = struct.unpack_from("<iII" if cdr else "<III", raw, 4)
    frame = raw[16 : 16 + size].rstrip(b"\0").decode()
    at = 16 + size
    at += (-(at - 4)) % 4 if cdr else 0
    angle_min, _, increment, _, _, range_min, range_max, n = struct.unpack_from("<7fI", raw, at)
    ranges = np.frombuffer(raw, "<f4", n, at + 32)
    (m,) = struct.unpack_from("<I", raw, at + 32 + 4 * n)
    intensities = np.frombuffer(raw, "<f4", m, at + 36 + 4 * n)
    return (sec * 1_000_000_000 + nanosec) / 1e9, frame, (angle_min, increment, range_min, range_max), ranges, \
        intensities  # fmt: skip


def _scan(table: Table, msg: Any) -> None:
    table.scans.append(_scan_fields(msg))


def _same_scan(a: tuple, b: tuple) -> bool:
    return a[:3] == b[:3] and np.array_equal(a[3], b[3]) and np.array_equal(a[4], b[4])


LAYOUTS: dict[str, tuple[Callable[[Any, Any, bytes], bool], Callable[[bytes, bool], Any], Callable[[Table], list]]] = {
    TWIST: (_twist_layout, _twist_row, lambda table: table.rows),
    SCAN: (_scan_layout, _scan_row, lambda table: table.scans),
}
"""Message types read by their byte layout (checked against rosbags on each connection's first message): the check,
the row read from the raw bytes, and the table's list it goes to."""


def detect_scans(table: Table, topic: str, detector: Detector) -> None:
    """Run the laser detector over a scan table's scans (those of one length at once) into its rows."""
    scans, table.scans = table.scans, []
    if detector.min_intensity is not None and any(len(s[4]) != len(s[3]) for s in scans):
        raise InputError(topic, 0, "scan_intensity", "a scan carries no intensities")
    table.times = [s[0] for s in scans]
    lengths = np.array([len(s[3]) for s in scans])
    for n in np.unique(lengths):
        index = np.flatnonzero(lengths == n)
        params = np.array([scans[i][2] for i in index], dtype=float).reshape(-1, 4)
        ranges = np.stack([scans[i][3] for i in index]) if n else np.zeros((len(index), 0))
        strong = np.stack([scans[i][4] for i in index]) if detector.min_intensity is not None and n else None
        found, keep, of = detect_many(ranges, params[:, 0], params[:, 1], params[:, 2], params[:, 3], detector,
                                      strong)  # fmt: skip
        for (r, b, _), kept, k in zip(found.tolist(), keep.tolist(), of.tolist()):
            table.rows.append((scans[index[k]][0], r, b, float(kept)))
            table.labels.append(scans[index[k]][1])


WIDTHS = {ODOMETRY: 13, POSE: 4, TWIST: 3, MARKERS: 3, NAVSAT: 8, POINT: 3, SCAN: 4}
"""Numbers per row of each message type's table."""


def _readers() -> dict[str, Callable[[Table, Any], None]]:
    return {ODOMETRY: _odometry, POSE: _pose, TWIST: _twist, MARKERS: _markers, NAVSAT: _navsat, POINT: _point,
            SCAN: _scan}  # fmt: skip


@dataclass
class Bag:
    """The topics read: a table per topic option, and the mountings of /tf_static."""

    tables: dict[str, Table]
    """By option name (``odom``, ``landmarks``, ...)."""
    tf: dict[str, tuple[str, float, float, float]]
    """Child frame -> (parent frame, x, y, yaw) of /tf_static."""
    messages: int
    """Messages read."""


def read_topics(path: Path, topics: dict[str, str], detector: Detector) -> Bag:
    """Read the topics (option name -> topic) and /tf_static.

    Raises:
        InputError: The bag cannot be read; a topic is missing or of a type its option does not read.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise InputError(str(path), 0, "", f"not a readable ROS bag: {exc}") from None
    try:
        return _read(reader, path, topics, detector)
    finally:
        reader.close()


def _read(reader: Any, path: Path, topics: dict[str, str], detector: Detector) -> Bag:
    present = {name: info.msgtype for name, info in reader.topics.items()}
    tables: dict[str, Table] = {}
    by_topic: dict[str, list[tuple[Table, Callable[[Table, Any], None]]]] = {}
    for option_name, topic in topics.items():
        if topic not in present:
            listed = ", ".join(sorted(present)) or "none"
            raise InputError(str(path), 0, option_name, f"no topic {topic} in the bag (its topics: {listed})")
        msgtype = present[topic]
        if msgtype not in TYPES[option_name]:
            wanted = " or ".join(TYPES[option_name])
            raise InputError(str(path), 0, option_name, f"topic {topic} is {msgtype}; --{option_name} reads {wanted}")
        table = tables[option_name] = Table(msgtype)
        by_topic.setdefault(topic, []).append((table, _readers()[msgtype]))
    tf: dict[str, tuple[str, float, float, float]] = {}
    wanted_topics = set(by_topic) | ({TF_STATIC} if present.get(TF_STATIC) == TF else set())
    connections = [c for c in reader.connections if c.topic in wanted_topics]
    count = 0
    fast: dict[int, bool] = {}  # connection id -> its twists decode by layout (checked on its first message)
    for connection, _, raw in reader.messages(connections=connections):
        count += 1
        layout = LAYOUTS.get(connection.msgtype) if connection.topic != TF_STATIC else None
        if layout is not None:
            check, row, into = layout
            if connection.id not in fast:
                fast[connection.id] = check(reader, connection, raw)
            if fast[connection.id]:
                for table, _ in by_topic[connection.topic]:
                    into(table).append(row(raw, reader.is2))
                continue
        try:
            msg = reader.deserialize(raw, connection.msgtype)
        except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds on a damaged message
            raise InputError(str(path), 0, connection.topic, f"cannot decode a message: {exc}") from None
        if connection.topic == TF_STATIC:
            for tr in msg.transforms:
                v = tr.transform.translation
                tf[tr.child_frame_id] = (tr.header.frame_id, v.x, v.y, yaw(tr.transform.rotation))
            continue
        for table, read in by_topic[connection.topic]:
            read(table, msg)
    for name, table in tables.items():
        if table.msgtype == SCAN:
            detect_scans(table, topics[name], detector)
        table.done(WIDTHS[table.msgtype])
        table.times.sort()
    return Bag(tables, tf, count)
