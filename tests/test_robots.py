"""Several robots in one stream: the robot fields, their validation, the smoother on them alone, MRCLAM's five
robots in one stream and the simulated worlds of several robots."""

from __future__ import annotations

import collections
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA, needs_data
from inprocess import run_cli

from online_slam import Slam
from online_slam.errors import InputError
from online_slam.frontend import FrontEnd
from online_slam.importers import open_dataset
from online_slam.importers._lines import table
from online_slam.importers.mrclam.reader import MrclamNoise, _interpolate_truth
from online_slam.importers.mrclam.robots import read_mrclam_robots
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources import (
    WORLDS,
    MeetConfig,
    Observation,
    Odometry,
    Start,
    Truth,
    meet_world,
    read_stream,
    square_world,
    write_stream,
)
from online_slam.sources.validate import validate_events

EXE = [shutil.which("online-slam")] if shutil.which("online-slam") else [sys.executable, "-m", "online_slam"]
MRCLAM = SHARED_DATA / "MRCLAM_Dataset6"
needs_mrclam = needs_data("MRCLAM_Dataset6")
SIG3, SIG2 = [0.1, 0.1, 0.05], [0.1, 0.01]


def two_robots() -> list[dict]:
    """A valid stream of robots 1 and "b": starts, a move each, truth, a landmark and a robot sighting."""
    return [
        {"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0], "robot": 1},
        {"type": "start", "t": 0.0, "pose": [2.0, 0.0, 3.0], "robot": "b", "sigma": [0.1, 0.1, 0.1]},
        {"type": "odometry", "t": 1.0, "delta": [1.0, 0.0, 0.0], "sigma": SIG3, "robot": 1},
        {"type": "odometry", "t": 1.0, "delta": [0.5, 0.0, 0.0], "sigma": SIG3, "robot": "b"},
        {"type": "truth", "t": 1.0, "pose": [1.0, 0.0, 0.0], "robot": 1},
        {"type": "observation", "t": 1.0, "landmark": 7, "range": 2.0, "bearing": 0.1, "sigma": SIG2, "robot": 1},
        {"type": "observation", "t": 1.0, "robot_seen": "b", "range": 0.5, "bearing": 0.0, "sigma": SIG2, "robot": 1},
    ]


def test_robot_fields_parse_and_round_trip() -> None:
    events = list(validate_events(two_robots()))
    assert [e.robot for e in events] == [1, "b", 1, "b", 1, 1, 1]
    sighting = events[-1]
    assert isinstance(sighting, Observation) and sighting.robot_seen == "b" and sighting.landmark is None
    assert sighting.to_record() == two_robots()[-1] | {"sigma": SIG2}
    buffer = io.StringIO()
    write_stream(buffer, events)
    assert [json.loads(line) for line in buffer.getvalue().splitlines()] == two_robots()


def test_a_stream_without_robots_writes_no_robot_field() -> None:
    buffer = io.StringIO()
    write_stream(buffer, square_world())
    assert '"robot' not in buffer.getvalue()
    steps = list(FrontEnd().steps(square_world()))
    assert all(s.robot is None and s.robots_seen == () and s.z_robots.shape == (0, 2) for s in steps)


@pytest.mark.parametrize(
    ("line", "field", "message"),
    [
        ({"type": "odometry", "t": 2.0, "delta": [1.0, 0, 0], "sigma": SIG3, "robot": 3}, "robot", "unknown robot 3"),
        ({"type": "truth", "t": 2.0, "pose": [1.0, 0, 0], "robot": "1"}, "robot", 'unknown robot "1"'),
        ({"type": "odometry", "t": 2.0, "delta": [1.0, 0, 0], "sigma": SIG3}, "robot", "missing required field"),
        ({"type": "odometry", "t": 0.5, "delta": [1.0, 0, 0], "sigma": SIG3, "robot": "b"}, "t", "over all robots"),
        (
            {"type": "observation", "t": 1.0, "robot_seen": 1, "range": 1.0, "bearing": 0.0, "sigma": SIG2, "robot": 1},
            "robot_seen",
            "robot 1 cannot sight itself",
        ),
        (
            {"type": "observation", "t": 1.0, "robot_seen": 2, "range": 1.0, "bearing": 0.0, "sigma": SIG2, "robot": 1},
            "robot_seen",
            "unknown robot 2",
        ),
        (
            {
                "type": "observation",
                "t": 1.0,
                "robot_seen": "b",
                "landmark": 3,
                "range": 1.0,
                "bearing": 0.0,
                "sigma": SIG2,
                "robot": 1,
            },
            "landmark",
            "has no landmark",
        ),  # fmt: skip
        ({"type": "start", "t": 1.0, "pose": [0.0, 0, 0], "robot": "b"}, "robot", "already has a start"),
        ({"type": "start", "t": 1.0, "pose": [0.0, 0, 0]}, "robot", "missing required field"),
        ({"type": "start", "t": 1.0, "pose": [0.0, 0, 0], "robot": True}, "robot", "expected an integer or"),
        ({"type": "start", "t": 1.0, "pose": [0.0, 0, 0], "robot": ""}, "robot", "expected an integer or"),
    ],
)
def test_each_robot_rule_is_one_error_naming_line_and_field(line: dict, field: str, message: str) -> None:
    with pytest.raises(InputError) as info:
        list(validate_events([*two_robots(), line]))
    assert f"<events>:8: {field}: " in str(info.value) and message in str(info.value)


def test_robots_in_a_stream_of_one_unnamed_robot_are_refused() -> None:
    one = [{"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0]}]
    sighting = {"type": "observation", "t": 0.0, "robot_seen": 2, "range": 1.0, "bearing": 0.0, "sigma": SIG2}
    with pytest.raises(InputError, match=r"<events>:2: robot_seen: unknown robot 2"):
        list(validate_events([*one, sighting]))
    joining = {"type": "start", "t": 1.0, "pose": [0.0, 0.0, 0.0], "robot": 2}
    with pytest.raises(InputError, match=r"<events>:2: robot: the first pose names no robot"):
        list(validate_events([*one, joining]))
    moved = {"type": "odometry", "t": 1.0, "delta": [1.0, 0, 0], "sigma": SIG3, "robot": 1}
    with pytest.raises(InputError, match=r"<events>:2: robot: unknown robot 1"):
        list(validate_events([*one, moved]))


def test_a_bad_robot_line_in_a_file_is_one_line_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "robots.jsonl"
    bad = {"type": "odometry", "t": 2.0, "delta": [1.0, 0, 0], "sigma": SIG3, "robot": 9}
    path.write_text("".join(json.dumps(r) + "\n" for r in [two_robots()[0], bad]))
    done = subprocess.run([*EXE, "replay", str(path)], capture_output=True, text=True)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [
        f"online-slam: error: {path}:2: robot: unknown robot 9: no start names it before (robots: 1)"
    ]


def test_g2o_refuses_a_second_robot(tmp_path: Path) -> None:
    path = tmp_path / "robots.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in two_robots()))
    done = run_cli("convert", "stream", str(path), "-o", str(tmp_path / "x.g2o"))
    assert done.returncode == 2 and not (tmp_path / "x.g2o").exists()
    assert done.stderr.strip().splitlines() == [
        "online-slam: error: g2o holds one pose chain; robot 'b' is a second robot"
    ]


def test_the_library_calls_refuse_events_without_a_robot_once_robots_are_named() -> None:
    slam = Slam("ekf")
    slam.add({"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0], "robot": 1})
    with pytest.raises(InputError, match="Slam.add_odometry: robot: missing required field"):
        slam.add_odometry(1.0, [1.0, 0.0, 0.0], SIG3)
    with pytest.raises(InputError, match="Slam.add_observations: robot: a scan names no robot"):
        slam.add_observations(1.0, [1], [1.0], [0.0], SIG2)
    slam.add({"type": "odometry", "t": 1.0, "delta": [1.0, 0.0, 0.0], "sigma": SIG3, "robot": 1})
    assert slam.estimate().index == 1  # one named robot is one robot


def test_the_smoother_alone_takes_several_robots() -> None:
    steps = list(FrontEnd().steps(validate_events(two_robots())))
    assert [(s.index, s.robot) for s in steps] == [(0, 1), (1, "b"), (2, 1), (3, "b")]
    slam = Slam("smoother")
    for record in two_robots():
        slam.add(record)
    assert slam.estimate().index == 2  # robot 1's newest pose (it has the newest sightings)
    smoother = replay("meet", ReplayConfig(estimators=("smoother",))).estimators["smoother"]
    assert sorted(smoother.robots) == ["1", "2", "3"] and smoother.details["robot_sightings_folded"] > 100


def test_replay_of_several_robots_with_the_smoother_alone_reports_each_robot() -> None:
    done = run_cli("replay", "meet-apart", "--estimators", "smoother")
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert "smoother  robot 2" in done.stdout and "left out" not in done.stdout


def test_a_step_carries_its_robot_and_its_robot_sightings_apart() -> None:
    front = FrontEnd()
    front.push(Start(0.0, (0.0, 0.0, 0.0), robot=1))
    front.push(Observation(0.0, 4, 2.0, 0.1, (0.1, 0.01), robot=1))
    front.push(Observation(0.0, None, 1.5, -0.2, (0.2, 0.02), robot=1, robot_seen=2))
    step = front.push(Odometry(1.0, (1.0, 0.0, 0.0), (0.1, 0.1, 0.05), robot=1))
    assert step.robot == 1 and step.landmarks == (4,) and step.robots_seen == (2,)
    assert np.array_equal(step.z_robots, [[1.5, -0.2]]) and np.allclose(step.z_robots_cov, [np.diag([0.04, 4e-4])])
    assert front.close().robot == 1 and front.counts["robot_observation"] == 1


def sightings(events: list) -> tuple[collections.Counter, dict]:
    """Robot sightings by (robot, seen robot), and the robots sighting each landmark."""
    pairs: collections.Counter = collections.Counter()
    sighters: dict = collections.defaultdict(set)
    for e in events:
        if isinstance(e, Observation) and e.robot_seen is not None:
            pairs[e.robot, e.robot_seen] += 1
        elif isinstance(e, Observation):
            sighters[e.landmark].add(e.robot)
    return pairs, sighters


def test_the_meet_world_robots_sight_each_other_and_shared_landmarks() -> None:
    events = list(WORLDS["meet"].events())
    assert list(validate_events(events)) == events  # a valid stream
    pairs, sighters = sightings(events)
    assert {pair for pair, n in pairs.items() if n >= 10} == {(a, b) for a in (1, 2, 3) for b in (1, 2, 3) if a != b}
    assert sum(len(robots) > 1 for robots in sighters.values()) >= 10
    assert len([e for e in events if isinstance(e, Truth)]) == 3 * MeetConfig.poses
    again = list(WORLDS["meet"].events())
    assert again == events and list(WORLDS["meet"].events(MeetConfig.seed + 1)) != events


def test_the_meet_apart_world_shares_no_landmark() -> None:
    events = list(validate_events(WORLDS["meet-apart"].events()))
    pairs, sighters = sightings(events)
    assert set(pairs) == {(1, 2), (2, 1)} and min(pairs.values()) >= 10
    assert all(len(robots) == 1 for robots in sighters.values()) and len(sighters) >= 10


def test_robot_sightings_measure_the_seen_robot_with_the_sensor_noise() -> None:
    events = list(meet_world(MeetConfig(sensor_sigma=(1e-6, 1e-6), poses=120)))
    truth = {(e.robot, e.t): np.array(e.pose) for e in events if isinstance(e, Truth)}
    for e in events:
        if isinstance(e, Observation) and e.robot_seen is not None:
            pose, seen = truth[e.robot, e.t], truth[e.robot_seen, e.t]
            d = seen[:2] - pose[:2]
            assert e.range == pytest.approx(np.hypot(*d), abs=1e-4)
            assert np.angle(np.exp(1j * (e.bearing - np.arctan2(d[1], d[0]) + pose[2]))) == pytest.approx(0, abs=1e-4)


def write_tiny_mrclam(folder: Path) -> None:
    """A five-robot MRCLAM folder of a few rows: robot 1 sights landmark 6 and robot 2 (barcode 14)."""
    folder.mkdir()
    (folder / "Barcodes.dat").write_text("# header\n" + "".join(f"{s} {b}\n" for s, b in
                                          [(1, 5), (2, 14), (3, 41), (4, 32), (5, 23), (6, 63)]))  # fmt: skip
    (folder / "Landmark_Groundtruth.dat").write_text("6 3.0 0.0 0.0001 0.0001\n")
    for robot in range(1, 6):
        y = float(robot)
        (folder / f"Robot{robot}_Odometry.dat").write_text("0.0 0.1 0.0\n10.0 0.1 0.0\n")
        (folder / f"Robot{robot}_Groundtruth.dat").write_text(f"0.0 0.0 {y} 0.0\n10.0 1.0 {y} 0.0\n")
        rows = {1: "1.0 63 3.0 0.0\n2.0 14 1.0 1.5\n2.0 99 1.0 0.0\n", 3: f"{robot}.5 63 3.0 0.0\n"}
        (folder / f"Robot{robot}_Measurement.dat").write_text(rows.get(robot, f"{robot}.0 63 3.0 0.1\n"))


def test_all_mrclam_robots_merge_by_time_and_link_robot_sightings(tmp_path: Path) -> None:
    folder = tmp_path / "MRCLAM_Dataset9"
    write_tiny_mrclam(folder)
    events = list(validate_events(open_dataset(folder, robot="all")))  # a valid stream
    header = events[0]
    assert header.name == "MRCLAM Dataset9, robots 1-5" and header.meta["robot_observations"] == 1
    assert header.meta["dropped_unknown_barcodes"] == 1 and header.meta["landmark_observations"] == 5
    timed = [e for e in events if hasattr(e, "t")]
    assert [e.t for e in timed] == sorted(e.t for e in timed)
    starts = {e.robot: e for e in events if isinstance(e, Start)}
    assert starts[2].t == 2.0 and starts[2].pose == pytest.approx((0.2, 2.0, 0.0))  # Vicon at its first pose time
    (sighting,) = [e for e in events if isinstance(e, Observation) and e.robot_seen is not None]
    assert (sighting.robot, sighting.robot_seen, sighting.t, sighting.landmark) == (1, 2, 2.0, None)
    assert any(isinstance(e, Odometry) and e.robot == 1 and e.t == 2.0 for e in events)  # the sighting robot's pose
    assert {e.robot for e in events if isinstance(e, Truth)} == {1, 2, 3, 4, 5}


def test_robot_sightings_read_the_seen_robot_closer_by_the_barcode_offset(tmp_path: Path) -> None:
    """The range of a robot sighting is the camera's placement less ``robot_barcode_m``."""
    folder = tmp_path / "MRCLAM_Dataset9"
    write_tiny_mrclam(folder)

    def robot_sighting(noise: MrclamNoise) -> Observation:
        (found,) = [e for e in read_mrclam_robots(folder, noise) if isinstance(e, Observation) and e.robot_seen]
        return found

    plain, offset = robot_sighting(MrclamNoise(robot_barcode_m=0.0)), robot_sighting(MrclamNoise(robot_barcode_m=0.05))
    assert plain.range - offset.range == pytest.approx(0.05, abs=1e-12) and plain.bearing == offset.bearing


@needs_mrclam
def test_mrclam_dataset_6_all_robots() -> None:
    events = list(open_dataset(MRCLAM, robot="all"))
    header = events[0]
    observations = [e for e in events if isinstance(e, Observation)]
    seen = [e for e in observations if e.robot_seen is not None]
    assert len(seen) == 3988 and len(observations) + header.meta["dropped_unknown_barcodes"] == 19377
    assert header.meta["robots"] == [1, 2, 3, 4, 5] and {e.robot for e in observations} == {1, 2, 3, 4, 5}
    assert collections.Counter(e.robot for e in seen) == {1: 407, 2: 792, 3: 1277, 4: 373, 5: 1139}  # PROVENANCE.md
    timed = [e.t for e in events if hasattr(e, "t")]
    assert timed == sorted(timed)
    for start in (e for e in events if isinstance(e, Start)):
        vicon = table(MRCLAM / f"Robot{start.robot}_Groundtruth.dat", ("time", "x", "y", "theta"))
        assert np.allclose(start.pose, _interpolate_truth(vicon, np.array([start.t]))[0][0], atol=1e-12)
        first = min(e.t for e in events if getattr(e, "robot", None) == start.robot)
        assert start.t == first


@needs_mrclam
def test_convert_all_mrclam_robots_writes_a_stream_that_reads_back(tmp_path: Path) -> None:
    out = tmp_path / "all.jsonl.gz"
    done = run_cli("convert", "mrclam", str(MRCLAM), "--robot", "all", "--half", "second", "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert list(read_stream(out)) == list(open_dataset(MRCLAM, robot="all", half="second"))
