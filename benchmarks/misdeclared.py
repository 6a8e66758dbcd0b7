"""Declared noise that is wrong: the same data, its declared covariances scaled, every estimator with its defaults.

A robot never comes with a correct noise model. Each stream is replayed as declared and with its odometry or its
sightings' covariances declared 0.09x or 9x (sigmas 0.3x or 3x; the data unchanged, through the front-end's
``odometry_noise_scale`` / ``sensor_noise_scale``), on 2000-pose simulated worlds (the grid at two seeds, the
random-waypoint world, the circle with range-bearing sightings, three robots meeting) and on MRCLAM Dataset 6's
robots when the folder is there. The figures against the target "nothing diverges": every estimator's online error
within 3x of the correctly declared stream's, the smoother's final within 1.5x of the batch's on the same stream.
Each case runs with ``--adapt-noise`` off and ``on`` (the default: the EKF and the smoother adapt the declared noise
to their innovations).
``python -m benchmarks --only misdeclared``.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from online_slam.frontend.steps import FrontEndConfig
from online_slam.options import replay_config
from online_slam.pipeline import replay
from online_slam.sources.events import Event
from online_slam.sources.meet import MeetConfig, meet_world
from online_slam.sources.worlds import (
    CircleConfig,
    GridConfig,
    WaypointConfig,
    circle_world,
    grid_world,
    waypoint_world,
)

MODES = ("off", "on")
"""``--no-adapt-noise`` and ``--adapt-noise`` (the default), as the table labels them."""
CASES: tuple[tuple[str, float, float], ...] = (
    ("as declared", 1.0, 1.0),
    ("odometry 0.3x", 0.09, 1.0),
    ("odometry 3x", 9.0, 1.0),
    ("sensor 0.3x", 1.0, 0.09),
    ("sensor 3x", 1.0, 9.0),
)
"""(label, odometry covariance scale, sensor covariance scale): the sigmas declared 0.3x or 3x."""
WORLDS: dict[str, Callable[[], Iterable[Event]]] = {
    "grid seed 7": lambda: grid_world(GridConfig(seed=7)),
    "grid seed 11": lambda: grid_world(GridConfig(seed=11)),
    "waypoint 2000": lambda: waypoint_world(WaypointConfig(poses=2000)),
    "circle 2000": lambda: circle_world(CircleConfig(poses=2000, model="range-bearing")),
    "meet 3 x 667": lambda: meet_world(MeetConfig(poses=667)),
}
"""The simulated worlds, 2000 poses each (the meet world: three robots sighting each other, 667 poses each)."""


@dataclass(frozen=True)
class Row:
    """One stream under one declaration."""

    stream: str
    """The world or MRCLAM robot."""
    case: str
    """Which covariances are misdeclared, and how (a label of :data:`CASES`)."""
    adapt: str
    """``--adapt-noise``: off or on."""
    online: dict[str, float]
    """Online position RMSE of the EKF and the smoother, m."""
    final: dict[str, float]
    """Final position RMSE of the smoother and the batch, m."""
    nees: dict[str, float]
    """Mean NEES of the EKF and the smoother."""


def _events(stream: str, folder: str | None) -> list[Event]:
    if stream.startswith("MRCLAM robot "):
        from online_slam.importers.mrclam.reader import read_mrclam

        return list(read_mrclam(str(folder), int(stream.rsplit(" ", 1)[1])))
    return list(WORLDS[stream]())


def run_stream(stream: str, folder: str | None = None) -> list[Row]:
    """Every case of one stream."""
    events = _events(stream, folder)
    rows = []
    for (case, odometry, sensor), adapt in itertools.product(CASES, MODES):
        frontend = FrontEndConfig(odometry_noise_scale=odometry, sensor_noise_scale=sensor)
        config = replay_config({"estimators": "ekf,smoother,batch", "adapt_noise": adapt == "on"})
        config = dataclasses.replace(config, frontend=frontend)
        e = replay(events, config, name=stream, validate=stream.startswith("MRCLAM")).estimators
        rows.append(
            Row(
                stream,
                case,
                adapt,
                {k: e[k].online_rmse_m for k in ("ekf", "smoother")},
                {k: e[k].final_rmse_m for k in ("smoother", "batch")},
                {k: e[k].nees_mean for k in ("ekf", "smoother")},
            )
        )
    return rows


def run_misdeclared(folder: str | Path | None, workers: int | None = None) -> list[Row]:
    """Every stream (the worlds; MRCLAM's five robots when ``folder`` is given) under every case."""
    streams = list(WORLDS) + ([f"MRCLAM robot {r}" for r in range(1, 6)] if folder else [])
    with ProcessPoolExecutor(max_workers=workers or os.cpu_count()) as pool:
        done = pool.map(run_stream, streams, [None if folder is None else str(folder)] * len(streams))
        return [row for rows in done for row in rows]


def verdicts(rows: list[Row], adapt: str) -> dict[str, float]:
    """Over the runs with one ``--adapt-noise`` mode: worst online ratio to the stream's correctly declared run in
    the same mode (EKF, smoother), worst smoother final over the batch final, worst mean NEES."""
    base = {r.stream: r for r in rows if r.case == CASES[0][0] and r.adapt == adapt}
    mine = [r for r in rows if r.adapt == adapt]
    return {
        "online_ratio": max(r.online[k] / base[r.stream].online[k] for r in mine for k in r.online),
        "smoother_over_batch": max(r.final["smoother"] / r.final["batch"] for r in mine),
        "nees": max(max(r.nees.values()) for r in mine),
    }
