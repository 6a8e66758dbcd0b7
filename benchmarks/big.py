"""The big world: 5000 poses, ~1000 landmarks over a 150 m square; the default smoother beside iSAM2 and batch.

Ours: one replay with the default smoother and the batch solver (the reference final estimate). The peer: GTSAM
iSAM2 (threshold 0.01, every step) on the same front-end steps, with its online and final poses scored against
the same truth (no alignment: the start pose is fixed in both).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from online_slam import gtsam_peer
from online_slam.frontend.steps import FrontEnd
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources.worlds import GridConfig, WaypointConfig, grid_world, waypoint_world

BIG_WORLD = GridConfig(poses=5000, blocks=15, landmarks=1000)
"""``online-slam simulate grid --blocks 15 --landmarks 1000 --poses 5000`` (982 landmarks seen, 72,287 sightings)."""
WAYPOINT_WORLD = WaypointConfig()
"""``online-slam simulate waypoint``: 5000 poses 0.5 m apart, 1500 landmarks over 150 m, 6 m range (884 seen,
38,539 sightings)."""


@dataclass(frozen=True)
class BigRow:
    """One system's figures on the big world."""

    label: str
    """Who ran."""
    online_rmse_m: float
    """RMSE of each pose as estimated when newest."""
    final_rmse_m: float
    """RMSE of the final estimate."""
    landmark_rmse_m: float | None
    """Landmark RMSE (ours; None for the peer)."""
    median_ms: float
    """Median step time."""
    p95_ms: float
    """95th percentile."""
    p99_ms: float
    """99th percentile."""
    max_ms: float
    """Largest step time."""
    total_s: float
    """Total wall time of the run (the final solve included)."""


def _stats(ms: np.ndarray) -> tuple[float, float, float, float]:
    p95, p99 = np.percentile(ms, [95, 99])
    return float(np.median(ms)), float(p95), float(p99), float(ms.max())


def run_big_world(config: GridConfig | WaypointConfig = BIG_WORLD) -> tuple[list[BigRow], tuple[float, float]]:
    """Replay the world with the default smoother and batch, then iSAM2 on the same steps.

    Args:
        config: A grid world's or a waypoint world's settings.

    Returns:
        (rows: ours first, then iSAM2 when available; (batch final RMSE, batch landmark RMSE)).
    """
    events = list(grid_world(config) if isinstance(config, GridConfig) else waypoint_world(config))
    results = replay(
        iter(events), replace(ReplayConfig(), estimators=("smoother", "batch")), name="big", validate=False
    )
    ours = results.estimators["smoother"]
    series = results.series["smoother"]
    rows = [
        BigRow(
            "smoother default",
            float(ours.online_rmse_m),
            float(ours.final_rmse_m),
            ours.landmark_rmse_m,
            *_stats(series.step_ms),
            ours.total_s,
        )
    ]
    batch = results.estimators["batch"]
    if gtsam_peer.available():
        frontend = FrontEnd()
        steps = list(frontend.steps(events))
        truth = np.array([frontend.truth.poses[s.index] for s in steps])[:, :2]
        started = time.perf_counter()
        peer = gtsam_peer.isam2_online(steps)
        total = time.perf_counter() - started

        def rmse(poses: np.ndarray) -> float:
            return float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth) ** 2, axis=1))))

        rows.append(
            BigRow("GTSAM iSAM2", rmse(peer.poses), rmse(peer.final_poses), None, *_stats(peer.step_s * 1e3), total)
        )
    return rows, (float(batch.final_rmse_m), float(batch.landmark_rmse_m))
