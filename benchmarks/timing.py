"""The front-end's timing: sightings between odometry ticks, lines that arrive late, lines of one time in any
order, and what the reorder buffer costs per step.

Sightings 40 ms after the ticks are compared with their synchronised twin (the same random draws, sightings at
the ticks) over seeded worlds, as means over seeds, in the frame that best fits the truth (``--align se2``). In the
frame of the first pose (the default ``anchor``) the errors are mostly the whole map's rotation against the start's
frame, which each run's first scans fix by chance (the benchmark prints both). Neither twin scans at the fixed start
pose: a scan there would tie the twin's map to the start's frame exactly and the other's through 40 ms of odometry
(NEES 0.88x of the twin's, a difference of frame, not of estimate). Beside them, the same asynchronous sightings
attached to the earlier tick (what the front-end did before it split increments) show what ignoring the timing costs.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from online_slam import Slam, replay
from online_slam.evaluation.results import Results
from online_slam.options import replay_config
from online_slam.sources.events import Event, Header, Observation, Odometry, Start, Truth
from online_slam.sources.timing import TimingConfig, timing_world
from online_slam.sources.worlds import GridConfig, grid_world

ESTIMATORS = ("ekf", "smoother", "batch")
MOUNT = (0.3, 0.0, math.radians(10.0))
"""The issue's sensor: 0.3 m ahead, turned 10 degrees."""


@dataclass(frozen=True)
class TimingRow:
    """Mean figures of one kind of stream over the seeds."""

    label: str
    """What the stream is."""
    online: dict[str, float]
    """Mean online position RMSE by estimator (the batch: its final), metres."""
    nees: dict[str, float]
    """Mean of each run's mean NEES by online estimator."""


def _figures(events: list[Event], **options: object) -> tuple[dict[str, float], dict[str, float], Results]:
    """Replay with the estimators and CLI-named options: mean online RMSE (batch: final), mean NEES, results."""
    results = replay(events, replay_config({"estimators": ",".join(ESTIMATORS), **options}))
    rows = results.rows()
    online = {n: float(rows[n].online_rmse_m if n != "batch" else rows[n].final_rmse_m) for n in ESTIMATORS}
    nees = {n: float(rows[n].nees_mean) for n in ("ekf", "smoother")}
    return online, nees, results


def _largest_change(a: Results, b: Results) -> float:
    """Largest relative change between two replays' figures (online, final and landmark RMSE; NEES)."""
    change = 0.0
    for name, row in a.rows().items():
        other = b.rows()[name]
        for key in ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "nees_mean"):
            x, y = getattr(row, key), getattr(other, key)
            if x is not None and y is not None and x == x and x != 0:
                change = max(change, abs(y - x) / abs(x))
    return change


def _means(sums: dict[str, list[tuple[dict[str, float], dict[str, float]]]], labels: dict[str, str]) -> list[TimingRow]:
    """One row per kind of stream: the means over the seeds of its (online RMSE, NEES) figures."""
    return [
        TimingRow(
            labels[key],
            {n: float(np.mean([r[0][n] for r in runs])) for n in ESTIMATORS},
            {n: float(np.mean([r[1][n] for r in runs])) for n in ("ekf", "smoother")},
        )
        for key, runs in sums.items()
    ]


def attached_early(events: Iterable[Event], tick: float, offset: float) -> list[Event]:
    """The stream with each sighting moved back to the tick before it (the front-end's old attachment)."""
    moved = [
        dataclasses.replace(e, t=round((e.t - offset) / tick) * tick) if isinstance(e, Observation) else e
        for e in events
    ]
    return sorted(moved, key=lambda e: getattr(e, "t", -math.inf))


def twin_rows(
    seeds: Sequence[int], duration: float = 60.0, offset: float = 0.04, align: str = "se2"
) -> list[TimingRow]:
    """Mean figures over the seeds: synchronised, sightings ``offset`` after the ticks, and those attached early."""
    sums: dict[str, list[tuple[dict[str, float], dict[str, float]]]] = {"twin": [], "async": [], "early": []}
    for seed in seeds:
        c = TimingConfig(seed=seed, duration=duration, offset=offset)
        twin = list(timing_world(dataclasses.replace(c, offset=0.0)))
        late = list(timing_world(c))
        for label, events in (("twin", twin), ("async", late), ("early", attached_early(late, 0.1, offset))):
            online, nees, _ = _figures(events, align=align)
            sums[label].append((online, nees))
    labels = {
        "twin": "synchronised twin (sightings at the ticks)",
        "async": f"sightings {offset * 1e3:.0f} ms after the ticks, split increments",
        "early": "the same, attached to the tick before (no split)",
    }
    return _means(sums, labels)


@dataclass(frozen=True)
class LatencyCheck:
    """A stream in arrival order through the reorder buffer beside the same stream in time order."""

    largest_change: float
    """Largest relative change of a figure (online, final, landmark RMSE; NEES), replay in arrival order."""
    skipped: int
    """Lines skipped as too late."""
    slam_gap_m: float
    """Largest distance between the trajectories of ``Slam`` fed in arrival and in time order, metres (the poses
    both have: the held one lacks the last ``budget`` seconds)."""
    slam_lag: int
    """Poses the held ``Slam`` has not made yet at the end (its lines within the budget are still held)."""
    slam_now_gap_m: float
    """Distance between the two ``Slam``'s poses predicted to the last odometry's time, metres."""
    out_of_order: int
    """Sighting lines that arrive after a later odometry line."""


def latency_check(seed: int = 5, duration: float = 60.0, delay: float = 0.15, budget: float = 0.2) -> LatencyCheck:
    """Every sighting line delayed by up to ``delay`` seconds, replayed with ``--max-latency budget``."""
    c = TimingConfig(seed=seed, duration=duration)
    ordered = list(timing_world(c))
    arriving = list(timing_world(dataclasses.replace(c, delay=delay)))
    newest, out_of_order = -math.inf, 0
    for e in arriving:
        if isinstance(e, Odometry):
            newest = max(newest, e.t)
        elif isinstance(e, Observation) and e.t < newest:
            out_of_order += 1
    _, _, base = _figures(ordered)
    _, _, held = _figures(arriving, max_latency=budget)
    skipped = sum(held.input.skipped_by_reason.values())
    gap, lag, now = _slam_gap(ordered, arriving, budget)
    return LatencyCheck(_largest_change(base, held), skipped, gap, lag, now, out_of_order)


def _slam_gap(ordered: list[Event], arriving: list[Event], budget: float) -> tuple[float, int, float]:
    """``Slam`` fed in time order (no budget) and in arrival order (``budget``), querying after each odometry:
    the largest distance between their trajectories' common poses, the poses the held one lacks at the end, and
    the distance between their poses predicted to the last odometry's time."""
    estimates = []
    last = max(e.t for e in ordered if isinstance(e, Odometry))
    for events, latency in ((ordered, 0.0), (arriving, budget)):
        slam = Slam("smoother", max_latency=latency)
        for event in events:
            slam.add(event)
            if isinstance(event, Odometry):
                slam.estimate(landmark_covs=False)  # a robot's loop queries as it goes
        estimates.append((slam.estimate(landmark_covs=False, held=False), slam.estimate(landmark_covs=False, at=last)))
    (whole, now), (held, held_now) = estimates
    n = len(held.trajectory)
    gap = float(np.max(np.linalg.norm(whole.trajectory[:n, :2] - held.trajectory[:, :2], axis=1)))
    return gap, len(whole.trajectory) - n, float(np.linalg.norm(now.pose[:2] - held_now.pose[:2]))


@dataclass(frozen=True)
class LiveRow:
    """What a robot's loop reads: ``Slam.estimate(at=t)`` at each odometry line's arrival, against the truth at t
    (position RMSE over the queries, metres; one estimator, means over the seeds)."""

    estimator: str
    """The estimator."""
    ordered_m: float
    """Every line in time order, no budget (nothing late: the best a query can do)."""
    predicted_m: float
    """Sightings 0-``delay`` s late, ``--max-latency`` budget, ``held=False``: the held odometry predicted."""
    held_m: float
    """The same with ``held=True`` (the default): the held lines given to a copy at their times."""
    worst: tuple[float, float]
    """Worst ratio over the seeds to the ordered feed, predicted and held."""
    query_ms: tuple[float, float, float]
    """Median milliseconds per odometry line of the lines added and the query: ordered, predicted, held."""


def _live_rmse(events: list[Event], estimator: str, budget: float, held: bool) -> tuple[float, float]:
    """Position RMSE of the queries at each odometry line's arrival, and the median milliseconds from one query to
    the end of the next (the lines added between and the query: what the loop pays per odometry line)."""
    truth = {round(e.t, 6): np.array(e.pose[:2]) for e in events if isinstance(e, Truth)}
    slam = Slam(estimator, max_latency=budget)
    errors, seconds, started = [], [], time.perf_counter()
    for event in events:
        slam.add(event)
        if isinstance(event, Odometry):
            estimate = slam.estimate(landmark_covs=False, at=event.t, held=held)
            seconds.append(time.perf_counter() - started)
            errors.append(float(np.linalg.norm(estimate.pose[:2] - truth[round(event.t, 6)])))
            started = time.perf_counter()
    return math.sqrt(float(np.mean(np.square(errors)))), 1e3 * float(np.median(seconds))


def live_rows(seeds: Sequence[int], duration: float = 60.0, delay: float = 0.15, budget: float = 0.2) -> list[LiveRow]:
    """Queries in a robot's loop with sightings arriving late, beside the same lines in time order."""
    rows = []
    for estimator in ("ekf", "smoother"):
        figures = []
        for seed in seeds:
            c = TimingConfig(seed=seed, duration=duration)
            arriving = list(timing_world(dataclasses.replace(c, delay=delay)))
            ordered = _live_rmse(list(timing_world(c)), estimator, 0.0, True)
            predicted = _live_rmse(arriving, estimator, budget, False)
            figures.append((ordered, predicted, _live_rmse(arriving, estimator, budget, True)))
        f = np.array(figures)  # (seeds, 3 feeds, rmse / ms)
        mean = f[:, :, 0].mean(axis=0)
        worst = (float((f[:, 1, 0] / f[:, 0, 0]).max()), float((f[:, 2, 0] / f[:, 0, 0]).max()))
        ms = np.median(f[:, :, 1], axis=0)
        rows.append(LiveRow(estimator, float(mean[0]), float(mean[1]), float(mean[2]), worst, tuple(map(float, ms))))
    return rows


def same_time_change(seed: int = 5, duration: float = 60.0) -> float:
    """Largest relative change of a figure when each sighting line comes before the odometry of its time."""
    events = list(timing_world(TimingConfig(seed=seed, duration=duration, offset=0.0)))
    rank = {Start: -1, Observation: 0, Odometry: 1}
    swapped = sorted(events, key=lambda e: (getattr(e, "t", -math.inf), rank.get(type(e), 2)))
    assert swapped != events
    _, _, a = _figures(events)
    _, _, b = _figures(swapped)
    return _largest_change(a, b)


def buffer_cost(poses: int = 2000, repeats: int = 3) -> tuple[float, float]:
    """Seconds of a grid replay (EKF and smoother) without and with a 0.2 s reorder buffer, best of ``repeats``,
    interleaved."""
    events = list(grid_world(GridConfig(poses=poses)))
    best = [math.inf, math.inf]
    for _ in range(repeats):
        for i, budget in enumerate((0.0, 0.2)):
            config = replay_config({"estimators": "ekf,smoother", "max_latency": budget})
            started = time.perf_counter()
            replay(events, config)
            best[i] = min(best[i], time.perf_counter() - started)
    return best[0], best[1]


def mount_rows(
    seeds: Sequence[int], duration: float = 60.0, mount: tuple[float, float, float] = MOUNT, align: str = "se2"
) -> list[TimingRow]:
    """Mean figures over the seeds: a sensor at the centre, the same sensor mounted at ``mount`` (its sightings
    taken from there, the stream declaring it), and those sightings read as if from the centre."""
    sums: dict[str, list[tuple[dict[str, float], dict[str, float]]]] = {"centre": [], "mounted": [], "ignored": []}
    for seed in seeds:
        c = TimingConfig(seed=seed, duration=duration, offset=0.0)
        centre = list(timing_world(c))
        mounted = list(timing_world(dataclasses.replace(c, mount=mount)))
        for label, events in (("centre", centre), ("mounted", mounted), ("ignored", without_sensors(mounted))):
            online, nees, _ = _figures(events, align=align)
            sums[label].append((online, nees))
    x, y, theta = mount
    labels = {
        "centre": "sensor at the robot's centre",
        "mounted": f"sensor {x:g} m ahead, {y:g} m left, turned {math.degrees(theta):g} deg (declared)",
        "ignored": "the same sightings read as from the centre",
    }
    return _means(sums, labels)


def without_sensors(events: Iterable[Event]) -> list[Event]:
    """The stream with its sensors undeclared: every sighting read as if taken at the robot's centre."""
    out: list[Event] = []
    for e in events:
        if isinstance(e, Header):
            e = Header(e.name, {k: v for k, v in e.meta.items() if k != "sensors"})
        elif isinstance(e, Observation):
            e = dataclasses.replace(e, sensor=None)
        out.append(e)
    return out
