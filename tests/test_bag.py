"""The ROS bag importer: the Victoria Park bags shipped in replay/ give the acfr importer's events of the same
excerpt, a simulated world's bag gives its stream, and bad topics or options are one line naming them."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import REPLAY, assert_close

import online_slam
from benchmarks.bags import VP_OPTIONS, write_stream_bag
from online_slam.cli.main import main
from online_slam.errors import InputError
from online_slam.geometry.angles import wrap
from online_slam.importers import registry
from online_slam.importers.acfr import GPS_ANTENNA
from online_slam.importers.acfr.reader import read_acfr
from online_slam.importers.bag import BagOptions
from online_slam.importers.bag.reader import from_local_plane, local_plane, read_bag
from online_slam.importers.laser import Detector, detect
from online_slam.models.fix import GPS_CORRELATION_S
from online_slam.pipeline import ReplayConfig
from online_slam.sources.events import Header, Observation, Odometry, Position, Start, Truth
from online_slam.sources.worlds import square_world

RAW = REPLAY / "victoria_park_raw_45s"
BAGS = [REPLAY / "victoria_park_45s.mcap", REPLAY / "victoria_park_45s.bag"]
SIGMA = (0.06, 0.013962634015954637)  # the square world's sighting noise


@pytest.mark.parametrize("bag", BAGS, ids=["mcap", "ros1"])
def test_the_victoria_park_bag_gives_the_raw_importers_events(bag: Path) -> None:
    # The bags mount the GPS antenna (frame gps) in /tf_static where the raw importer's default puts it
    raw = [e for e in read_acfr(RAW) if not isinstance(e, Header)]
    read = [e for e in read_bag(bag, BagOptions(**VP_OPTIONS)) if not isinstance(e, Header)]
    assert [type(e) for e in read] == [type(e) for e in raw]
    assert sum(isinstance(e, Observation) for e in raw) > 1000
    others = [(a, b) for a, b in zip(raw, read) if not isinstance(a, Truth)]
    assert_close([a for a, _ in others], [b for _, b in others], rtol=1e-9)
    truth = np.array([(a.t, *a.pose[:2], b.t, *b.pose[:2]) for a, b in zip(raw, read) if isinstance(a, Truth)])
    assert {(a.offset, b.offset) for a, b in zip(raw, read) if isinstance(a, Truth)} == {(GPS_ANTENNA, GPS_ANTENNA)}
    assert len(truth) > 100 and np.array_equal(truth[:, 0], truth[:, 3])
    # NavSatFix holds degrees in float64: one unit in the last place of 151 deg east is 2.6e-9 m
    assert np.max(np.abs(truth[:, 1:3] - truth[:, 4:6])) < 1e-8


def test_a_simulated_worlds_bag_gives_its_stream(tmp_path: Path) -> None:
    stream = list(square_world())
    for ros1, name in ((False, "square.mcap"), (True, "square.bag")):
        write_stream_bag(stream, tmp_path / name, ros1)
        options = BagOptions(odom="/odom", landmarks="/landmarks", truth="/truth", range_sigma=SIGMA[0],
                             bearing_sigma=SIGMA[1])  # fmt: skip
        read = list(read_bag(tmp_path / name, options))
        for kind in (Start, Odometry, Observation, Truth):
            mine = [e for e in read if isinstance(e, kind)]
            theirs = [e for e in stream if isinstance(e, kind)]
            if kind is Odometry:  # the bag carries the covariance, the stream its sigmas
                mine = [replace(e, cov=None, sigma=tuple(np.sqrt(np.diag(e.covariance)))) for e in mine]
            if kind is Truth:  # a heading of pi reads back as -pi
                turn = [wrap(a.pose[2] - b.pose[2]) for a, b in zip(mine, theirs)]
                assert np.allclose(turn, 0.0, atol=1e-12)
                mine = [replace(a, pose=(*a.pose[:2], b.pose[2])) for a, b in zip(mine, theirs)]
            assert_close(mine, theirs, rtol=1e-9, where=f"{name} {kind.__name__}")


@pytest.mark.slow
def test_replaying_the_bag_gives_the_raw_importers_figures(tmp_path: Path) -> None:
    flags = ["--estimators", "ekf", "--quiet"]
    assert main(["replay", str(RAW), *flags, "--json", str(tmp_path / "raw.json")]) == 0
    bag = ["--odom", "/wheels", "--scan", "/scan", "--truth", "/gps", "--steer", "2.83,0.76", "--odom-sigma",
           "0.001,0.001,0.001", "--odom-sigma-per-m", "0.02,0.02,0.005", "--odom-sigma-per-rad", "0.02",
           "--range-sigma", "0.2", "--bearing-sigma", "0.005", "--scan-range", "3,25", "--scan-bearing", "6.3,177",
           "--scan-decimals", "5", "--sensor-to-base", "--fix-origin=-33.8888,151.1930", "--truth-speed", "10",
           "--start-from-truth", "20"]  # fmt: skip
    assert main(["replay", str(BAGS[0]), *bag, *flags, "--json", str(tmp_path / "bag.json")]) == 0
    raw, read = (json.loads((tmp_path / f"{n}.json").read_text())["estimators"]["ekf"] for n in ("raw", "bag"))
    assert raw["final_rmse_m"] is not None
    for figure in ("final_rmse_m", "online_rmse_m", "landmark_rmse_m", "nis_mean", "nis_median", "state_size"):
        assert (raw[figure] is None and read[figure] is None) or math.isclose(raw[figure], read[figure], rel_tol=1e-6)
    assert main(["convert", "bag", str(BAGS[1]), *bag, "-o", str(tmp_path / "vp.jsonl")]) == 0


def test_bags_are_detected(tmp_path: Path) -> None:
    assert registry.detect(BAGS[0]) == "bag" and registry.detect(BAGS[1]) == "bag"
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "metadata.yaml").write_text("")
    assert registry.detect(tmp_path / "run") == "bag"
    assert registry.detect(RAW) == "acfr"


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({}, "--odom"),
        ({"odom": "/nothing"}, "no topic /nothing"),
        ({"odom": "/scan"}, "topic /scan is sensor_msgs/msg/LaserScan"),
        ({"odom": "/wheels"}, "topic /wheels: no covariance"),
        ({"odom": "/wheels", "odom_sigma": (0.1, 0.1, 0.01), "scan": "/scan"}, "topic /scan: give --range-sigma"),
        ({"odom": "/wheels", "odom_sigma": (0.1, 0.1, 0.01), "fix": "/gps"}, "topic /gps: fixes without"),
        ({"odom": "/wheels", "odom_sigma": (0.1, 0.1, 0.01), "scan": "/scan", "range_sigma": 0.1,
          "bearing_sigma": 0.01, "base_frame": "car"}, "frame 'laser' has no /tf_static mounting on 'car'"),
        ({"odom": "/wheels", "odom_sigma": (0.1, 0.1, 0.01), "truth": "/gps", "base_frame": "car"},
         "frame 'gps' has no /tf_static mounting on 'car'"),
    ],
)  # fmt: skip
def test_bad_topics_and_options_are_one_line(options: dict, words: str) -> None:
    with pytest.raises(InputError, match=words) as caught:
        list(read_bag(BAGS[0], BagOptions(**options)))
    assert "\n" not in str(caught.value)


def test_fixes_are_position_records_in_the_local_plane() -> None:
    options = replace(BagOptions(**VP_OPTIONS), fix="/gps", fix_sigma=3.0)
    events = list(read_bag(BAGS[0], options))
    fixes = [e for e in events if isinstance(e, Position)]
    header = next(e for e in events if isinstance(e, Header))  # a GPS's errors wander: declared for the front-end
    assert header.meta["fix_correlation_s"] == GPS_CORRELATION_S
    gps = np.loadtxt(RAW / "gps.dat")
    assert len(fixes) == len(gps)
    assert np.allclose([f.xy for f in fixes], gps[:, 1:3], atol=1e-8) and fixes[0].sigma == (3.0, 3.0)
    assert {f.offset for f in fixes} == {GPS_ANTENNA}  # the gps frame's mounting


def test_the_local_plane_is_metric_and_inverts() -> None:
    origin = (-33.8888, 151.193)
    xy = np.array([[0.0, 0.0], [1000.0, -250.0], [-3.5, 7.25]])
    lat, lon = from_local_plane(xy, origin)
    assert np.allclose(local_plane(lat, lon, origin), xy, atol=1e-8)
    # one second of latitude is 30.81 m at Sydney (WGS84's meridian radius), one of longitude 25.70 m
    assert np.allclose(
        local_plane(np.array([origin[0] + 1 / 3600]), np.array([origin[1]]), origin), [[0, 30.81]], atol=0.01
    )
    assert np.allclose(
        local_plane(np.array([origin[0]]), np.array([origin[1] + 1 / 3600]), origin), [[25.70, 0]], atol=0.01
    )


def test_the_laser_detector_finds_runs_of_returns() -> None:
    ranges = np.full(181, np.inf)
    ranges[10:14] = 5.0  # a trunk of 4 beams
    ranges[14:16] = 9.0  # behind it, a jump: another object
    ranges[100] = 20.0
    increment = math.pi / 180
    found, keep = detect(ranges, 0.0, increment, (0.0, 80.0), Detector(max_diameter=0.5))
    assert found.shape == (3, 3)
    assert np.allclose(found[0], [5.0 + 2 * increment * 5.0, 11.5 * increment, 4 * increment * 5.0])
    assert np.allclose(found[:, 1] / increment, [11.5, 14.5, 100.0])
    assert keep.tolist() == [True, True, True]
    _, keep = detect(ranges, 0.0, increment, (0.0, 80.0), Detector(max_range=15.0, min_diameter=0.32))
    assert keep.tolist() == [True, False, False]


def test_messages_out_of_order_read_as_in_order(tmp_path: Path) -> None:
    stream = list(square_world())
    sightings = [e for e in stream if isinstance(e, Observation)]
    times = sorted({e.t for e in sightings}, reverse=True)  # written last, the latest first (one time's in order)
    shuffled = [e for e in stream if not isinstance(e, Observation)] + [e for t in times for e in sightings if e.t == t]
    options = BagOptions(odom="/odom", landmarks="/landmarks", range_sigma=SIGMA[0], bearing_sigma=SIGMA[1])
    write_stream_bag(stream, tmp_path / "ordered.mcap", ros1=False)
    write_stream_bag(shuffled, tmp_path / "shuffled.mcap", ros1=False)
    ordered, late = (list(read_bag(tmp_path / f"{n}.mcap", options))[1:] for n in ("ordered", "shuffled"))
    assert_close(ordered, late, rtol=0.0)


@pytest.mark.slow
def test_a_sensor_off_the_centre_is_declared_and_replays() -> None:
    options = replace(BagOptions(**VP_OPTIONS), sensor_to_base=False)
    events = list(read_bag(BAGS[0], options))
    assert events[0].meta["sensors"] == {"laser": {"pose": [3.78, 0.5, pytest.approx(-math.pi / 2, abs=1e-15)]}}
    sightings = [e for e in events if isinstance(e, Observation)]
    assert {e.sensor for e in sightings} == {"laser"} and sightings[0].sigma == (0.2, 0.005)
    assert min(e.bearing for e in sightings) >= 0.0 and max(e.bearing for e in sightings) <= math.pi  # laser frame
    results = online_slam.replay(events, ReplayConfig(estimators=("ekf",)))
    assert results.error is None and results.observations == len(sightings)


def test_a_body_twist_integrates_and_odometry_without_covariance_takes_the_option(tmp_path: Path) -> None:
    from benchmarks.bags import open_bag

    with open_bag(tmp_path / "twist.bag", ros1=True) as bag:
        for k in range(11):  # 1 m/s ahead turning at 0.1 rad/s, one message a second
            twist = bag.msg("geometry_msgs/msg/Twist", linear=bag.vector(1.0), angular=bag.vector(z=0.1))
            bag.write("/cmd", float(k), bag.msg("geometry_msgs/msg/TwistStamped", header=bag.header(float(k), ""),
                                                twist=twist))  # fmt: skip
    events = list(read_bag(tmp_path / "twist.bag", BagOptions(odom="/cmd", odom_sigma=(0.1, 0.1, 0.01), pose_gap=2.5)))
    steps = [e for e in events if isinstance(e, Odometry)]
    assert [e.t for e in steps] == [2.5, 5.0, 7.5]  # no sighting: a pose every 2.5 s (none at the end: acfr's rule)
    arc = 2 * math.sin(0.125) / 0.25 * 2.5  # chord of 2.5 m turning 0.25 rad
    assert np.allclose(steps[0].delta, [arc * math.cos(0.125), arc * math.sin(0.125), 0.25], atol=1e-12)
    assert np.allclose(steps[0].covariance, np.diag([0.01, 0.01, 0.0001]))


def test_position_truth_is_of_its_frames_antenna_and_the_start_puts_it_there(tmp_path: Path) -> None:
    from benchmarks.bags import open_bag

    start, antenna = np.array([10.0, 20.0, math.pi / 2]), (2.0, 1.0)  # driving north at 1 m/s from (10, 20)
    with open_bag(tmp_path / "gps.bag", ros1=True) as bag:
        bag.mount(0.0, "base_link", "antenna", (*antenna, 0.3))
        for k in range(41):
            t = 0.25 * k
            if k % 4 == 0:
                twist = bag.msg("geometry_msgs/msg/Twist", linear=bag.vector(1.0), angular=bag.vector())
                bag.write("/cmd", t, bag.msg("geometry_msgs/msg/TwistStamped", header=bag.header(t, ""), twist=twist))
            point = bag.msg("geometry_msgs/msg/Point", x=start[0] - antenna[1], y=start[1] + t + antenna[0], z=0.0)
            for topic, frame in (("/truth", "antenna"), ("/map", "map"), ("/mixed", "antenna" if k else "map")):
                bag.write(topic, t, bag.msg("geometry_msgs/msg/PointStamped", header=bag.header(t, frame), point=point))
    options = BagOptions(odom="/cmd", odom_sigma=(0.1, 0.1, 0.01), truth="/truth", fix="/map", fix_sigma=1.0,
                         start_from_truth=3.0)  # fmt: skip
    events = list(read_bag(tmp_path / "gps.bag", options))
    assert np.allclose(next(e for e in events if isinstance(e, Start)).pose, start, atol=1e-12)
    truth = [e for e in events if isinstance(e, Truth)]
    assert len(truth) > 5 and {e.offset for e in truth} == {antenna}  # the frame's mounting, without its turn
    assert {e.offset for e in events if isinstance(e, Position)} == {None}  # a map frame: no antenna
    axle = list(read_bag(tmp_path / "gps.bag", replace(options, truth="/map")))
    assert np.allclose(next(e for e in axle if isinstance(e, Start)).pose, [start[0] - 1, start[1] + 2, start[2]])
    with pytest.raises(InputError, match="truth messages in frames 'antenna', 'map'"):
        list(read_bag(tmp_path / "gps.bag", replace(options, truth="/mixed")))
