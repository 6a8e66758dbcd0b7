"""UTIAS MRCLAM, all five robots -> one stream v1 (``--robot all``): merged by time, robot sightings kept.

Each robot is converted as :func:`~online_slam.importers.mrclam.reader.read_mrclam` converts it alone (the same noise
model, odometry integrated exactly from its commands), with these differences:

- Its sightings of other robots are kept, as observations with ``robot_seen`` (Barcodes.dat: subjects 1-5 are
  the robots); a row of its own barcode, or of an unknown one, is dropped and counted in the header.
- Its poses are at the times of all of its own sightings (landmarks and robots) and at the times another robot
  sights it, so that a robot sighting links two poses of the same time.
- Its sightings of other robots are placed by its camera too, their range shortened by ``robot_barcode_m`` (a
  robot reads farther than its Vicon centre), and widened for their correlation as landmark sightings are, with
  the model's correlation, one observer's sightings of one seen robot grouped as one landmark's
  (:func:`~online_slam.importers.mrclam.sightings.sighting_sigmas`; on Dataset 6 their errors are correlated too:
  range ``0.23 exp(-dt / 1.9 s) + 0.44 exp(-dt / 31 s)`` in the camera's sigmas).
- Its start is its Vicon pose at its first pose time, with the conversion's small prior (``start_sigma``): the
  anchor's convention (every robot starts at its Vicon pose; the anchor's prior is zero).

Lines are ordered by time; within one time: starts, odometry, truth, then sightings, robot by robot. So a
robot sighting comes after the seen robot's pose of that time.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

from online_slam.importers._lines import table
from online_slam.importers.mrclam.reader import (
    MrclamNoise,
    RobotData,
    _interpolate_truth,
    bias_meta,
    correlates,
    load_robot,
    noise_meta,
    odometry_increments,
    own_scale_meta,
)
from online_slam.importers.mrclam.sightings import camera_of, camera_sightings, mounting, widened_field
from online_slam.sources.events import Event, Header, LandmarkTruth, Observation, Odometry, Start, Truth

ROBOTS = (1, 2, 3, 4, 5)
"""MRCLAM's robots (subjects 1-5)."""

_START, _ODOMETRY, _TRUTH, _SIGHTING = range(4)
"""Order of the lines of one time."""


def pose_times(robot: int, data: dict[int, RobotData]) -> np.ndarray:
    """A robot's pose times: its own sighting times and the times another robot sights it, sorted, distinct."""
    own = [data[robot].measurements[:, 0], data[robot].robot_rows[:, 0]]
    seen = [d.robot_rows[d.robots_seen == robot, 0] for r, d in data.items() if r != robot]
    return np.unique(np.concatenate(own + seen))


def _robot_lines(robot: int, data: RobotData, times: np.ndarray, cfg: MrclamNoise) -> Iterator[tuple]:
    """One robot's lines as ``(t, order, robot, event)``, in time order."""
    increments, covariances = odometry_increments(data.odometry, times, cfg)
    true_poses, covered = _interpolate_truth(data.truth, times)
    t0 = float(times[0])
    yield (
        t0,
        _START,
        robot,
        Start(t=t0, pose=tuple(map(float, true_poses[0])), sigma=(cfg.start_sigma,) * 3, robot=robot),
    )
    for k in range(1, len(times)):
        cov = tuple(tuple(map(float, row)) for row in covariances[k - 1])
        odometry = Odometry(t=float(times[k]), delta=tuple(map(float, increments[k - 1])), cov=cov, robot=robot)
        yield float(times[k]), _ODOMETRY, robot, odometry
    for j in np.flatnonzero(covered):
        yield (
            float(times[j]),
            _TRUTH,
            robot,
            Truth(t=float(times[j]), pose=tuple(map(float, true_poses[j])), robot=robot),
        )
    camera, rows, sigmas, widening = camera_sightings(cfg, robot, data.measurements, data.subjects, mounted=True)
    sensor = None if camera is None else f"camera{robot}"
    for row, subject, sigma, factors in zip(rows, data.subjects, sigmas, widening):
        t = float(row[0])
        sighting = Observation(
            t,
            int(subject),
            float(row[2]),
            float(row[3]),
            (float(sigma[0]), float(sigma[1])),
            robot=robot,
            sensor=sensor,
            widened=widened_field(factors),
        )
        yield t, _SIGHTING, robot, sighting
    _, placed, widened, _ = camera_sightings(cfg, robot, data.robot_rows, data.robots_seen, cfg.robot_barcode_m)
    for row, seen, sigma in zip(placed, data.robots_seen, widened):
        t = float(row[0])
        yield (
            t,
            _SIGHTING,
            robot,
            Observation(
                t,
                None,
                float(row[2]),
                float(row[3]),
                (float(sigma[0]), float(sigma[1])),
                robot=robot,
                robot_seen=int(seen),
            ),
        )


def _among(data: RobotData, robots: tuple[int, ...]) -> RobotData:
    """The robot's data with its sightings of robots outside ``robots`` left out."""
    keep = np.isin(data.robots_seen, robots)
    return data if keep.all() else replace(data, robot_rows=data.robot_rows[keep], robots_seen=data.robots_seen[keep])


def _named(robots: tuple[int, ...]) -> str:
    """``1-5`` for all five, else ``1, 3, 4``."""
    return "1-5" if robots == ROBOTS else ", ".join(map(str, robots))


def _sensors(cfg: MrclamNoise) -> dict[str, dict[str, dict[str, list[float]]]]:
    """The header's ``sensors``: each robot's camera (``camera1``..``camera5``) where the model has one."""
    cameras = {f"camera{r}": {"pose": mounting(c)} for r in ROBOTS if (c := camera_of(cfg, r)) is not None}
    return {"sensors": cameras} if cameras else {}


def read_mrclam_robots(
    folder: str | Path,
    noise: MrclamNoise | None = None,
    span: tuple[float, float] | None = None,
    robots: tuple[int, ...] = ROBOTS,
) -> Iterator[Event]:
    """Stream all five MRCLAM robots as one multi-robot stream.

    Args:
        folder: The dataset folder (as for :func:`~online_slam.importers.mrclam.reader.read_mrclam`).
        noise: Noise model (defaults: fitted on Dataset 6), the same for every robot.
        span: Only this part of the recording (as for ``read_mrclam``).
        robots: Only these robots (their sightings of the others left out).

    Yields:
        Stream-v1 events naming their robot (1..5), ordered by time.
    """
    root = Path(folder)
    cfg = noise or MrclamNoise()
    data = {robot: _among(load_robot(root, robot, span), robots) for robot in robots}
    landmarks = table(root / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std"))
    times = {robot: pose_times(robot, data) for robot in robots}
    lines = [line for robot in robots for line in _robot_lines(robot, data[robot], times[robot], cfg)]
    lines.sort(key=lambda line: line[:3])  # stable: one robot's sightings of one time keep the order made above
    yield Header(
        name=f"MRCLAM {root.name.removeprefix('MRCLAM_')}, robots {_named(robots)}",
        meta={
            "converted_from": str(root.name),
            "robots": list(robots),
            "poses": {str(r): int(len(times[r])) for r in robots},
            "landmark_observations": sum(int(len(d.measurements)) for d in data.values()),
            "robot_observations": sum(int(len(d.robot_rows)) for d in data.values()),
            "dropped_unknown_barcodes": sum(d.dropped_unknown for d in data.values()),
            "dropped_own_barcode": sum(d.dropped_self for d in data.values()),
            "start": "each robot's Vicon pose at its first pose time",
            "noise": noise_meta(cfg),
            "sightings_correlated": correlates(cfg),
            **own_scale_meta(cfg),
            **bias_meta(cfg),
            **_sensors(cfg),
        },
    )
    for subject, x, y, _, _ in landmarks:
        yield LandmarkTruth(int(subject), (float(x), float(y)))
    for line in lines:
        yield line[3]
