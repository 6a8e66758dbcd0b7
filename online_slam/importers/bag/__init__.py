"""ROS bags, as an importer plug-in: ROS 1 bags (``.bag``), ROS 2 bags (a folder with ``metadata.yaml``, or one
``.mcap`` or ``.db3`` file), read by ``rosbags`` without a ROS install (:mod:`.reader`).

Topics are named by options: the odometry (``nav_msgs/msg/Odometry`` or ``geometry_msgs/msg/TwistStamped``),
landmark sightings (``visualization_msgs/msg/MarkerArray``, or a ``sensor_msgs/msg/LaserScan`` through a landmark
detector), position fixes and truth. Every option is None when not given; the reader applies the defaults its
help names.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from online_slam.importers.registry import option
from online_slam.sources.events import Event

SUFFIXES = (".bag", ".mcap", ".db3")
"""A ROS 1 bag, a ROS 2 bag's MCAP or sqlite3 file."""


def floats(count: int) -> Callable[[str], tuple[float, ...]]:
    """The parser of ``count`` comma-separated numbers (``count`` 0: any number of them)."""

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(v) for v in str(text).split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
        if count and len(values) != count:
            raise argparse.ArgumentTypeError(f"expected {count} comma-separated numbers, got {text!r}")
        return values

    return parse


@dataclass(frozen=True)
class BagOptions:
    """Which topics to read and how (:mod:`.reader`)."""

    odom: str | None = option(
        None, "ROS bag: the odometry topic (nav_msgs/msg/Odometry, or geometry_msgs/msg/TwistStamped, integrated)",
        metavar="TOPIC", required=True,
    )  # fmt: skip
    """Odometry: increments between consecutive messages' poses, or a twist integrated between messages."""
    landmarks: str | None = option(None, "ROS bag: landmark sightings (visualization_msgs/msg/MarkerArray: each "
                                   "marker's ns/id and position)", metavar="TOPIC")  # fmt: skip
    """Each marker a sighting of landmark ``id`` (``ns/id`` when ``ns`` is set) at its position."""
    scan: str | None = option(None, "ROS bag: a laser (sensor_msgs/msg/LaserScan): landmarks by the laser "
                              "detector, without ids", metavar="TOPIC")  # fmt: skip
    """Landmarks found in each scan by :func:`online_slam.importers.laser.detect`."""
    fix: str | None = option(None, "ROS bag: absolute position fixes (sensor_msgs/msg/NavSatFix or "
                             "geometry_msgs/msg/PointStamped) as position records", metavar="TOPIC")  # fmt: skip
    """Position fixes (``position`` records)."""
    truth: str | None = option(
        None, "GTSAM/iSAM text: the noise-free twin file; ROS bag: the truth topic (Odometry, PoseStamped, or "
        "NavSatFix or PointStamped: position only, of their frame's /tf_static mounting)", metavar="PATH|TOPIC",
    )  # fmt: skip
    """The truth topic, interpolated at pose times, for scoring only."""
    base_frame: str | None = option(None, "ROS bag: the robot's frame, the root of /tf_static's sensor mountings",
                                    metavar="FRAME", unset="base_link")  # fmt: skip
    """Sightings in another frame are of a sensor mounted where /tf_static says."""
    odom_sigma: tuple[float, ...] | None = option(
        None, "ROS bag: odometry noise per increment (used when the messages carry no covariance)",
        metavar="SX,SY,STH", parse=floats(3), unset="the messages' covariance",
    )  # fmt: skip
    """Standard deviations of every increment; an Odometry message's own covariance wins when it has one."""
    odom_sigma_per_m: tuple[float, ...] | None = option(
        None, "ROS bag: odometry noise growing with the distance driven (sigma per sqrt(m), added in variance)",
        metavar="SX,SY,STH", parse=floats(3), unset="none",
    )  # fmt: skip
    """Variance per metre driven: ``s^2`` per metre, added to ``--odom-sigma``'s."""
    odom_sigma_per_rad: float | None = option(
        None, "ROS bag: heading noise growing with the angle turned (sigma per sqrt(rad))", kind=float,
        metavar="STH", unset="none",
    )  # fmt: skip
    """Heading variance per radian turned."""
    steer: tuple[float, ...] | None = option(
        None, "ROS bag: TwistStamped is a car's wheel speed (linear.x) and steering angle (angular.z): its wheelbase "
        "L and the lateral offset H of the measured wheel", metavar="L,H", parse=floats(2), unset="a body twist",
    )  # fmt: skip
    """Ackermann: ``v = v_wheel / (1 - tan(steer) H / L)``, ``w = v tan(steer) / L``."""
    pose_gap: float | None = option(
        None, "ROS bag: with TwistStamped odometry, a pose at each sighting time and every S seconds between",
        kind=float, metavar="S", positive=True, unset="1 s",
    )  # fmt: skip
    """Longest time between two poses of an integrated twist, seconds."""
    xy_sigma: float | None = option(None, "ROS bag: markers as position sightings with this noise per axis",
                                    kind=float, metavar="S", positive=True)  # fmt: skip
    """Markers: ``xy`` sightings, ``[S, S]``."""
    range_sigma: float | None = option(None, "ROS bag: range noise of the scan's landmarks, and of markers read as "
                                       "range and bearing", kind=float, metavar="S", positive=True)  # fmt: skip
    """Range standard deviation, metres."""
    bearing_sigma: float | None = option(None, "ROS bag: bearing noise (rad), with --range-sigma", kind=float,
                                         metavar="S", positive=True)  # fmt: skip
    """Bearing standard deviation, radians."""
    scan_jump: float | None = option(None, "ROS bag: laser detector: neighbouring returns this far apart in range "
                                     "are different objects", kind=float, metavar="M", positive=True,
                                     unset="1 m")  # fmt: skip
    """:attr:`online_slam.importers.laser.Detector.jump`."""
    scan_range: tuple[float, ...] | None = option(None, "ROS bag: laser detector: landmark ranges kept (m)",
                                                  metavar="MIN,MAX", parse=floats(2), unset="all")  # fmt: skip
    """Range limits of the landmarks' centres."""
    scan_bearing: tuple[float, ...] | None = option(None, "ROS bag: laser detector: landmark bearings kept (degrees, "
                                                    "in the scan's angles)", metavar="MIN,MAX", parse=floats(2),
                                                    unset="all")  # fmt: skip
    """Bearing limits, degrees, in the scan's own angles."""
    scan_diameter: tuple[float, ...] | None = option(None, "ROS bag: laser detector: object diameters kept (m)",
                                                     metavar="MIN,MAX", parse=floats(2), unset="all")  # fmt: skip
    """Diameter limits: clutter and walls out."""
    scan_intensity: float | None = option(None, "ROS bag: laser detector: returns weaker than this are no object "
                                          "(reflectors)", kind=float, metavar="I", unset="not read")  # fmt: skip
    """Minimum intensity of a return."""
    scan_decimals: int | None = option(None, "ROS bag: laser detector: round range, bearing (scan angles) and "
                                       "diameter to N decimals, as a log that printed them", kind=int,
                                       metavar="N", unset="no rounding")  # fmt: skip
    """Rounding of the detections (the raw Victoria Park files hold 5 decimals)."""
    sensor_to_base: bool = option(False, "ROS bag: move each sensor's range-bearing sightings to the robot's centre "
                                  "(noise to first order) instead of declaring the sensor", kind=bool)  # fmt: skip
    """Sightings from the robot's centre, as the acfr importer gives them, instead of a ``sensors`` header."""
    fix_origin: tuple[float, ...] | None = option(None, "ROS bag: latitude and longitude (degrees) of the local "
                                                  "east-north frame of NavSatFix", metavar="LAT,LON",
                                                  parse=floats(2), unset="the first fix")  # fmt: skip
    """Origin of the local tangent plane of NavSatFix positions."""
    fix_sigma: float | None = option(None, "ROS bag: fix noise per axis (m) when a message has no covariance",
                                     kind=float, metavar="S", positive=True)  # fmt: skip
    """Standard deviation of a fix without a known covariance."""
    truth_gap: float | None = option(None, "ROS bag: truth messages bracketing a pose at most S seconds apart give "
                                     "it truth", kind=float, metavar="S", positive=True, unset="0.5 s")  # fmt: skip
    """Longest span between the two truth messages a pose's truth is interpolated between."""
    truth_speed: float | None = option(None, "ROS bag: two truth messages implying a faster motion (m/s) are a jump: "
                                       "no truth between them", kind=float, metavar="V", positive=True,
                                       unset="no limit")  # fmt: skip
    """Truth jumps (GPS) are not interpolated across."""
    start_from_truth: float | None = option(
        None, "ROS bag: start at the truth's first pose (position-only truth: the antenna at its first position, "
        "heading from the first D metres driven)", kind=float, metavar="D", unset="the odometry's frame",
    )  # fmt: skip
    """Start in the truth's frame instead of the odometry's."""


def is_bag_folder(path: Path) -> bool:
    """A ROS 2 bag: a folder with ``metadata.yaml`` and its storage files."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


class Bag:
    """The ROS bag importer."""

    name = "bag"
    summary = "ROS 1 bag (.bag) or ROS 2 bag (.mcap, .db3, or its folder), with --odom TOPIC"
    options = BagOptions

    def detect(self, path: Path) -> bool:
        """A ``.bag``, ``.mcap`` or ``.db3`` file, or a ROS 2 bag folder."""
        return (path.is_file() and path.suffix in SUFFIXES) or is_bag_folder(path)

    def refuse(self, path: Path) -> str | None:
        """Nothing to say."""
        return None

    def open(self, path: Path, options: BagOptions) -> Iterator[Event]:
        """The bag's events (``rosbags`` is imported here, not at start-up)."""
        from online_slam.importers.bag.reader import read_bag

        return read_bag(path, options)


IMPORTER = Bag()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
