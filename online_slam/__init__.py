"""online-slam: incremental, online 2D landmark SLAM.

Data flows one way: ``sources`` (stream files, simulated worlds) -> ``frontend`` (steps) -> ``estimators``
(snapshots, final estimates) -> ``evaluation`` and ``reports`` (tables, JSON) via :func:`replay`.
"""

from online_slam.errors import InputError, OnlineSlamError, SolverError
from online_slam.evaluation.results import EstimatorResult, OdometryResult, Results
from online_slam.pipeline import ReplayConfig, replay

__all__ = [
    "EstimatorResult",
    "InputError",
    "OdometryResult",
    "OnlineSlamError",
    "ReplayConfig",
    "Results",
    "SolverError",
    "replay",
]

__version__ = "0.1.0"
