"""Filter versus smoother: one library call that runs the EKF, smoother configurations and the batch solver
on the same stream and gathers what the table, the plots and the JSON all read.

Monte Carlo (simulated worlds only) repeats the comparison over noise seeds on all cores and tests the
average NEES across runs against its chi-square bounds.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import InputError, OnlineSlamError
from online_slam.estimators.smoother import SmootherConfig, WindowConfig
from online_slam.evaluation.results import Results, Row
from online_slam.evaluation.scoring import nees_bounds, share_in_bounds
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sinks.protocol import ReplaySink
from online_slam.sources.worlds import WORLDS, World

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CompareConfig:
    """What ``online-slam compare`` runs."""

    windows: tuple[int, ...] = (WindowConfig.size,)
    """Smoother window sizes W; every (W, K) pair is run."""
    relinearize_every: tuple[int, ...] = (SmootherConfig.relinearize_every,)
    """Smoother relinearization periods K."""
    replay: ReplayConfig = field(default_factory=lambda: ReplayConfig(estimators=("ekf", "batch")))
    """Everything else (EKF and batch settings, front-end, alignment); its smoother settings seed each (W, K)."""
    runs: int = 1
    """Monte Carlo runs over noise seeds (simulated worlds only); 1 = just the given stream."""
    workers: int | None = None
    """Processes for Monte Carlo runs (default: all cores)."""

    def __post_init__(self) -> None:
        if any(w < 1 for w in self.windows) or any(k < 1 for k in self.relinearize_every):
            raise ValueError("windows and relinearize_every must be >= 1")
        if self.runs < 1 or (self.workers is not None and self.workers < 1):
            raise ValueError("runs and workers must be >= 1")


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
    """Per online estimator: NEES averaged over runs and steps."""
    anees_bounds: tuple[float, float]
    """Two-sided 95% bounds for a per-step NEES averaged over ``runs`` runs (3 dof)."""
    anees_in_bounds: dict[str, float]
    """Per online estimator: fraction of steps whose run-averaged NEES lies inside those bounds."""
    anees_per_step: dict[str, list[float]]
    """Per online estimator: the run-averaged NEES of every step."""


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
        if self.monte_carlo is not None:
            out["monte_carlo"] = dict(self.monte_carlo.__dict__, seeds=list(self.monte_carlo.seeds))
        return _json_safe(out)


def _row_json(row: Row) -> dict[str, Any]:
    """A row as ``compare --json`` writes it: its step times as one ``step_ms`` object (median, p95, max) or null."""
    figures = dict(row.__dict__)
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


def _run_seed(args: tuple[str, int, ReplayConfig]) -> tuple[dict[str, Row], dict[str, Array]]:
    source, seed, config = args
    results = replay(_world(source).events(seed), config, name=source, validate=False)
    return results.rows(), {name: s.nees for name, s in results.series.items()}


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
    cfg = config or CompareConfig()  # validated when made (windows, periods, runs, workers >= 1)
    one_replay = replay_config(cfg)
    results = replay(source, one_replay, on_skip=on_skip, sinks=sinks)
    rows = results.rows()
    monte_carlo = None
    if cfg.runs > 1:
        name = str(source)
        seeds = tuple(_world(name).seed + k for k in range(cfg.runs))
        jobs = [(name, seed, one_replay) for seed in seeds]
        workers = cfg.workers or os.cpu_count() or 1
        if workers > 1:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                outcomes = list(pool.map(_run_seed, jobs))
        else:
            outcomes = [_run_seed(job) for job in jobs]
        monte_carlo = _summarise(outcomes, seeds)
    return Comparison(results, rows, monte_carlo)


def _summarise(outcomes: list[tuple[dict[str, Row], dict[str, Array]]], seeds: tuple[int, ...]) -> MonteCarlo:
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
    low, high = nees_bounds(runs)
    anees, in_bounds, per_step = {}, {}, {}
    for name in outcomes[0][1]:
        stack = np.array([o[1][name] for o in outcomes])  # (runs, N)
        usable = np.isfinite(stack).all(axis=0)
        if not usable.any():
            continue
        average = stack[:, usable].mean(axis=0)
        anees[name] = float(average.mean())
        in_bounds[name] = share_in_bounds(average, runs)
        per_step[name] = [
            float(v) if ok else float("nan") for v, ok in zip(np.where(usable, stack.mean(axis=0), np.nan), usable)
        ]
    return MonteCarlo(runs, seeds, mean, std, anees, (low, high), in_bounds, per_step)
