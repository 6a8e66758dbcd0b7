"""Held-out figures for MRCLAM's model: fitted on one part of Dataset 6, scored on another.

The conversion's model (:mod:`online_slam.importers.mrclam.noise`) is fitted against Vicon. Scored on the data it
was fitted on, its figures flatter it; here every fit is scored on data it did not see:

- **halves**: the recording cut at its middle (one cut for all robots,
  :func:`~online_slam.importers.mrclam.reader.half_span`); the model fitted on one half over the five robots,
  each robot (and all five in one stream) replayed on the other half. Beside it, the same fit scored on its own
  half (in-sample), and the built-in model (fitted on the whole recording) on each half;
- **leave one robot out**: the commands' calibration, the increments' noise, the sightings' correlation and the
  robot barcode fitted on the other four robots (the whole recording); the robot's own camera (where it places a
  sighting, its sigmas) on its own first half; scored on its second half;
- **whole run**: a half replayed from an empty map is a harder stream than the same half in a robot's run (it maps
  from nothing what the robot had mapped by then), whatever the model. So each robot's second half is also scored
  inside a replay of its whole run, under the model fitted on the first half and under the one fitted on the other
  robots: the figures over the second half's steps only (its online estimates, and the final estimates of its
  poses). The model still never saw the scored half's data; the estimators did see the first half's, as on a robot
  that kept running.

Every replay runs the default estimators but dead reckoning (EKF, smoother, batch) and reports the online and final
position RMSE against Vicon and the mean NEES. A held-out cell that misses the online target (0.25 m) or the NEES
target (6) is replayed once more with the smoother keeping every pose (:data:`SO_FAR_WINDOW`): at each step every pose
re-solved, approximately the maximum a posteriori estimate of the data so far under the same model (the smoother's
iteration limits and robust loss stay). If it misses as the default estimators do, the miss is not the window's or
the filter's. Only a one-robot replay of a part: every step solves every pose, so the replay's time grows with the
square of its poses (a robot's half, 1,100 poses: about two minutes; all five robots' or a whole run, several times
that).
``python -m benchmarks --only heldout --mrclam FOLDER``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from online_slam.estimators.smoother.config import SmootherConfig, WindowConfig
from online_slam.evaluation.results import Results
from online_slam.evaluation.scoring import position_errors
from online_slam.importers.mrclam.noise import fit_camera_on, fit_mrclam_noise, with_camera
from online_slam.importers.mrclam.reader import MrclamNoise, half_of, read_mrclam, recording_span
from online_slam.importers.mrclam.robots import ROBOTS, read_mrclam_robots
from online_slam.pipeline import replay
from online_slam.pipeline.config import ReplayConfig
from online_slam.sources.events import Event

ESTIMATORS = ("ekf", "smoother", "batch")
"""The estimators every replay runs (the defaults but dead reckoning)."""
STREAMS: tuple[int | str, ...] = (*ROBOTS, "all")
"""Each robot alone, then all five in one stream."""
TARGETS = {"online_m": 0.25, "nees": 6.0}
"""The issue's targets for every held-out cell: online RMSE (m) and mean NEES, EKF and smoother."""
SO_FAR_WINDOW = 1_000_000
"""A window no stream fills: the smoother marginalizes nothing and solves every pose at every step."""


@dataclass(frozen=True)
class Cell:
    """One replay: a model scored on a part of the recording."""

    scheme: str
    """What was fitted on what, e.g. ``fit first, score second``."""
    held_out: bool
    """Whether the scored data was left out of the fit."""
    stream: int | str
    """The robot (1-5), or ``all``."""
    online: dict[str, float]
    """Online position RMSE by estimator (m; the batch has none)."""
    final: dict[str, float]
    """Final position RMSE by estimator, m."""
    nees: dict[str, float]
    """Mean NEES by estimator (the batch has none)."""
    whole_run: bool = False
    """Scored on part of a replay of the whole recording (the ``whole run`` cells), not on a replay of the part."""
    so_far: tuple[float, float] | None = None
    """Online RMSE (m) and mean NEES of the smoother keeping every pose (approximately the MAP of the data so far at
    each step), for a one-robot held-out cell that misses a target; None otherwise."""

    def misses(self) -> bool:
        """Whether this held-out cell misses the online or the NEES target."""
        return self.held_out and (
            max(self.online.values()) > TARGETS["online_m"] or max(self.nees.values()) > TARGETS["nees"]
        )


@dataclass(frozen=True)
class Job:
    """A replay to run: the model, the part scored, the stream."""

    scheme: str
    held_out: bool
    stream: int | str
    noise: MrclamNoise
    span: tuple[float, float]
    scored: tuple[float, float] | None = None
    """The part of ``span`` scored (start, end excluded); None: all of it."""


def fits(folder: str | Path, spans: dict[str, tuple[float, float]]) -> dict[str, MrclamNoise]:
    """The fitted models: ``builtin``, ``first``, ``second`` (a half's fit, ``spans`` by half) and ``without N``
    (robot N left out, its camera from its first half)."""
    models = {"builtin": MrclamNoise()}
    for half in ("first", "second"):
        models[half] = fit_mrclam_noise(folder, span=spans[half]).noise
    for robot in ROBOTS:
        others = tuple(r for r in ROBOTS if r != robot)
        fitted = fit_mrclam_noise(folder, robots=others).noise
        models[f"without {robot}"] = with_camera(fitted, robot, fit_camera_on(folder, robot, spans["first"]))
    return models


def jobs(models: dict[str, MrclamNoise], spans: dict[str, tuple[float, float]]) -> list[Job]:
    """Every replay of the benchmark, in the order of its table (``spans``: ``first``, ``second`` and ``whole``)."""
    other = {"first": "second", "second": "first"}
    out = []
    for half in ("first", "second"):
        for stream in STREAMS:
            out.append(Job(f"built-in, score {half}", False, stream, models["builtin"], spans[half]))
            out.append(Job(f"fit {half}, score {half}", False, stream, models[half], spans[half]))
            out.append(Job(f"fit {other[half]}, score {half}", True, stream, models[other[half]], spans[half]))
    for robot in ROBOTS:
        out.append(Job("fit other robots, score second", True, robot, models[f"without {robot}"], spans["second"]))
    for robot in ROBOTS:
        for scheme, model in (("fit first", models["first"]), ("fit other robots", models[f"without {robot}"])):
            out.append(Job(f"{scheme}, score second, whole run", True, robot, model, spans["whole"], spans["second"]))
    return out


def _events(folder: str, job: Job) -> Iterable[Event]:
    """The events of a job's stream: one robot, or all five in one stream."""
    if job.stream == "all":
        return read_mrclam_robots(folder, job.noise, job.span)
    return read_mrclam(folder, int(job.stream), job.noise, job.span)


def run_job(folder: str, job: Job) -> Cell:
    """Replay one job's stream and take its figures (over its scored part)."""
    results = replay(_events(folder, job), ReplayConfig(estimators=ESTIMATORS), name=f"{job.scheme} {job.stream}")
    if job.scored is not None:
        online, final, nees = scored_figures(results, job.scored)
        return Cell(job.scheme, job.held_out, job.stream, online, final, nees, whole_run=True)
    e = results.estimators
    return Cell(
        job.scheme,
        job.held_out,
        job.stream,
        {k: e[k].online_rmse_m for k in ("ekf", "smoother")},
        {k: e[k].final_rmse_m for k in ESTIMATORS},
        {k: e[k].nees_mean for k in ("ekf", "smoother")},
    )


def scored_figures(
    results: Results, span: tuple[float, float]
) -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
    """Online RMSE, final RMSE (m) and mean NEES by estimator over the steps of a replay within ``span`` (start, end
    excluded): its online and final errors as the replay's table computes them, averaged over those steps only."""
    t = results.series["ekf"].t
    inside = (t >= span[0]) & (t < span[1])
    online = {k: _rms(results.series[k].position_error_m[inside]) for k in ("ekf", "smoother")}
    nees = {k: float(np.nanmean(results.series[k].nees[inside])) for k in ("ekf", "smoother")}
    final = {}
    for k in ESTIMATORS:
        errors = position_errors(
            results.estimates[k].poses,
            results.truth_poses,
            results.alignment,
            results.truth_offsets,
            results.truth_starts,
        )
        final[k] = _rms(errors[inside])
    return online, final, nees


def _rms(errors: np.ndarray) -> float:
    """Root mean square of the finite errors."""
    return float(np.sqrt(np.nanmean(np.square(errors))))


def so_far(folder: str, job: Job) -> tuple[float, float]:
    """Online RMSE (m) and mean NEES of the smoother keeping every pose (:data:`SO_FAR_WINDOW`) on a job's stream."""
    smoother = SmootherConfig(window=WindowConfig(size=SO_FAR_WINDOW))
    config = ReplayConfig(estimators=("smoother",), smoother=smoother)
    row = replay(_events(folder, job), config, name=f"{job.scheme} {job.stream}, every pose kept").estimators
    online, nees = row["smoother"].online_rmse_m, row["smoother"].nees_mean
    return float("nan") if online is None else online, float("nan") if nees is None else nees


def run_heldout(folder: str | Path, workers: int | None = None) -> list[Cell]:
    """Fit every model, run every replay, then :func:`so_far` on the one-robot held-out cells that miss a target
    (``workers`` processes; None: every core)."""
    recording = recording_span(Path(folder))
    spans = {half: half_of(recording, half) for half in ("first", "second")}
    spans["whole"] = (recording[0], float(np.nextafter(recording[1], np.inf)))
    todo = jobs(fits(folder, spans), spans)
    with ProcessPoolExecutor(max_workers=workers or os.cpu_count()) as pool:
        cells = list(pool.map(run_job, [str(folder)] * len(todo), todo))
        again = [k for k, c in enumerate(cells) if c.misses() and c.stream != "all" and not c.whole_run]
        figures = pool.map(so_far, [str(folder)] * len(again), [todo[k] for k in again])
        for k, figure in zip(again, figures):
            cells[k] = replace(cells[k], so_far=figure)
    return cells


def worst(cells: Sequence[Cell], whole_run: bool = False) -> dict[str, float]:
    """The held-out cells' worst figures against the targets: online RMSE and mean NEES (EKF and smoother), and the
    smoother's and batch's final over the EKF's final; over the replays of a part, or over the ``whole_run`` cells."""
    held = [c for c in cells if c.held_out and c.whole_run == whole_run]
    return {
        "online_m": max(max(c.online.values()) for c in held),
        "nees": max(max(c.nees.values()) for c in held),
        "final_over_ekf": max(max(c.final["smoother"], c.final["batch"]) / c.final["ekf"] for c in held),
    }
