"""Estimators: the only stateful objects. Each consumes steps and returns immutable snapshots."""

from online_slam.estimators.batch import BatchConfig, BatchEstimator
from online_slam.estimators.dead_reckoning import DeadReckoning
from online_slam.estimators.ekf import EkfSlam
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.protocol import Estimate, Estimator, SlamEstimator, Snapshot
from online_slam.estimators.smoother import SlidingWindowSmoother, SmootherConfig

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
