"""A world of unsynchronised sensors: sightings off the odometry clock, lines that arrive late.

The odometry reports a constant speed with a turn rate that changes only at ticks; the true path leaves it by a
random walk of slip, drawn at 20 substeps per tick (``continuous``), so the odometry's error over a stretch of time
has a covariance in proportion to it, as the front-end's split assumes; or (``continuous=False``) the true path
moves at constant twist and each tick's increment carries one draw of noise. Odometry comes at ``odometry_rate``;
a sighting scan every ``1 / sighting_rate`` seconds, ``offset`` seconds after a tick, taken from the true pose at
its own time (the truth is given there too). With ``offset`` 0 it is the synchronised twin: every random number is
drawn in the same order and used for the same thing (the landmarks in view are chosen at the tick), so the two
streams differ only in timing. ``delay`` makes a sighting line arrive up to that much later (the events then come
in arrival order, as a detector's would). The first scan follows the first ``1 / sighting_rate`` seconds of
odometry: a scan at the start pose, which is held fixed, would tie the twin's map to the start's frame exactly and
the other's through 40 ms of odometry, a difference of frame (a rotation of the whole map) that no front-end makes.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, compose, exp
from online_slam.models.range_bearing import range_bearing
from online_slam.sources.events import Event, Header, LandmarkTruth, Observation, Odometry, Start, Truth

Array = NDArray[np.float64]


SUBSTEPS = 20
"""Substeps per odometry tick of the simulated slip (5 ms at 10 Hz): scans fall on them."""


@dataclass(frozen=True)
class TimingConfig:
    """A drive among scattered landmarks with sensors on their own clocks."""

    duration: float = 120.0
    """Seconds driven."""
    speed: float = 1.0
    """Forward speed, m/s."""
    max_turn_rate: float = 0.4
    """Largest turn rate, rad/s (drawn anew every ``turn_every`` seconds)."""
    turn_every: float = 2.0
    """Seconds between changes of the turn rate."""
    area: float = 15.0
    """Radius of the area driven in, metres: outside it the robot turns back towards its start."""
    odometry_rate: float = 10.0
    """Odometry ticks per second."""
    sighting_rate: float = 2.0
    """Sighting scans per second."""
    offset: float = 0.04
    """Seconds from a tick to its scan (0: the synchronised twin; less than one tick)."""
    delay: float = 0.0
    """Each sighting line arrives up to this many seconds late (uniform), so events come in arrival order."""
    landmarks: int = 200
    """Landmarks, uniform over the drive's bounding box grown by ``sensor_range``."""
    sensor_range: float = 8.0
    """Landmarks within this distance of the tick's pose are sighted, metres."""
    odometry_sigma: tuple[float, float, float] = (0.01, 0.01, 0.004)
    """Standard deviations of each odometry increment (dx m, dy m, dtheta rad)."""
    sensor_sigma: tuple[float, float] = (0.05, 0.01)
    """Standard deviations of range (m) and bearing (rad)."""
    mount: tuple[float, float, float] | None = None
    """Pose ``[x, y, theta]`` of the sensor in the robot frame (declared in the header as ``camera``; sightings
    taken from it), or None: at the robot's centre."""
    continuous: bool = True
    """Odometry error that accumulates as the robot drives (a random walk of slip, as wheels slip: the true path
    leaves the odometry's between ticks too), the model the front-end's split assumes; False: the true path moves
    at constant twist between ticks and each tick's increment is measured with one draw of noise."""
    seed: int = 5
    """Seed of ``numpy.random.default_rng``."""

    def __post_init__(self) -> None:
        tick = 1.0 / self.odometry_rate
        if abs(self.offset / tick * SUBSTEPS - round(self.offset / tick * SUBSTEPS)) > 1e-9:
            raise ValueError(f"timing world: offset must be a multiple of 1/{SUBSTEPS} of a tick")
        if not 0.0 <= self.offset < tick or self.sighting_rate > self.odometry_rate or self.delay < 0.0:
            raise ValueError("timing world needs 0 <= offset < one tick, sighting rate <= odometry rate, delay >= 0")


def timing_world(config: TimingConfig | None = None) -> Iterator[Event]:
    """The world's events: time order, or arrival order with ``delay`` (truth at the ticks included).

    Args:
        config: World settings.

    Yields:
        Stream-v1 events.
    """
    c = config or TimingConfig()
    rng = np.random.default_rng(c.seed)
    arrival = np.random.default_rng([c.seed, 1])  # delays on their own draws: the data stay those of delay 0
    dt = 1.0 / c.odometry_rate
    ticks = int(round(c.duration * c.odometry_rate))
    per_turn = max(1, int(round(c.turn_every / dt)))
    twists = np.zeros((ticks, 3))  # the odometry's motion per tick interval: [v dt, 0, omega dt]
    twists[:, 0] = c.speed * dt
    sub = SUBSTEPS
    drift = rng.normal(size=(ticks, sub, 3)) * np.array(c.odometry_sigma) / math.sqrt(sub)  # continuous: per substep
    truth = np.zeros((ticks + 1, 3))
    fraction = c.offset / dt
    within = int(round(fraction * sub))  # substeps from a tick to its scan
    between_ticks = np.zeros((ticks, 3))  # the true pose a scan after each tick (continuous noise)
    rate = 0.0
    for k in range(ticks):
        if k % per_turn == 0:  # a new turn rate: random, or back towards the area when outside it
            rate = rng.uniform(-c.max_turn_rate, c.max_turn_rate)
            x, y, heading = truth[k]
            if math.hypot(x, y) > c.area:
                back = float(wrap(math.atan2(-y, -x) - heading)) / c.turn_every
                rate = float(np.clip(back, -c.max_turn_rate, c.max_turn_rate))
        twists[k, 2] = rate * dt
        if not c.continuous:
            truth[k + 1] = compose(truth[k], exp(twists[k]))
            continue
        pose, step = truth[k], exp(twists[k] / sub)
        for j in range(sub):  # the true motion: the odometry's, with a random walk of slip added as it goes
            if j == within:
                between_ticks[k] = pose
            pose = compose(compose(pose, step), drift[k, j])
        truth[k + 1] = pose
    low, high = truth[:, :2].min(0) - c.sensor_range, truth[:, :2].max(0) + c.sensor_range
    landmarks = rng.uniform(low, high, size=(c.landmarks, 2))
    if c.continuous:  # the odometry reports the motion without the slip
        odometry = exp(twists)
    else:  # the truth moves at constant twist; each tick's increment is measured with one draw of noise
        odometry = between(truth[:-1], truth[1:]) + rng.normal(size=(ticks, 3)) * np.array(c.odometry_sigma)
    every = max(1, int(round(c.odometry_rate / c.sighting_rate)))
    scans = np.arange(every, ticks, every)  # the tick each scan follows (none at the fixed start pose: see below)
    # the true pose at each scan's own time
    at_scan = between_ticks[scans] if c.continuous else compose(truth[scans], exp(fraction * twists[scans]))
    robot_at_scan = at_scan
    if c.mount is not None:
        at_scan = compose(at_scan, np.array(c.mount, dtype=float))  # the sensor's pose
    events: list[tuple[float, int, Event]] = []  # (arrival time, order, event)
    meta = {"generator": "online-slam timing world", **{k: getattr(c, k) for k in c.__dataclass_fields__}}
    meta["odometry_sigma"], meta["sensor_sigma"] = list(c.odometry_sigma), list(c.sensor_sigma)
    del meta["mount"]
    sensor = None
    if c.mount is not None:
        meta["sensors"], sensor = {"camera": {"pose": [float(v) for v in c.mount]}}, "camera"
    events.append((-math.inf, 0, Header(name="timing", meta=meta)))
    events.extend((-math.inf, 1, LandmarkTruth(i, tuple(map(float, p)))) for i, p in enumerate(landmarks))
    events.append((0.0, 2, Start(0.0, (0.0, 0.0, 0.0))))
    events.append((0.0, 3, Truth(0.0, (0.0, 0.0, 0.0))))
    odometry_sigma, sensor_sigma = tuple(map(float, c.odometry_sigma)), tuple(map(float, c.sensor_sigma))
    for k in range(ticks):
        t = (k + 1) * dt
        events.append((t, 2, Odometry(t, tuple(map(float, odometry[k])), odometry_sigma)))
        events.append((t, 3, Truth(t, tuple(map(float, truth[k + 1])))))
    for scan, tick in enumerate(scans):
        distances = np.linalg.norm(landmarks - truth[tick, :2], axis=1)
        seen = np.flatnonzero(distances <= c.sensor_range)
        z = range_bearing(np.broadcast_to(at_scan[scan], (len(seen), 3)), landmarks[seen])
        z = z + rng.normal(size=z.shape) * np.array(c.sensor_sigma)
        late = arrival.uniform(0.0, c.delay, size=len(seen)) if c.delay > 0.0 else np.zeros(len(seen))
        t = float(tick * dt + c.offset)
        if c.offset > 0.0:  # the robot's true pose at the scan (a pose of its own: scored too)
            events.append((t, 3, Truth(t, tuple(map(float, robot_at_scan[scan])))))
        for i, lid in enumerate(seen):
            rb = (float(abs(z[i, 0])), float(wrap(z[i, 1])))
            sighting = Observation(t, int(lid), rb[0], rb[1], sensor_sigma, sensor=sensor)
            events.append((t + float(late[i]), 4, sighting))
    events.sort(key=lambda e: (e[0], e[1]))  # stable: ties keep the order made
    for _, _, event in events:
        yield event
