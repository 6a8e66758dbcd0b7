"""Simulated worlds of several robots: ``meet`` has robots whose loops cross, so that they sight each other and
the same landmarks; ``meet-apart`` two robots that share no landmark (only their sightings of each other link
their maps)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.models.range_bearing import range_bearing
from online_slam.sources.events import (
    Event,
    Header,
    LandmarkTruth,
    Observation,
    Odometry,
    RobotId,
    Start,
    Truth,
)

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MeetConfig:
    """Robots on circular loops that cross: they meet, sight each other and (unless told not to) the same
    landmarks. All move at once, one pose each per time step; robot k drives its loop the other way round from
    robot k - 1, so that they pass each other head-on where the loops cross."""

    robots: int = 3
    """Number of robots (ids 1..robots), at least 2; their loops' centres form a regular polygon."""
    poses: int = 300
    """Poses per robot (odometry steps + 1)."""
    radius: float = 8.0
    """Radius of each loop, metres."""
    spacing: float = 10.0
    """Distance between neighbouring loop centres, metres (below twice the radius: the loops cross)."""
    step: float = 0.5
    """Distance driven between poses, metres."""
    landmarks: int = 60
    """Number of landmarks, uniform over the loops' bounding box plus ``sensor_range``."""
    sensor_range: float = 5.0
    """Landmarks and robots within this distance are sighted at every pose, metres."""
    share_landmarks: bool = True
    """False: landmark j is sighted by robot ``1 + j mod robots`` only, so no two robots sight one landmark and
    only robot sightings tie their maps together."""
    odometry_sigma: tuple[float, float, float] = (0.05, 0.05, 0.01)
    """Standard deviations of each odometry increment (dx m, dy m, dtheta rad)."""
    sensor_sigma: tuple[float, float] = (0.05, float(np.deg2rad(0.5)))
    """Standard deviations of range (m) and bearing (rad), for landmark and robot sightings alike."""
    seed: int = 11
    """Seed of ``numpy.random.default_rng``."""
    dt: float = 1.0
    """Time between poses, seconds."""

    def __post_init__(self) -> None:
        if self.robots < 1 or self.poses < 2 or self.landmarks < 1:
            raise ValueError("the meet world needs robots >= 1, poses >= 2 and landmarks >= 1")
        if not (self.dt > 0 and self.step > 0 and self.sensor_range > 0):
            raise ValueError("the meet world's dt, step and sensor range must be > 0")


def _loops(c: MeetConfig) -> Array:
    """True poses of every robot, shape (robots, poses, 3): loop k around centre k, alternate directions, each
    starting at the point of its loop nearest the middle."""
    n = c.robots
    middle = c.spacing / (2 * np.sin(np.pi / n))  # centres' distance from the origin
    angles = 2 * np.pi * np.arange(n) / n
    centres = middle * np.stack([np.cos(angles), np.sin(angles)], -1)
    directions = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    phase = angles[:, None] + np.pi + directions[:, None] * np.arange(c.poses)[None, :] * (c.step / c.radius)
    xy = centres[:, None, :] + c.radius * np.stack([np.cos(phase), np.sin(phase)], -1)
    heading = wrap(phase + directions[:, None] * np.pi / 2)
    return np.concatenate([xy, heading[..., None]], -1)


def _robot_sightings(c: MeetConfig, truth: Array, rng: np.random.Generator) -> list[tuple[int, int, int, Array]]:
    """Noisy sightings of robot by robot within range: ``(pose index, robot index, seen index, [range, bearing])``
    in time order, then sighting robot, then seen robot."""
    found = []
    for i in range(c.poses):
        for a in range(c.robots):
            for b in range(c.robots):
                if a != b and np.hypot(*(truth[b, i, :2] - truth[a, i, :2])) <= c.sensor_range:
                    found.append((i, a, b))
    z = range_bearing(np.array([truth[a, i] for i, a, _ in found]).reshape(-1, 3),
                      np.array([truth[b, i, :2] for i, _, b in found]).reshape(-1, 2))  # fmt: skip
    z = z + rng.normal(size=z.shape) * np.array(c.sensor_sigma)
    z[:, 0], z[:, 1] = np.abs(z[:, 0]), wrap(z[:, 1])
    return [(i, a, b, z[k]) for k, (i, a, b) in enumerate(found)]


def meet_world(config: MeetConfig | None = None) -> Iterator[Event]:
    """Several robots whose loops cross (defaults: 3 robots, 300 poses each, 60 shared landmarks).

    Args:
        config: World settings.

    Yields:
        Stream-v1 events naming their robot (1..robots), truth included; every robot starts at its true pose,
        held fixed.
    """
    c = config or MeetConfig()
    if c.robots < 2 or c.poses < 1 or c.step <= 0 or c.sensor_range <= 0 or not 0 < c.spacing < 2 * c.radius:
        raise ValueError("meet world needs robots >= 2, poses >= 1, step and sensor range > 0, 0 < spacing < 2 radius")
    rng = np.random.default_rng(c.seed)
    truth = _loops(c)
    low, high = truth[..., :2].min(axis=(0, 1)) - c.sensor_range, truth[..., :2].max(axis=(0, 1)) + c.sensor_range
    landmarks = rng.uniform(low, high, size=(c.landmarks, 2))
    owner = np.arange(c.landmarks) % c.robots
    odometry, seen = [], []
    for k in range(c.robots):
        odometry.append(between(truth[k, :-1], truth[k, 1:]) + rng.normal(size=(c.poses - 1, 3)) * c.odometry_sigma)
        distances = np.linalg.norm(landmarks[None, :, :] - truth[k, :, None, :2], axis=2)
        visible = (distances <= c.sensor_range) & (c.share_landmarks | (owner == k))[None, :]
        pose, landmark = np.nonzero(visible)
        z = range_bearing(truth[k, pose], landmarks[landmark]) + rng.normal(size=(len(pose), 2)) * c.sensor_sigma
        z[:, 0], z[:, 1] = np.abs(z[:, 0]), wrap(z[:, 1])
        seen.append((np.searchsorted(pose, np.arange(c.poses + 1)), landmark, z))
    robot_z = _robot_sightings(c, truth, rng)
    meta = {"generator": "online-slam simulate meet", **asdict(c), "robots": list(range(1, c.robots + 1))}
    meta["odometry_sigma"], meta["sensor_sigma"] = list(c.odometry_sigma), list(c.sensor_sigma)
    yield Header(name="meet" if c.share_landmarks else "meet-apart", meta=meta)
    for k in range(c.robots):
        yield Start(t=0.0, pose=tuple(map(float, truth[k, 0])), robot=k + 1)
    for j, place in enumerate(landmarks):
        yield LandmarkTruth(landmark=j, position=tuple(map(float, place)))
    yield from _meet_events(c, truth, odometry, seen, robot_z)


def _meet_events(c: MeetConfig, truth: Array, odometry: list, seen: list, robot_z: list) -> Iterator[Event]:
    """The timed lines of the meet world: per time, every robot's odometry, truth, landmark sightings, then the
    robot sightings (the seen robot's pose of that time is made by then)."""
    odo_sigma, obs_sigma = tuple(map(float, c.odometry_sigma)), tuple(map(float, c.sensor_sigma))
    ids: list[RobotId] = list(range(1, c.robots + 1))
    bounds = np.searchsorted([i for i, *_ in robot_z], np.arange(c.poses + 1))
    for i in range(c.poses):
        t = i * c.dt
        for k in range(c.robots):
            if i > 0:
                yield Odometry(t=t, delta=tuple(map(float, odometry[k][i - 1])), sigma=odo_sigma, robot=ids[k])
            yield Truth(t=t, pose=tuple(map(float, truth[k, i])), robot=ids[k])
        for k in range(c.robots):
            starts, landmark, z = seen[k]
            for m in range(starts[i], starts[i + 1]):
                yield Observation(t, int(landmark[m]), float(z[m, 0]), float(z[m, 1]), obs_sigma, robot=ids[k])
        for _, a, b, z in robot_z[bounds[i] : bounds[i + 1]]:
            yield Observation(t, None, float(z[0]), float(z[1]), obs_sigma, robot=ids[a], robot_seen=ids[b])
