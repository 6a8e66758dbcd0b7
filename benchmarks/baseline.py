"""The machine-written baseline: every estimator's figures on each source, recorded and gated.

``python -m benchmarks --record`` replays each of :data:`SOURCES` with the defaults and writes
``benchmarks/baseline.json``: one row per source and estimator (online, final and landmark RMSE, mean NEES, median
step time as a ratio to GTSAM's iSAM2 run on the same steps in the same process), with the commit and date.
``--gate`` measures again and fails when an accuracy figure moves by more than :data:`ACCURACY_RTOL` (relative)
or a time ratio grows by more than :data:`TIME_GROWTH`. Accuracy is deterministic on one machine and equal to
about 1e-12 across CPUs; a time ratio cancels most of the machine's speed but not its noise, hence the looser bound.
Both also measure what the socket of a live source costs per step over a file (:mod:`benchmarks.live`), recorded
beside the rows and held to its target. RESULTS.md's table of current figures is generated from the baseline
(:mod:`benchmarks.results_page`).
"""

from __future__ import annotations

import datetime
import json
import math
import subprocess
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / "benchmarks" / "baseline.json"
"""Where ``--record`` writes and ``--gate`` reads."""
SOURCES = (
    "square",
    "grid",
    "meet",
    "replay/mrclam6_robot1.jsonl.gz",
    "replay/citytrees_first1000.jsonl.gz",
    "replay/victoria_park.jsonl.gz",
)
"""Built-in worlds and the streams shipped in replay/: what a fresh clone has."""
ACCURACY = ("online_rmse_m", "final_rmse_m", "landmark_rmse_m", "nees_mean", "chi2")
"""The accuracy figures of a row, gated to :data:`ACCURACY_RTOL`."""
ACCURACY_RTOL = 0.01
"""An accuracy figure that moves by more than 1% (either way) fails the gate: re-record if the change is meant."""
TIME_GROWTH = 1.5
"""A time ratio that grows beyond 1.5x its recorded value fails the gate (one that falls does not)."""


@dataclass(frozen=True)
class BaselineRow:
    """One estimator on one source."""

    source: str
    """The source as given to ``online-slam replay``."""
    estimator: str
    """``ekf``, ``smoother`` or ``batch``."""
    online_rmse_m: float | None
    """RMSE of each pose as estimated when it was the newest, metres (None: batch, or no truth)."""
    final_rmse_m: float | None
    """RMSE of the final trajectory, metres (None without truth)."""
    landmark_rmse_m: float | None
    """RMSE of the final map, metres (None without the landmarks' truth)."""
    nees_mean: float | None
    """Mean pose NEES over the steps (3 if consistent; None: batch, or no truth)."""
    chi2: float | None
    """The batch's chi-square at its solution (twice its final cost): its figure where there is no truth."""
    step_ratio: float | None
    """Median step time over iSAM2's median step time on the same steps (None: batch, or no GTSAM)."""


def _commit() -> str:
    try:
        done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        return done.stdout.strip() + ("+changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _peer_step_ms(source: str) -> float | None:
    """iSAM2's median step time (ms) over the source's steps, one robot; None without GTSAM or with several."""
    from online_slam import gtsam_peer
    from online_slam.frontend.steps import FrontEnd
    from online_slam.pipeline import ReplayConfig
    from online_slam.pipeline.source import open_events

    if not gtsam_peer.available():
        return None
    config = ReplayConfig()
    steps = list(FrontEnd(config.frontend).steps(open_events(_path(source), config).events))
    if len({s.robot for s in steps}) > 1:
        return None
    return 1e3 * float(np.median(gtsam_peer.isam2_online(steps).step_s))


def _path(source: str) -> str:
    return str(ROOT / source) if "/" in source else source


def measure(sources: tuple[str, ...] = SOURCES, tell: Any = print) -> list[BaselineRow]:
    """Replay each source with the defaults (EKF, smoother, batch) and iSAM2 beside it; one row per estimator."""
    import online_slam

    rows = []
    for source in sources:
        results = online_slam.replay(_path(source))
        peer_ms = _peer_step_ms(source)
        for name, result in results.estimators.items():
            median = result.step_ms.median if result.step_ms is not None else None
            ratio = median / peer_ms if median is not None and peer_ms else None
            cost = result.details.get("final_cost") if name == "batch" else None
            rows.append(BaselineRow(source, name, result.online_rmse_m, result.final_rmse_m, result.landmark_rmse_m,
                                    result.nees_mean, None if cost is None else 2.0 * cost, ratio))  # fmt: skip
        tell(f"{source}: {', '.join(results.estimators)} measured")
    return rows


def measure_live(tell: Any = print) -> float:
    """What the socket of a live source costs per step over a file, ms (:mod:`benchmarks.live`, reading alone)."""
    from benchmarks.live import socket_ms_per_step
    from online_slam.sources.worlds import GridConfig

    ms = socket_ms_per_step(GridConfig())
    tell(f"live input: the socket costs {ms:.4f} ms per step over a file")
    return ms


def record(rows: list[BaselineRow], path: Path = BASELINE, live_ms: float | None = None) -> dict[str, Any]:
    """Write the baseline: rows, the live input's cost per step (when measured), commit, date and the tolerances
    and limit the gate applies."""
    from benchmarks.live import TARGET_MS

    document = {
        "commit": _commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "accuracy_rtol": ACCURACY_RTOL,
        "time_growth": TIME_GROWTH,
        "rows": [asdict(r) for r in rows],
    }
    if live_ms is not None:
        document.update(live_ms_per_step=live_ms, live_limit_ms=TARGET_MS)
    path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return document


def read(path: Path = BASELINE) -> dict[str, Any]:
    """The recorded baseline."""
    return json.loads(path.read_text(encoding="utf-8"))


def gate(baseline: dict[str, Any], rows: list[BaselineRow], live_ms: float | None = None) -> list[str]:
    """What moved beyond the baseline's tolerances, or a live input's cost per step (``live_ms``) beyond its limit
    (an absolute one: the figure is a small difference of two times, mostly the machine's noise, so no ratio to
    a recorded value means anything): one line per figure (empty: the gate passes)."""
    from benchmarks.live import TARGET_MS

    rtol, growth = baseline["accuracy_rtol"], baseline["time_growth"]
    now = {(r.source, r.estimator): r for r in rows}
    failures = []
    limit = baseline.get("live_limit_ms", TARGET_MS)
    if live_ms is not None and live_ms > limit:
        failures.append(f"live input: the socket costs {live_ms:.4f} ms per step over a file (at most {limit} ms)")
    for old in baseline["rows"]:
        key = (old["source"], old["estimator"])
        new = now.get(key)
        if new is None:
            failures.append(f"{key[0]} {key[1]}: not measured")
            continue
        for figure in ACCURACY:
            before, after = old[figure], getattr(new, figure)
            if (before is None) != (after is None):
                failures.append(f"{key[0]} {key[1]} {figure}: {before} -> {after}")
            elif before is not None and not math.isclose(after, before, rel_tol=rtol):
                failures.append(f"{key[0]} {key[1]} {figure}: {before:.6g} -> {after:.6g} "
                                f"({after / before - 1:+.1%}, tolerance {rtol:.0%})")  # fmt: skip
        before, after = old["step_ratio"], new.step_ratio
        if before is not None and after is not None and after > growth * before:
            failures.append(f"{key[0]} {key[1]} step_ratio: {before:.3g} -> {after:.3g} "
                            f"(x{after / before:.2f}, at most x{growth})")  # fmt: skip
    return failures
