"""The EKF's odometry bias state (``--odometry-bias-scale``, ``--odometry-bias-rate``) on streams as logged and
with their odometry biased.

Each stream is replayed by the EKF (its defaults) without the bias state and with it, at each prior given, both as
logged and with every increment's distance overstated by ``s`` and ``w`` rad/s added to its turn
(:func:`~online_slam.sources.odometry_bias.biased_odometry`; the declared noise unchanged). Streams: MRCLAM
Dataset 6's five robots (with the folder) and simulated worlds where sightings are sparse enough for drift to
matter: the grid seeing 6 m, the random-waypoint world (2000 poses), three robots meeting.
``python -m benchmarks --only odometry-bias``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from online_slam.options import replay_config
from online_slam.pipeline import replay
from online_slam.sources.events import Event
from online_slam.sources.meet import MeetConfig, meet_world
from online_slam.sources.odometry_bias import biased_odometry
from online_slam.sources.worlds import GridConfig, WaypointConfig, grid_world, waypoint_world

BIAS = (1.0 - 1.0 / 1.06, 0.008)
"""The stress: distances 6% long, 8 mrad/s added to the turn (about two and a half times MRCLAM robot 4's own)."""
PRIORS = ((0.02, 0.003), (0.05, 0.01))
"""The bias priors (scale, rate rad/s) compared with none."""
WORLDS = ("grid 6 m", "waypoint", "meet")


@dataclass(frozen=True)
class Row:
    """One stream, biased or not, under one prior."""

    stream: str
    biased: bool
    prior: tuple[float, float]
    """The prior sigmas (scale, rate rad/s); (0, 0): none."""
    online_m: float
    nees: float
    found: str
    """The biases found, ``s/w`` per robot (empty without the state)."""


def _events(stream: str, folder: str | None) -> list[Event]:
    if stream.startswith("MRCLAM robot "):
        from online_slam.importers.mrclam.reader import read_mrclam

        return list(read_mrclam(str(folder), int(stream.rsplit(" ", 1)[1])))
    if stream == "grid 6 m":
        return list(grid_world(GridConfig(poses=2000, sensor_range=6.0)))
    if stream == "waypoint":
        return list(waypoint_world(WaypointConfig(poses=2000)))
    return list(meet_world(MeetConfig(poses=667)))


def run_stream(stream: str, folder: str | None = None) -> list[Row]:
    """The stream as logged and biased, without the bias state and with each of :data:`PRIORS`."""
    logged = _events(stream, folder)
    rows = []
    for biased in (False, True):
        events: Iterable[Event] = list(biased_odometry(logged, BIAS)) if biased else logged
        for prior in ((0.0, 0.0), *PRIORS):
            options = {"estimators": "ekf", "odometry_bias_scale": prior[0], "odometry_bias_rate": prior[1]}
            r = replay(events, replay_config(options), name=stream)
            e, found = r.estimators["ekf"], r.estimates["ekf"].info.get("odometry_bias", {})
            text = " ".join(f"{v[0]:+.3f}/{1e3 * v[1]:+.1f}" for v in found.values())
            rows.append(Row(stream, biased, prior, float(e.online_rmse_m or 0.0), float(e.nees_mean or 0.0), text))
    return rows


def run_odometry_bias(folder: str | Path | None, workers: int | None = None) -> list[Row]:
    """Every stream (the worlds; MRCLAM's five robots when ``folder`` is given)."""
    streams = list(WORLDS) + ([f"MRCLAM robot {r}" for r in range(1, 6)] if folder else [])
    with ProcessPoolExecutor(max_workers=workers or os.cpu_count()) as pool:
        done = pool.map(run_stream, streams, [None if folder is None else str(folder)] * len(streams))
        return [row for rows in done for row in rows]


def table(rows: list[Row]) -> str:
    """The rows as a markdown table: per stream and bias, online m / mean NEES for each prior."""
    priors = ((0.0, 0.0), *PRIORS)
    heads = " | ".join(f"EKF {p[0]:g}, {p[1]:g}" if any(p) else "EKF" for p in priors)
    lines = [f"| stream | odometry | {heads} | found (s / w mrad/s) |",
             "|---|---|" + "---:|" * len(priors) + "---|"]  # fmt: skip
    keys = dict.fromkeys((r.stream, r.biased) for r in rows)
    for stream, biased in keys:
        cells = {r.prior: r for r in rows if (r.stream, r.biased) == (stream, biased)}
        figures = " | ".join(f"{cells[p].online_m:.3f} / {cells[p].nees:.2f}" for p in priors)
        label = f"biased {BIAS[0]:.3f} / {1e3 * BIAS[1]:.0f} mrad/s" if biased else "as logged"
        lines.append(f"| {stream} | {label} | {figures} | {cells[PRIORS[0]].found} |")
    return "\n".join(lines)


def heldout_cell(folder: str, job: Any, prior: tuple[float, float]) -> tuple[float, float]:
    """The EKF's online RMSE (m) and mean NEES on one of ``benchmarks.heldout``'s jobs under a bias prior (its
    scored part: a whole run's second half)."""
    import numpy as np

    from benchmarks.heldout import _events, _rms
    from online_slam.frontend.steps import FrontEndConfig
    from online_slam.pipeline import ReplayConfig

    frontend = FrontEndConfig(odometry_bias_scale=prior[0], odometry_bias_rate=prior[1])
    r = replay(_events(folder, job), ReplayConfig(estimators=("ekf",), frontend=frontend))
    if job.scored is None:
        return float(r.estimators["ekf"].online_rmse_m or 0.0), float(r.estimators["ekf"].nees_mean or 0.0)
    series = r.series["ekf"]
    inside = (series.t >= job.scored[0]) & (series.t < job.scored[1])
    return _rms(series.position_error_m[inside]), float(np.nanmean(series.nees[inside]))


def run_heldout(folder: str | Path, workers: int | None = None) -> list[tuple[str, str, list[tuple[float, float]]]]:
    """``benchmarks.heldout``'s held-out cells (27 on Dataset 6) by the EKF without the bias state and with each of
    :data:`PRIORS`: (scheme, stream, [(online m, mean NEES) per prior])."""
    import numpy as np

    from benchmarks.heldout import fits, jobs
    from online_slam.importers.mrclam.reader import half_of, recording_span

    recording = recording_span(Path(folder))
    spans = {half: half_of(recording, half) for half in ("first", "second")}
    spans["whole"] = (recording[0], float(np.nextafter(recording[1], np.inf)))
    todo = [job for job in jobs(fits(folder, spans), spans) if job.held_out]
    priors = ((0.0, 0.0), *PRIORS)
    pairs = [(job, prior) for job in todo for prior in priors]
    with ProcessPoolExecutor(max_workers=workers or os.cpu_count()) as pool:
        figures = list(pool.map(heldout_cell, [str(folder)] * len(pairs), *zip(*pairs)))
    n = len(priors)
    return [(job.scheme, str(job.stream), figures[k * n : (k + 1) * n]) for k, job in enumerate(todo)]
