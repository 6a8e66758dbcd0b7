"""Overhead of the library API (``online_slam.Slam``) over driving an estimator directly, on the grid world.

Direct: the front-end turns the (already validated) events into steps and ``estimator.step`` consumes them,
as a hand-written loop would. API: a robot's loop — ``add_odometry``, the step's sightings (one
``add_observations`` call per scan, or one ``add_observation`` call per sighting), ``estimate()`` once per
pose — with every call validated; the calls' arguments are prepared before timing, as the events of the direct
path are. The difference is validation, dispatch and the queries.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from online_slam.estimators.ekf import EkfSlam
from online_slam.estimators.smoother import SlidingWindowSmoother
from online_slam.frontend.steps import FrontEnd
from online_slam.slam import Slam
from online_slam.sources.events import Event, Observation, Odometry, Start
from online_slam.sources.worlds import GridConfig, grid_world


@dataclass(frozen=True)
class ApiOverhead:
    """Best-of-N wall times of one estimator driven three ways."""

    estimator: str
    """``ekf`` or ``smoother``."""
    direct_s: float
    """Front-end steps into ``estimator.step``."""
    scans_s: float
    """``Slam`` with one ``add_observations`` per scan and ``estimate()`` per pose."""
    sightings_s: float
    """``Slam`` with one ``add_observation`` per sighting and ``estimate()`` per pose."""


def _direct(name: str, events: list[Event]) -> float:
    estimator = EkfSlam() if name == "ekf" else SlidingWindowSmoother()
    started = time.perf_counter()
    for step in FrontEnd().steps(events):
        estimator.step(step)
    return time.perf_counter() - started


def _calls(events: list[Event], scans: bool) -> list[tuple]:
    """The robot loop's calls, prepared before timing (a sensor hands over its scan as lists)."""
    calls: list[tuple] = []
    batch: list[Observation] = []

    def flush() -> None:
        if batch:
            first = batch[0]
            calls.append(("scan", first.t, [o.landmark for o in batch], [o.range for o in batch],
                          [o.bearing for o in batch], first.sigma))  # fmt: skip
            batch.clear()

    started = False
    for event in events:
        if type(event) is Observation:
            if not scans:
                calls.append(("one", event.t, event.landmark, event.range, event.bearing, event.sigma, event.cov))
            elif batch and (event.t != batch[0].t or event.sigma != batch[0].sigma or event.cov is not None):
                flush()
                batch.append(event)
            else:
                batch.append(event)
            started = True
        elif type(event) is Odometry:
            flush()
            if started:
                calls.append(("estimate",))
            calls.append(("odometry", event.t, event.delta, event.sigma, event.cov))
            started = True
        elif type(event) is Start:
            calls.append(("start", event.t, event.pose, event.sigma, event.cov))
            started = True
    flush()
    calls.append(("estimate",))
    return calls


def _api(name: str, events: list[Event], scans: bool) -> float:
    calls = _calls(events, scans)
    slam = Slam(name)
    started = time.perf_counter()
    for call in calls:
        kind = call[0]
        if kind == "scan":
            slam.add_observations(call[1], call[2], call[3], call[4], sigma=call[5])
        elif kind == "one":
            slam.add_observation(*call[1:])
        elif kind == "odometry":
            slam.add_odometry(*call[1:])
        elif kind == "estimate":
            slam.estimate(landmark_covs=False)
        else:
            slam.start(*call[1:])
    return time.perf_counter() - started


def measure_api_overhead(config: GridConfig, repeats: int = 3) -> list[ApiOverhead]:
    """Time both estimators direct and through the API, interleaved, best of ``repeats`` each."""
    events = [e for e in grid_world(config) if isinstance(e, (Start, Odometry, Observation))]
    rows = []
    for name in ("smoother", "ekf"):
        direct, scans, sightings = [], [], []
        for _ in range(max(1, repeats)):
            direct.append(_direct(name, events))
            scans.append(_api(name, events, scans=True))
            sightings.append(_api(name, events, scans=False))
        rows.append(ApiOverhead(name, min(direct), min(scans), min(sightings)))
    return rows
