"""Estimators: the only stateful objects. Each consumes steps and returns immutable snapshots."""

from __future__ import annotations

from typing import TYPE_CHECKING

from online_slam.lazy import lazy_exports

if TYPE_CHECKING:
    from online_slam.estimators.batch import BatchConfig, BatchEstimator
    from online_slam.estimators.dead_reckoning import DeadReckoning
    from online_slam.estimators.ekf import EkfSlam
    from online_slam.estimators.ekf_config import EkfConfig
    from online_slam.estimators.protocol import Estimate, Estimator, SlamEstimator, Snapshot
    from online_slam.estimators.smoother import SlidingWindowSmoother, SmootherConfig

_HOMES = {
    "BatchConfig": "online_slam.estimators.batch",
    "BatchEstimator": "online_slam.estimators.batch",
    "DeadReckoning": "online_slam.estimators.dead_reckoning",
    "EkfSlam": "online_slam.estimators.ekf",
    "EkfConfig": "online_slam.estimators.ekf_config",
    "Estimate": "online_slam.estimators.protocol",
    "Estimator": "online_slam.estimators.protocol",
    "SlamEstimator": "online_slam.estimators.protocol",
    "Snapshot": "online_slam.estimators.protocol",
    "SlidingWindowSmoother": "online_slam.estimators.smoother",
    "SmootherConfig": "online_slam.estimators.smoother",
}
"""Each public name's module (imported on first use)."""

__all__ = [
    "BatchConfig",
    "BatchEstimator",
    "DeadReckoning",
    "EkfConfig",
    "EkfSlam",
    "Estimate",
    "Estimator",
    "SlamEstimator",
    "SlidingWindowSmoother",
    "SmootherConfig",
    "Snapshot",
]
__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
