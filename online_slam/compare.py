"""Filter versus smoother: one library call that runs the EKF, smoother configurations and the batch solver
on the same stream and gathers what the table, the plots and the JSON all read.

Monte Carlo (simulated worlds only) repeats the comparison over noise seeds on all cores and tests the
average NEES across runs against its chi-square bounds. Its figures over steps follow Bar-Shalom, Li &
Kirubarajan (2001, 5.4) and esde (Brossard et al. 2019): per step, the NEES averaged over runs (ANEES) and the
error's root mean square over runs; then both averaged over the world's scored steps (:attr:`World.scored`).
A peer (:data:`PEERS`: GTSAM's iSAM2, the ``peers`` extra; the EKF linearized at the truth) can run beside the
estimators on every run's stream; its figures over steps join theirs.
"""

from __future__ import annotations

import importlib.util
import os
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.compare_config import CompareConfig
from online_slam.errors import InputError, OnlineSlamError
from online_slam.estimators.ideal_ekf import IdealEkf
from online_slam.estimators.protocol import Estimate
from online_slam.evaluation.metrics import apply_transform
from online_slam.evaluation.results import Results, Row, Series
from online_slam.evaluation.scoring import evaluate, nees_bounds, online_figures, share_in_bounds
from online_slam.frontend.steps import FrontEnd, GroundTruth, Step
from online_slam.geometry.angles import wrap
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sinks.protocol import ReplaySink
from online_slam.sources.events import Event
from online_slam.sources.worlds import WORLDS, World

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MonteCarlo:
    """Figures over noise seeds: mean and standard deviation per estimator, and the average-NEES test."""

    runs: int
    """Number of runs."""
    seeds: tuple[int, ...]
    """Seeds used."""
    mean: dict[str, dict[str, float | None]]
    """Per estimator, the mean of each figure over runs."""
    std: dict[str, dict[str, float | None]]
    """Per estimator, the standard deviation of each figure over runs."""
    anees: dict[str, float]
    """Per online estimator (and peer): pose NEES averaged over runs, then over the scored steps (3 =
    consistent). The figures over steps below are also by online estimator and peer."""
    anees_bounds: tuple[float, float]
    """Two-sided 95% bounds for a per-step NEES averaged over ``runs`` runs (3 dof)."""
    anees_in_bounds: dict[str, float]
    """Per online estimator: fraction of scored steps whose run-averaged NEES lies inside those bounds."""
    anees_per_step: dict[str, list[float]]
    """Per online estimator: the run-averaged NEES of every step (NaN where a run has none)."""
    scored_steps: tuple[int, int]
    """First and last step (0-based, inclusive) the figures over steps average (the world's
    :attr:`~online_slam.sources.worlds.World.scored`, else every step with a NEES in every run)."""
    landmark_anees: dict[str, float | None]
    """Per online estimator: 2-dof NEES of each landmark of its final map, averaged over landmarks and runs
    (2 = consistent); None where it gives no landmark covariance."""
    position_rmse_m: dict[str, float]
    """Per online estimator: per step, the root mean square over runs of the newest pose's position error;
    averaged over the scored steps, metres (esde's RMSE)."""
    heading_rmse_rad: dict[str, float]
    """Per online estimator: the same for the heading error, radians."""


@dataclass(frozen=True)
class Comparison:
    """Everything ``compare`` produced; table, plots and JSON read only this."""

    results: Results
    """The replay results of the (first) run, with per-step series and final estimates."""
    rows: dict[str, Row]
    """Table lines by estimator name (``odometry`` first)."""
    monte_carlo: MonteCarlo | None = None
    """Monte Carlo figures when ``runs > 1``."""

    def to_json(self) -> dict[str, Any]:
        """The documented JSON of ``compare --json``."""
        out: dict[str, Any] = {
            "source": self.results.source,
            "robot": self.results.robot,
            "poses": self.results.poses,
            "landmarks": self.results.landmarks,
            "observations": self.results.observations,
            "alignment": self.results.alignment,
            "estimators": {name: _row_json(row) for name, row in self.rows.items()},
            "input": self.results.input.to_json(),
        }
        for name, result in self.results.estimators.items():  # several robots: each robot's figures
            if result.robots and name in self.rows:
                out["estimators"][name]["robots"] = {r: _row_json(f.row()) for r, f in result.robots.items()}
        if self.monte_carlo is not None:
            out["monte_carlo"] = dict(self.monte_carlo.__dict__, seeds=list(self.monte_carlo.seeds))
        return _json_safe(out)


def _row_json(row: Row) -> dict[str, Any]:
    """A row as ``compare --json`` writes it: its step times as one ``step_ms`` object (median, p95, max) or null."""
    figures = dict(row.__dict__)
    figures["nees_band"] = None if row.nees_band is None else row.nees_band.to_json()
    median, p95, longest = (figures.pop(k) for k in ("step_median_ms", "step_p95_ms", "step_max_ms"))
    total_s = figures.pop("total_s")
    step_ms = None if median is None else {"median": median, "p95": p95, "max": longest}
    return {**figures, "step_ms": step_ms, "total_s": total_s}


def _json_safe(value: Any) -> Any:
    """NaN and infinities become null; tuples become lists."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def replay_config(config: CompareConfig) -> ReplayConfig:
    """The one replay a comparison runs: EKF and batch settings as given, one smoother per (W, K)."""
    base = config.replay
    smoothers = tuple(
        replace(base.smoother, window=replace(base.smoother.window, size=w), relinearize_every=k)
        for w in config.windows
        for k in config.relinearize_every
    )
    estimators = tuple(n for n in base.estimators if n != "smoother")
    return replace(base, estimators=estimators, extra_smoothers=smoothers)


def _world(source: str) -> World:
    if source not in WORLDS:
        raise OnlineSlamError(f"Monte Carlo runs need a simulated world ({', '.join(WORLDS)}), not {source!r}")
    return WORLDS[source]


@dataclass(frozen=True)
class RunErrors:
    """One online estimator's errors in one Monte Carlo run (N steps)."""

    nees: Array
    """Pose NEES of each step, shape (N,), NaN where there is none."""
    position_error_m: Array
    """Position error of the newest pose at each step (after the replay's alignment), shape (N,)."""
    heading_error_rad: Array
    """Heading error of the newest pose at each step, wrapped, shape (N,)."""
    landmark_nees: float | None
    """2-dof NEES of the final map's landmarks, averaged over those with truth (None without covariances)."""


Outcome = tuple[dict[str, Row], dict[str, RunErrors]]
"""One run's table rows, and errors per online estimator and peer."""


def _run_seed(args: tuple[str, int, ReplayConfig, tuple[str, ...]]) -> Outcome:
    source, seed, config, peers = args
    results = replay(_world(source).events(seed), config, name=source, validate=False)
    errors = run_errors(results)
    for peer in peers:
        errors[peer] = peer_errors(peer, _world(source).events(seed), config, results)
    return results.rows(), errors


def run_errors(results: Results) -> dict[str, RunErrors]:
    """Per online estimator of a replay with truth: what Monte Carlo averages (see :class:`RunErrors`)."""
    truth = _truth(results)
    return {
        name: _errors(name, series, results.estimates[name], truth, results.alignment)
        for name, series in results.series.items()
    }


def peer_errors(peer: str, events: Iterable[Event], config: ReplayConfig, results: Results) -> RunErrors:
    """A peer (:data:`PEERS`) on the events ``results`` came from, through the same front-end, scored as they
    were (their truth and alignment); iSAM2 has no landmark NEES (None), the ideal EKF has."""
    steps = list(FrontEnd(config.frontend).steps(events))
    if len({s.robot for s in steps}) > 1:
        raise OnlineSlamError(f"peer {peer}: takes one robot, and the stream has several")
    truth = _truth(results)
    if peer == "ideal":
        poses, covariances, seconds, final = _ideal_ekf(steps, truth, config)
    else:
        from online_slam import gtsam_peer

        run = gtsam_peer.isam2_online(steps, covariances=True, qr=True)
        assert run.covariances is not None  # asked for
        poses, covariances, seconds = run.poses, list(run.covariances), run.step_s
        final = Estimate(peer, run.final_poses, (), np.zeros((0, 2)))
    times, nis = np.array([s.t for s in steps]), np.full(len(steps), np.nan)
    figures = online_figures(final, poses, covariances, times, nis, seconds, truth, results.alignment)
    return _errors(peer, figures.series, final, truth, results.alignment)


def _ideal_ekf(
    steps: list[Step], truth: GroundTruth, config: ReplayConfig
) -> tuple[Array, list[Array | None], Array, Estimate]:
    """The truth-linearized EKF (:class:`~online_slam.estimators.ideal_ekf.IdealEkf`, the replay's EKF settings)
    on the steps: (newest pose after each step (N, 3), its covariance, seconds per step (N,), final estimate)."""
    ekf = IdealEkf(truth, config.ekf)
    snapshots = []
    seconds = np.zeros(len(steps))
    for k, step in enumerate(steps):
        began = time.perf_counter()
        snapshots.append(ekf.step(step))
        seconds[k] = time.perf_counter() - began
    poses = np.array([s.pose for s in snapshots])
    last = snapshots[-1]
    final = Estimate("ideal", poses, last.landmark_ids, last.landmarks, landmark_covs=last.landmark_covs)
    return poses, [s.pose_cov for s in snapshots], seconds, final


def _truth(results: Results) -> GroundTruth:
    """The replay's ground truth (poses with a finite truth, landmarks)."""
    poses = {} if results.truth_poses is None else dict(enumerate(results.truth_poses))
    return GroundTruth(
        poses={i: p for i, p in poses.items() if np.isfinite(p).all()},
        landmarks=results.truth_landmarks,
        starts=results.truth_starts,
    )


def _errors(name: str, series: Series, final: Estimate, truth: GroundTruth, alignment: str) -> RunErrors:
    """One online estimator's errors in one run, from its per-step series and its final estimate."""
    online = evaluate(Estimate(name, series.poses, (), np.zeros((0, 2))), truth, alignment)
    heading = np.full(len(series.poses), np.nan)
    if online.indices is not None and online.transform is not None:
        moved = apply_transform(online.transform, series.poses[online.indices])
        true_poses = np.array([truth.poses[i] for i in online.indices])
        heading[online.indices] = np.abs(wrap(moved[:, 2] - true_poses[:, 2]))
    landmark_nees = _landmark_nees(final, evaluate(final, truth, alignment).transform, truth)
    return RunErrors(series.nees, series.position_error_m, heading, landmark_nees)


def _landmark_nees(estimate: Estimate, transform: Array | None, truth: GroundTruth) -> float | None:
    """Mean 2-dof NEES of the estimate's landmarks that have truth, moved into the truth's frame."""
    if estimate.landmark_covs is None or transform is None:
        return None
    known = [k for k, lid in enumerate(estimate.landmark_ids) if lid in truth.landmarks]
    if not known:
        return None
    c, s = np.cos(transform[2]), np.sin(transform[2])
    R = np.array([[c, -s], [s, c]])
    e = apply_transform(transform, estimate.landmarks[known])
    e = e - np.array([truth.landmarks[estimate.landmark_ids[k]] for k in known])
    covs = R @ estimate.landmark_covs[known] @ R.T
    return float(np.mean(np.einsum("ki,ki->k", e, np.linalg.solve(covs, e[..., None])[..., 0])))


def compare(
    source: str | Path,
    config: CompareConfig | None = None,
    on_skip: Callable[[InputError], None] | None = None,
    sinks: Sequence[ReplaySink] = (),
) -> Comparison:
    """Run EKF, smoother configurations and batch on the same stream; optionally Monte Carlo over seeds.

    Args:
        source: A stream path, ``-``, or a built-in world (see :data:`~online_slam.sources.worlds.WORLDS`).
        config: Smoother grid, replay settings, Monte Carlo runs.
        on_skip: Told of each bad line skipped (``config.replay.on_error == "skip"``).
        sinks: Given every step of the (first) run with all configurations' snapshots, then its results (e.g.
            one Rerun recording of every configuration).

    Returns:
        The comparison (table rows, per-step series through ``results``, Monte Carlo figures).
    """
    cfg = config or CompareConfig()  # validated when made (windows, periods, runs, workers >= 1, peers)
    if "isam2" in cfg.peers and importlib.util.find_spec("gtsam") is None:
        raise OnlineSlamError("peer isam2: GTSAM is not installed (pip install 'online-slam[peers]')")
    one_replay = replay_config(cfg)
    results = replay(source, one_replay, on_skip=on_skip, sinks=sinks)
    rows = results.rows()
    monte_carlo = None
    if cfg.runs > 1:
        name = str(source)
        seeds = tuple(_world(name).seed + k for k in range(cfg.runs))
        jobs = [(name, seed, one_replay, cfg.peers) for seed in seeds]
        workers = cfg.workers or os.cpu_count() or 1
        if workers > 1:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                outcomes = list(pool.map(_run_seed, jobs))
        else:
            outcomes = [_run_seed(job) for job in jobs]
        monte_carlo = summarise(outcomes, seeds, _world(name).scored)
    return Comparison(results, rows, monte_carlo)


def summarise(outcomes: list[Outcome], seeds: tuple[int, ...], scored: tuple[int, int] | None = None) -> MonteCarlo:
    """Monte Carlo figures from the runs' outcomes.

    Args:
        outcomes: Per run, its table rows and its online estimators' errors.
        seeds: The runs' seeds.
        scored: Steps (first, last; inclusive) the figures over steps average; None: every step with a NEES in
            every run.
    """
    runs = len(outcomes)
    names = list(outcomes[0][0])
    keys = ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "endpoint_gap_m", "nees_mean", "nis_mean", "total_s")
    mean: dict[str, dict[str, float | None]] = {}
    std: dict[str, dict[str, float | None]] = {}
    for name in names:
        mean[name], std[name] = {}, {}
        for key in keys:
            values = np.array([getattr(o[0][name], key) for o in outcomes], dtype=float)
            ok = np.isfinite(values)
            mean[name][key] = float(values[ok].mean()) if ok.any() else None
            std[name][key] = float(values[ok].std(ddof=1)) if ok.sum() > 1 else None
    over_steps = {name: _over_steps([o[1][name] for o in outcomes], scored) for name in outcomes[0][1]}
    figures = {name: f for name, f in over_steps.items() if f is not None}
    steps = next(iter(figures.values()))["steps"] if figures else (0, -1)
    return MonteCarlo(
        runs,
        seeds,
        mean,
        std,
        anees={name: f["anees"] for name, f in figures.items()},
        anees_bounds=nees_bounds(runs),
        anees_in_bounds={name: f["in_bounds"] for name, f in figures.items()},
        anees_per_step={name: f["per_step"] for name, f in figures.items()},
        scored_steps=steps,
        landmark_anees={name: f["landmark"] for name, f in figures.items()},
        position_rmse_m={name: f["position"] for name, f in figures.items()},
        heading_rmse_rad={name: f["heading"] for name, f in figures.items()},
    )


def _over_steps(errors: list[RunErrors], scored: tuple[int, int] | None) -> dict[str, Any] | None:
    """One online estimator's figures over steps from its runs' errors (None when no step has a NEES)."""
    nees = np.array([e.nees for e in errors])  # (runs, N)
    usable = np.isfinite(nees).all(axis=0)
    steps = np.flatnonzero(usable)
    if scored is not None:
        steps = steps[(steps >= scored[0]) & (steps <= scored[1])]
    if not len(steps):
        return None
    average = nees.mean(axis=0)
    position = np.sqrt(np.mean(np.array([e.position_error_m for e in errors]) ** 2, axis=0))
    heading = np.sqrt(np.mean(np.array([e.heading_error_rad for e in errors]) ** 2, axis=0))
    landmark = [e.landmark_nees for e in errors if e.landmark_nees is not None]
    return {
        "anees": float(average[steps].mean()),
        "in_bounds": share_in_bounds(average[steps], len(errors)),
        "per_step": [float(v) if ok else float("nan") for v, ok in zip(average, usable)],
        "landmark": float(np.mean(landmark)) if landmark else None,
        "position": float(position[steps].mean()),
        "heading": float(heading[steps].mean()),
        "steps": (int(steps[0]), int(steps[-1])),
    }
