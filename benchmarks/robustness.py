"""Robustness benchmark: wrong landmark ids in the grid world, our default estimators beside GTSAM iSAM2 with a
Cauchy kernel on the same streams, in the same run."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from benchmarks import gtsam_peer
from online_slam.engine import Engine
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sources.worlds import Contamination, GridConfig, contaminate, grid_world


@dataclass(frozen=True)
class RobustnessRow:
    """Figures at one contamination level (metres; None where not run)."""

    wrong_ids: float
    """Fraction of sightings with a wrong landmark id."""
    ekf_online: float
    """EKF online RMSE."""
    smoother_online: float
    """Smoother online RMSE."""
    smoother_final: float
    """Smoother final RMSE."""
    batch_final: float
    """Batch final RMSE."""
    isam2_online: float | None
    """iSAM2 (Cauchy kernel) online RMSE."""
    isam2_final: float | None
    """iSAM2 (Cauchy kernel) final RMSE."""


def _rmse(poses: np.ndarray, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth[:, :2]) ** 2, axis=1))))


def run_robustness(
    config: GridConfig, levels: tuple[float, ...] = (0.0, 0.05, 0.1, 0.2), cauchy: float = 3.0, seed: int = 1
) -> list[RobustnessRow]:
    """Replay the grid world at each wrong-id level with default flags; iSAM2 + Cauchy on the same steps."""
    rows = []
    for level in levels:
        events = list(grid_world(config))
        if level:
            events = list(contaminate(events, Contamination(wrong_ids=level, seed=seed)))
        results = replay(iter(events), ReplayConfig(), validate=False)
        figures = results.estimators
        isam_online = isam_final = None
        if gtsam_peer.available():
            engine = Engine([])
            steps = [r.step for r in (engine.push(e) for e in events) if r is not None]
            last = engine.close()
            steps += [last.step] if last is not None else []
            truth = np.array([engine.frontend.truth.poses[s.index] for s in steps])
            peer = gtsam_peer.isam2_online(steps, cauchy=cauchy)
            isam_online, isam_final = _rmse(peer.poses, truth), _rmse(peer.final_poses, truth)
        rows.append(
            RobustnessRow(
                level,
                figures["ekf"].online_rmse_m or float("nan"),
                figures["smoother"].online_rmse_m or float("nan"),
                figures["smoother"].final_rmse_m or float("nan"),
                figures["batch"].final_rmse_m or float("nan"),
                isam_online,
                isam_final,
            )
        )
    return rows
