"""Built-in simulated worlds, produced as stream-v1 events (truth included).

``square`` reproduces the article's worked example exactly: the same generator (``default_rng(1616)``), the
same draws in the same order, the same landmark selection, so its numbers match the article's table.
``grid`` is a configurable Manhattan-street world for scale tests; ``waypoint`` a robot wandering towards random
goals over a field of scattered landmarks (slower, with random revisits). Both sense range and bearing by
default, or (``model="xy"``) each landmark's position in the robot frame with independent noise per axis.
``circle`` the Monte Carlo protocol of
Brossard, Barrau & Bonnabel (IEEE Sensors J. 2019, code ``CAOR-MINES-ParisTech/esde``), on which the standard
EKF's inconsistency is textbook, with position sightings as theirs (``circle-rb``: range and bearing). ``meet`` and
``meet-apart`` have several robots (:mod:`~.meet`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between, compose
from online_slam.models.observation import MODEL_NAMES
from online_slam.models.position import position
from online_slam.models.range_bearing import range_bearing
from online_slam.sources.events import (
    Event,
    Header,
    LandmarkId,
    LandmarkTruth,
    Observation,
    Odometry,
    Start,
    Truth,
)
from online_slam.sources.meet import MeetConfig, meet_world
from online_slam.sources.timing import TimingConfig, timing_world

Array = NDArray[np.float64]


def _events(
    name: str,
    meta: dict,
    truth: Array,
    landmarks: Array,
    odometry: Array,
    odometry_sigma: Array,
    observed_pose: NDArray[np.int64],
    observed_landmark: NDArray[np.int64],
    z: Array,
    sensor_sigma: Array,
    dt: float,
    xy: bool = False,
) -> Iterator[Event]:
    """Lay out simulated arrays as a time-ordered event stream (pose i at t = i * dt); z holds ranges and
    bearings, or positions in the robot frame (``xy``), all with the standard deviations ``sensor_sigma``."""
    yield Header(name=name, meta=meta)
    yield Start(t=0.0, pose=tuple(map(float, truth[0])))
    for j, point in enumerate(landmarks):
        yield LandmarkTruth(landmark=j, position=tuple(map(float, point)))
    odo_sigma = tuple(map(float, odometry_sigma))
    obs_sigma = tuple(map(float, sensor_sigma))
    bounds = np.searchsorted(observed_pose, np.arange(len(truth) + 1))
    for i in range(len(truth)):
        t = i * dt
        if i > 0:
            yield Odometry(t=t, delta=tuple(map(float, odometry[i - 1])), sigma=odo_sigma)
        yield Truth(t=t, pose=tuple(map(float, truth[i])))
        for k in range(bounds[i], bounds[i + 1]):
            if xy:
                yield Observation(
                    t=t, landmark=int(observed_landmark[k]), sigma=obs_sigma, xy=(float(z[k, 0]), float(z[k, 1]))
                )
                continue
            yield Observation(
                t=t,
                landmark=int(observed_landmark[k]),
                range=float(z[k, 0]),
                bearing=float(z[k, 1]),
                sigma=obs_sigma,
            )


ARTICLE_SEED = 1616
"""The article's seed of the square world."""


def square_world(seed: int = ARTICLE_SEED) -> Iterator[Event]:
    """The article's square path: 25 poses, 12 landmarks, 95 observations (with seed 1616).

    Args:
        seed: Seed of ``numpy.random.default_rng``; 1616 is the article's.

    Yields:
        Stream-v1 events, 1 s apart, truth included.
    """
    rng = np.random.default_rng(seed)
    corners = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0], [0.0, 0.0]])
    xy = np.vstack([np.linspace(corners[k], corners[k + 1], 6, endpoint=False) for k in range(4)] + [corners[-1:]])
    yaw = np.r_[np.repeat([0.0, np.pi / 2, np.pi, -np.pi / 2], 6), 0.0]
    truth = np.c_[xy, yaw]
    landmarks = np.array(
        [[-1.0, -1.0], [2.0, -1.0], [5.0, -1.0], [5.0, 2.0], [5.0, 5.0], [2.0, 5.0],
         [-1.0, 5.0], [-1.0, 2.0], [1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0]]
    )  # fmt: skip
    odometry_sigma = np.array([0.10, 0.10, 0.04])
    sensor_sigma = np.array([0.06, np.deg2rad(0.8)])
    odometry = between(truth[:-1], truth[1:])
    # Draw order as in the article: all odometry noise first, then one (range, bearing) pair per observation.
    odometry = odometry + rng.normal(size=odometry.shape) * odometry_sigma
    counts = np.where(np.isin(np.arange(len(truth)), [0, 5, 10, 15, 20]), 3, 4)
    distances = np.linalg.norm(landmarks[None, :, :] - truth[:, None, :2], axis=2)
    nearest = [np.argsort(distances[i])[: counts[i]] for i in range(len(truth))]
    observed_pose = np.repeat(np.arange(len(truth)), counts)
    observed_landmark = np.concatenate(nearest)
    z = range_bearing(truth[observed_pose], landmarks[observed_landmark])
    z = z + rng.normal(size=z.shape) * sensor_sigma
    z[:, 1] = wrap(z[:, 1])
    meta = {"generator": "online-slam simulate square", "seed": seed}
    yield from _events(
        "square", meta, truth, landmarks, odometry, odometry_sigma,
        observed_pose, observed_landmark, z, sensor_sigma, dt=1.0,
    )  # fmt: skip


@dataclass(frozen=True)
class GridConfig:
    """A Manhattan-street world: the robot drives along a grid of streets, turning at random crossings."""

    poses: int = 2000
    """Number of poses (odometry steps + 1)."""
    blocks: int = 6
    """Streets form a ``blocks`` x ``blocks`` grid of square blocks."""
    block_size: float = 10.0
    """Edge length of one block, metres."""
    step: float = 1.0
    """Distance driven between poses, metres (must divide ``block_size``)."""
    landmarks: int = 190
    """Number of landmarks, placed uniformly at random over the area plus a margin of half a block."""
    sensor_range: float = 11.0
    """Landmarks within this distance are observed at every pose, metres."""
    odometry_sigma: tuple[float, float, float] = (0.05, 0.05, 0.01)
    """Standard deviations of each odometry increment (dx m, dy m, dtheta rad)."""
    sensor_sigma: tuple[float, float] = (0.05, float(np.deg2rad(0.5)))
    """Standard deviations of range (m) and bearing (rad) (model ``range-bearing``)."""
    model: str = "range-bearing"
    """Sighting model: ``range-bearing``, or ``xy`` (the landmark's position in the robot frame)."""
    xy_sigma: tuple[float, float] = (0.05, 0.05)
    """Standard deviations of dx and dy (m), independent (model ``xy``): the range noise, and about the lateral
    noise of the default bearing noise at 6 m."""
    seed: int = 7
    """Seed of ``numpy.random.default_rng``."""
    dt: float = 1.0
    """Time between poses, seconds."""

    def __post_init__(self) -> None:
        if self.poses < 2 or self.landmarks < 1:
            raise ValueError("a world needs poses >= 2 and landmarks >= 1")
        if self.model not in MODEL_NAMES:
            raise ValueError(f"model must be one of {', '.join(MODEL_NAMES)}, not {self.model!r}")


def grid_world(config: GridConfig | None = None) -> Iterator[Event]:
    """A configurable street-grid world for scale tests.

    Args:
        config: World settings; defaults give 2000 poses, ~190 landmarks, ~13 observations per pose.

    Yields:
        Stream-v1 events, truth included.
    """
    c = config or GridConfig()
    per_block = round(c.block_size / c.step)
    if c.poses < 2 or c.blocks < 1 or per_block < 1 or not np.isclose(per_block * c.step, c.block_size):
        raise ValueError("grid world needs poses >= 2, blocks >= 1 and a step that divides block_size")
    rng = np.random.default_rng(c.seed)
    size = c.blocks * c.block_size
    margin = c.block_size / 2
    landmarks = rng.uniform(-margin, size + margin, size=(c.landmarks, 2))
    headings = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])
    moves = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])
    cell = np.array([c.blocks // 2, c.blocks // 2]) * per_block  # start at the central crossing (units of `step`)
    direction = 0
    limit = c.blocks * per_block
    truth = np.empty((c.poses, 3))
    turns = rng.integers(0, 1 << 30, size=c.poses)
    for i in range(c.poses):
        truth[i] = [cell[0] * c.step, cell[1] * c.step, headings[direction]]
        if i + 1 == c.poses:
            break
        cell = cell + moves[direction]
        if cell[0] % per_block == 0 and cell[1] % per_block == 0:
            # At a crossing: go straight, left or right (never back), staying inside the grid.
            options = [d for d in (direction, (direction + 1) % 4, (direction + 3) % 4)
                       if 0 <= cell[0] + moves[d][0] * per_block <= limit
                       and 0 <= cell[1] + moves[d][1] * per_block <= limit]  # fmt: skip
            direction = options[turns[i] % len(options)]
    yield from _sensed("grid", c, rng, truth, landmarks)


@dataclass(frozen=True)
class WaypointConfig:
    """A random-waypoint world: the robot drives towards random goals over a square field of scattered
    landmarks, turning at a bounded rate, so its path wanders, crosses itself and revisits places at random."""

    poses: int = 5000
    """Number of poses (odometry steps + 1)."""
    size: float = 150.0
    """Edge of the square field, metres (landmarks anywhere in it; the goals keep ``sensor_range`` inside)."""
    landmarks: int = 1500
    """Number of landmarks, uniform over the field."""
    step: float = 0.5
    """Distance driven between poses, metres."""
    max_turn: float = 0.2
    """Largest heading change per pose, radians."""
    sensor_range: float = 6.0
    """Landmarks within this distance are observed at every pose, metres."""
    min_range: float = 0.5
    """Landmarks closer than this are not observed (the sensor's blind zone; the robot drives over landmarks
    here). Without it a sighting at a few centimetres (range noise 5 cm) carries a bearing the pose cannot
    explain but by sitting on the landmark: the batch's information grew without bound there and its solution
    depended on where it started."""
    odometry_sigma: tuple[float, float, float] = (0.05, 0.05, 0.01)
    """Standard deviations of each odometry increment (dx m, dy m, dtheta rad)."""
    sensor_sigma: tuple[float, float] = (0.05, float(np.deg2rad(0.5)))
    """Standard deviations of range (m) and bearing (rad) (model ``range-bearing``)."""
    model: str = "range-bearing"
    """Sighting model: ``range-bearing``, or ``xy`` (the landmark's position in the robot frame)."""
    xy_sigma: tuple[float, float] = (0.05, 0.05)
    """Standard deviations of dx and dy (m), independent (model ``xy``): the range noise, and about the lateral
    noise of the default bearing noise at 6 m."""
    seed: int = 7
    """Seed of ``numpy.random.default_rng``."""
    dt: float = 1.0
    """Time between poses, seconds."""

    def __post_init__(self) -> None:
        if self.poses < 2 or self.landmarks < 1:
            raise ValueError("a world needs poses >= 2 and landmarks >= 1")
        if self.model not in MODEL_NAMES:
            raise ValueError(f"model must be one of {', '.join(MODEL_NAMES)}, not {self.model!r}")


def waypoint_world(config: WaypointConfig | None = None) -> Iterator[Event]:
    """A random-waypoint world (defaults: 5000 poses, 1500 landmarks over 150 m, 0.5 m steps, 6 m range).

    Args:
        config: World settings.

    Yields:
        Stream-v1 events, truth included.
    """
    c = config or WaypointConfig()
    if c.poses < 2 or c.step <= 0 or c.max_turn <= 0 or c.size <= 2 * c.sensor_range or c.sensor_range <= 0:
        raise ValueError("waypoint world needs poses >= 2, step and max_turn > 0, size > 2 x sensor range > 0")
    if not 0.0 <= c.min_range < c.sensor_range:
        raise ValueError("waypoint world needs 0 <= min range < sensor range")
    rng = np.random.default_rng(c.seed)
    landmarks = rng.uniform(0.0, c.size, size=(c.landmarks, 2))
    goals = rng.uniform(c.sensor_range, c.size - c.sensor_range, size=(c.poses, 2))
    truth = np.empty((c.poses, 3))
    position, heading, goal = np.full(2, c.size / 2), 0.0, 0
    for i in range(c.poses):
        truth[i] = [position[0], position[1], heading]
        to_goal = goals[goal] - position
        if np.hypot(*to_goal) < 2 * c.step:  # reached: the next goal
            goal += 1
            to_goal = goals[goal] - position
        turn = float(np.clip(wrap(np.arctan2(to_goal[1], to_goal[0]) - heading), -c.max_turn, c.max_turn))
        heading = float(wrap(heading + turn))
        position = position + c.step * np.array([np.cos(heading), np.sin(heading)])
    yield from _sensed("waypoint", c, rng, truth, landmarks, c.min_range)


def _sensed(
    name: str,
    c: GridConfig | WaypointConfig,
    rng: np.random.Generator,
    truth: Array,
    landmarks: Array,
    min_range: float = 0.0,
) -> Iterator[Event]:
    """Noisy odometry, then a noisy sighting of every landmark within range (and not closer than ``min_range``)
    of every pose, as events (the draws in this order, after the world's own)."""
    if c.model not in MODEL_NAMES:
        raise ValueError(f"the sighting model must be one of {', '.join(MODEL_NAMES)}, not {c.model!r}")
    xy = c.model == "xy"
    odometry_sigma = np.array(c.odometry_sigma, dtype=float)
    sensor_sigma = np.array(c.xy_sigma if xy else c.sensor_sigma, dtype=float)
    odometry = between(truth[:-1], truth[1:])
    odometry = odometry + rng.normal(size=odometry.shape) * odometry_sigma
    distances = np.linalg.norm(landmarks[None, :, :] - truth[:, None, :2], axis=2)
    observed_pose, observed_landmark = np.nonzero((distances <= c.sensor_range) & (distances >= min_range))
    z = (position if xy else range_bearing)(truth[observed_pose], landmarks[observed_landmark])
    z = z + rng.normal(size=z.shape) * sensor_sigma
    if not xy:
        z[:, 0] = np.abs(z[:, 0])
        z[:, 1] = wrap(z[:, 1])
    sensor = ("xy_sigma", "model") if xy else ("sensor_sigma",)
    fields = [k for k in c.__dataclass_fields__ if k in sensor or k not in ("sensor_sigma", "model", "xy_sigma")]
    meta = {"generator": f"online-slam simulate {name}", **{k: getattr(c, k) for k in fields}}
    meta["odometry_sigma"] = list(c.odometry_sigma)
    meta[sensor[0]] = list(getattr(c, sensor[0]))
    yield from _events(
        name, meta, truth, landmarks, odometry, odometry_sigma,
        observed_pose, observed_landmark, z, sensor_sigma, dt=c.dt, xy=xy,
    )  # fmt: skip


@dataclass(frozen=True)
class CircleConfig:
    """The Monte Carlo world of Brossard, Barrau & Bonnabel 2019 (``esde``: ``simulations/main.m``, ``rws.m``,
    ``gen_map.m``): a unicycle on a circle inside a ring of landmarks, the same landmarks in every run."""

    poses: int = 400
    """Number of poses (esde's ``nSteps``)."""
    v: float = 0.25
    """True forward speed, m/s."""
    omega: float = 0.075
    """True turn rate, rad/s."""
    dt: float = 1.0
    """Time between poses, seconds."""
    landmarks: int = 15
    """Landmarks, evenly on a circle of radius ``v / omega + 2 min_range``; landmark j at angle 2 pi (j + 1) / n."""
    center: tuple[float, float] = (0.1251, 3.3318)
    """Centre of the landmarks' circle, metres (esde's ``cx``, ``cy``)."""
    min_range: float = 0.5
    """A landmark is seen when ``min_range < range < max_range`` (strict), metres."""
    max_range: float = 5.0
    """See ``min_range``, metres."""
    sigma_v: float = 0.02 / math.sqrt(2.0)
    """Noise on the measured speed, m/s."""
    sigma_omega: float = 2.0 * math.sqrt(2.0) * 0.02
    """Noise on the measured turn rate, rad/s."""
    lateral_sigma: float = 1e-6
    """Standard deviation given to the increment's lateral component, metres. The velocity-input increment
    ``(v_m dt, 0, omega_m dt)`` has none; stream v1 needs a positive one (at least 1e-8). The EKF's figures are
    the same to 4 digits for 0, 1e-8 and 1e-6 (benchmarks/RESULTS.md, "Circle protocol")."""
    model: str = "xy"
    """``xy`` (esde's): each landmark's position ``(dx, dy)`` in the robot frame, independent noise ``sigma_xy``
    per axis; ``range-bearing``: its range and bearing, noise ``sigma_range`` and ``sigma_bearing``."""
    sigma_xy: float = 0.1
    """Noise of each axis of a position sighting, metres (model ``xy``)."""
    sigma_range: float = 0.1
    """Noise of a sighting's range, metres (model ``range-bearing``): ``sigma_xy``."""
    sigma_bearing: float = 0.04
    """Noise of a sighting's bearing, radians (model ``range-bearing``): ``sigma_xy`` across the ray at 2.5 m, the
    middle of the visible ranges. Drawn in range and bearing, so the stream's noise model is exact (the noise of
    a position sighting propagated to range and bearing is not Gaussian there: its bearing sigma reaches 0.2 rad
    at 0.5 m)."""
    seed: int = 0
    """Seed of ``numpy.random.default_rng``."""

    def __post_init__(self) -> None:
        if self.poses < 2 or self.landmarks < 1 or not 0.0 <= self.min_range < self.max_range:
            raise ValueError("circle world needs poses >= 2, landmarks >= 1 and 0 <= min range < max range")
        if self.model not in MODEL_NAMES:
            raise ValueError(f"circle world: model must be one of {', '.join(MODEL_NAMES)}, not {self.model!r}")

    @property
    def radius(self) -> float:
        """Radius of the landmarks' circle, metres."""
        return self.v / self.omega + 2.0 * self.min_range

    @property
    def sensor_sigma(self) -> tuple[float, float]:
        """Standard deviations of a sighting's two components in its model."""
        return (self.sigma_xy, self.sigma_xy) if self.model == "xy" else (self.sigma_range, self.sigma_bearing)


def circle_landmarks(c: CircleConfig) -> Array:
    """The landmarks of the circle world (esde's ``gen_map``), shape (n, 2)."""
    angle = 2.0 * np.pi * np.arange(1, c.landmarks + 1) / c.landmarks
    return np.c_[c.radius * np.cos(angle), c.radius * np.sin(angle)] + np.array(c.center)


def circle_world(config: CircleConfig | None = None) -> Iterator[Event]:
    """esde's simulation (``rws.m``): truth, velocity-input odometry and sightings, in their order of draws.

    Draw order: the measured speeds of every pose, then the turn rates, then pose by pose each visible
    landmark's 2-D noise (landmarks in order; the same draws for both models). Like esde, the first pose's
    sightings are drawn but not used: the first pose is known exactly, and sightings from it would anchor the
    map to the truth.

    Args:
        config: World settings; the defaults are esde's.

    Yields:
        Stream-v1 events, truth included.
    """
    c = config or CircleConfig()
    rng = np.random.default_rng(c.seed)
    landmarks = circle_landmarks(c)
    step = np.array([c.v * c.dt, 0.0, c.omega * c.dt])
    truth = np.zeros((c.poses, 3))
    for i in range(1, c.poses):
        truth[i] = compose(truth[i - 1], step)
    v_m = c.v + c.sigma_v * rng.normal(size=c.poses)
    omega_m = c.omega + c.sigma_omega * rng.normal(size=c.poses)
    odometry = np.c_[v_m * c.dt, np.zeros(c.poses), omega_m * c.dt][:-1]
    odometry_sigma = np.array([c.sigma_v * c.dt, c.lateral_sigma, c.sigma_omega * c.dt])
    distances = np.linalg.norm(landmarks[None, :, :] - truth[:, None, :2], axis=2)
    observed_pose, observed_landmark = np.nonzero((distances > c.min_range) & (distances < c.max_range))
    xy = c.model == "xy"
    z = (position if xy else range_bearing)(truth[observed_pose], landmarks[observed_landmark])
    z = z + np.array(c.sensor_sigma) * rng.normal(size=z.shape)
    if not xy:
        z[:, 0], z[:, 1] = np.abs(z[:, 0]), wrap(z[:, 1])
    used = observed_pose > 0
    name = "circle" if xy else "circle-rb"
    meta = {"generator": f"online-slam simulate {name}", **asdict(c)}
    yield from _events(
        name, meta, truth, landmarks, odometry, odometry_sigma,
        observed_pose[used], observed_landmark[used], z[used], np.array(c.sensor_sigma), dt=c.dt, xy=xy,
    )  # fmt: skip


@dataclass(frozen=True)
class Contamination:
    """Outliers to add to a simulated stream, each sighting marked for evaluation (``truth_outlier``)."""

    wrong_ids: float = 0.0
    """Fraction of sightings given a random other existing landmark's id (a data-association mistake)."""
    range_spikes: float = 0.0
    """Fraction of sightings whose range (a position sighting: its vector) is scaled by a random factor in [1.5, 3]
    or [1/3, 1/1.5]."""
    clutter: float = 0.0
    """Extra sightings of landmarks that do not exist, as a fraction of the real ones (of the same model); random
    range within the observed ranges, random bearing; their ids come from a pool of phantom ids (``clutter-k``) a
    quarter the size of the map, so the same phantom is "seen" in unrelated places."""
    seed: int = 0
    """Seed of the contamination draws (separate from the world's: the clean part stays the same)."""

    def __post_init__(self) -> None:
        for name in ("wrong_ids", "range_spikes", "clutter"):
            value = getattr(self, name)
            if not (0.0 <= value <= 1.0 if name != "clutter" else 0.0 <= value <= 10.0):
                raise ValueError(f"{name} must be a fraction in [0, 1] (clutter: [0, 10]), not {value}")

    @property
    def any(self) -> bool:
        """True when some contamination is asked for."""
        return bool(self.wrong_ids or self.range_spikes or self.clutter)


def contaminate(events: Iterable[Event], c: Contamination) -> Iterator[Event]:
    """The same stream with outliers: wrong ids, range spikes, clutter (marked ``truth_outlier``).

    Each real sighting is corrupted with probability ``wrong_ids`` (else ``range_spikes``); clutter sightings
    follow the real ones of a pose. The header records the contamination.
    """
    rng = np.random.default_rng(c.seed)
    ids: list[LandmarkId] = []
    ranges: list[float] = []
    phantoms = 1
    for event in events:
        if isinstance(event, Header):
            yield replace(event, meta={**event.meta, "contamination": asdict(c)})
            continue
        if isinstance(event, LandmarkTruth):
            ids.append(event.landmark)
            phantoms = max(1, len(ids) // 4)
        if not isinstance(event, Observation) or event.robot_seen is not None:  # robot sightings stay clean
            yield event
            continue
        ranges.append(event.z[0] if event.xy is None else float(np.hypot(event.xy[0], event.xy[1])))  # z: range first
        u = rng.uniform()
        if u < c.wrong_ids and len(ids) > 1:
            others = [lid for lid in ids if lid != event.landmark]
            event = replace(event, landmark=others[int(rng.integers(len(others)))], truth_outlier="wrong_id")
        elif u < c.wrong_ids + c.range_spikes:
            factor = float(rng.uniform(1.5, 3.0) ** rng.choice([-1.0, 1.0]))
            event = replace(event, **_scaled(event, factor), truth_outlier="spike")
        yield event
        for _ in range(rng.poisson(c.clutter) if c.clutter else 0):
            phantom = f"clutter-{int(rng.integers(phantoms))}"  # the draws in this order: id, range, bearing
            r, b = float(rng.uniform(0.5, max(ranges))), float(rng.uniform(-np.pi, np.pi))
            measured = {"range": r, "bearing": b} if event.xy is None else {"xy": (r * np.cos(b), r * np.sin(b))}
            yield replace(event, landmark=phantom, **measured, truth_outlier="clutter")


def _scaled(event: Observation, factor: float) -> dict[str, Any]:
    """The fields of a sighting moved ``factor`` times as far along its ray (a range spike)."""
    if event.xy is None:
        return {"range": event.z[0] * factor}  # z: (range, bearing)
    return {"xy": (event.xy[0] * factor, event.xy[1] * factor)}


@dataclass(frozen=True)
class World:
    """A built-in simulated world: its events for any noise seed."""

    build: Callable[[int], Iterator[Event]]
    """The world's events (truth included) for a seed."""
    seed: int
    """Its default seed; Monte Carlo runs and sweeps use ``seed``, ``seed + 1``, ..."""
    description: str
    """One line for help texts."""
    scored: tuple[int, int] | None = None
    """Steps (first, last; 0-based, inclusive) over which Monte Carlo averages NEES and RMSE over steps; None:
    every step that has a NEES (all but a fixed start pose)."""

    def events(self, seed: int | None = None) -> Iterator[Event]:
        """The world's events for ``seed`` (None: the default seed)."""
        return self.build(self.seed if seed is None else seed)


def _grid(seed: int) -> Iterator[Event]:
    return grid_world(GridConfig(seed=seed))


def _waypoint(seed: int) -> Iterator[Event]:
    return waypoint_world(WaypointConfig(seed=seed))


def _circle(seed: int) -> Iterator[Event]:
    return circle_world(CircleConfig(seed=seed))


def _circle_rb(seed: int) -> Iterator[Event]:
    return circle_world(CircleConfig(model="range-bearing", seed=seed))


def _meet(seed: int) -> Iterator[Event]:
    return meet_world(MeetConfig(seed=seed))


def _timing(seed: int) -> Iterator[Event]:
    return timing_world(TimingConfig(seed=seed))


def _meet_apart(seed: int) -> Iterator[Event]:
    return meet_world(MeetConfig(robots=2, share_landmarks=False, seed=seed))


WORLDS: dict[str, World] = {
    "square": World(square_world, ARTICLE_SEED, "the article's square path: 25 poses, 12 landmarks"),
    "grid": World(
        _grid, GridConfig.seed, f"Manhattan streets: {GridConfig.poses} poses, {GridConfig.landmarks} landmarks"
    ),
    "waypoint": World(
        _waypoint,
        WaypointConfig.seed,
        f"random waypoints: {WaypointConfig.poses} poses, {WaypointConfig.landmarks} landmarks",
    ),
    "circle": World(
        _circle,
        CircleConfig.seed,
        f"esde's Monte Carlo protocol: {CircleConfig.poses} poses on a circle, {CircleConfig.landmarks} landmarks "
        "sighted as positions in the robot frame",
        scored=(4, CircleConfig.poses - 2),  # esde's steps 5..399 (1-based)
    ),
    "circle-rb": World(
        _circle_rb,
        CircleConfig.seed,
        "circle with range-bearing sightings",
        scored=(4, CircleConfig.poses - 2),
    ),
    "meet": World(
        _meet,
        MeetConfig.seed,
        f"{MeetConfig.robots} robots on crossing loops: {MeetConfig.poses} poses each, {MeetConfig.landmarks} "
        "shared landmarks, robot sightings",
    ),
    "meet-apart": World(
        _meet_apart, MeetConfig.seed, "2 robots on crossing loops sharing no landmark: only robot sightings link them"
    ),
    "timing": World(
        _timing,
        TimingConfig.seed,
        f"sensors off the odometry clock: {TimingConfig.duration:g} s at {TimingConfig.speed:g} m/s, odometry at "
        f"{TimingConfig.odometry_rate:g} Hz, sighting scans at {TimingConfig.sighting_rate:g} Hz "
        f"{TimingConfig.offset * 1e3:g} ms after a tick",
    ),
}
"""The built-in worlds by name: ``simulate``, ``replay``, ``compare`` and ``sweep`` all read this registry."""
CIRCLE_WORLDS = {"xy": "circle", "range-bearing": "circle-rb"}
"""The circle world by sighting model (``simulate circle --model``)."""


def without_ids(events: Iterable[Event]) -> Iterator[Event]:
    """The same stream with every sighting's landmark id removed (unknown data association); truth kept.

    A removed id becomes the sighting's hidden truth (``truth_landmark``), so that the association can be scored;
    not on a sighting marked ``wrong_id`` or ``clutter``, whose id is not its true landmark.
    """
    for event in events:
        if isinstance(event, Observation):
            true_id = event.truth_landmark
            if true_id is None and event.truth_outlier not in ("wrong_id", "clutter"):
                true_id = event.landmark
            event = replace(event, landmark=None, truth_landmark=true_id)
        yield event
