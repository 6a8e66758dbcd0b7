"""Live-run reliability benchmarks: checkpoint overhead, fuzzing at volume, and a long soak run.

The soak replays a 100,000-pose grid stream (bounded map) through the EKF and the smoother with a Rerun
recording, and samples the process's resident memory and the per-step times along the way.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from online_slam.estimators.protocol import Snapshot
from online_slam.frontend.steps import GroundTruth, Step
from online_slam.pipeline import Checkpointing, ReplayConfig, replay
from online_slam.sources.worlds import GridConfig, grid_world


def resident_mib() -> float:
    """Resident memory of this process, MiB (Linux ``/proc``; NaN elsewhere)."""
    try:
        with open("/proc/self/statm") as handle:
            pages = int(handle.read().split()[1])
    except (OSError, ValueError, IndexError):
        return float("nan")
    import resource

    return pages * resource.getpagesize() / 2**20


@dataclass(frozen=True)
class CheckpointOverhead:
    """Best-of-N replay times with and without checkpoints."""

    poses: int
    """Poses replayed."""
    every: int
    """Steps between checkpoints."""
    plain_s: float
    """Replay without checkpoints."""
    checkpointed_s: float
    """The same replay writing a checkpoint every ``every`` steps."""
    size_mib: float
    """Size of the last checkpoint."""


def measure_checkpoint_overhead(config: GridConfig, every: int = 100, repeats: int = 3) -> CheckpointOverhead:
    """Replay the grid world (EKF, smoother, batch) with and without checkpoints, interleaved."""
    events = list(grid_world(config))
    folder = Path(tempfile.mkdtemp(prefix="online-slam-ckpt-"))
    plain, checkpointed, size = [], [], 0.0
    try:
        for _ in range(max(1, repeats)):
            started = time.perf_counter()
            replay(iter(events), ReplayConfig(), validate=False)
            plain.append(time.perf_counter() - started)
            started = time.perf_counter()
            replay(iter(events), ReplayConfig(), checkpoint=Checkpointing(folder, every), validate=False)
            checkpointed.append(time.perf_counter() - started)
            size = (folder / "replay.ckpt").stat().st_size / 2**20
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return CheckpointOverhead(config.poses, every, min(plain), min(checkpointed), size)


class _MemoryProbe:
    """A replay sink that samples resident memory at chosen steps."""

    def __init__(self, at: tuple[int, ...]) -> None:
        self.at = set(at)
        self.samples: dict[int, float] = {}

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        if step.index + 1 in self.at:
            self.samples[step.index + 1] = resident_mib()

    def on_finish(self, results: object, truth: GroundTruth) -> None:
        """Nothing to do at the end."""


@dataclass(frozen=True)
class SoakRun:
    """One estimator's long run."""

    estimator: str
    """Estimator name."""
    poses: int
    """Poses replayed."""
    memory_mib: dict[int, float]
    """Resident memory of the process after that many poses, MiB."""
    first_ms: tuple[float, float]
    """Median and p95 step time over the first 10,000 steps, ms."""
    last_ms: tuple[float, float]
    """Median and p95 step time over the last 10,000 steps, ms."""
    online_rmse_m: float | None
    """Online position RMSE over the whole run."""
    rrd_mib: float
    """Size of the Rerun recording, MiB."""
    total_s: float
    """Wall time of the run."""


def soak(poses: int = 100_000, estimators: tuple[str, ...] = ("ekf", "smoother"), seed: int = 7) -> list[SoakRun]:
    """Replay a long grid stream (bounded map: the grid's landmarks) per estimator, with a Rerun recording."""
    from online_slam.sinks.recording import Layout, RerunConfig, RerunSink

    world = GridConfig(poses=poses, seed=seed)
    checkpoints = tuple(sorted({min(poses, p) for p in (10_000, 50_000, poses)}))
    folder = Path(tempfile.mkdtemp(prefix="online-slam-soak-"))
    runs = []
    try:
        for name in estimators:
            probe = _MemoryProbe(checkpoints)
            rrd = folder / f"{name}.rrd"
            sink = RerunSink(RerunConfig(path=rrd), f"soak {poses}", Layout(("odometry", name)))
            started = time.perf_counter()
            results = replay(
                grid_world(world), replace(ReplayConfig(), estimators=(name,)), sinks=[probe, sink], validate=False
            )
            total = time.perf_counter() - started
            ms = results.series[name].step_ms
            window = min(10_000, len(ms))
            runs.append(
                SoakRun(
                    estimator=name,
                    poses=results.poses,
                    memory_mib=dict(probe.samples),
                    first_ms=(float(np.median(ms[:window])), float(np.percentile(ms[:window], 95))),
                    last_ms=(float(np.median(ms[-window:])), float(np.percentile(ms[-window:], 95))),
                    online_rmse_m=results.estimators[name].online_rmse_m,
                    rrd_mib=rrd.stat().st_size / 2**20,
                    total_s=total,
                )
            )
            rrd.unlink()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return runs
