"""online-slam: incremental, online 2D landmark SLAM.

Data flows one way: ``sources`` (stream files, simulated worlds) -> ``engine`` (front-end steps, ``estimators``)
-> snapshots and estimates -> ``evaluation``, ``reports`` and ``sinks``. Two ways to use it as a library:
:class:`Slam` (push events from a robot's loop, read the estimate at once) and :func:`replay` (a whole stream,
scored against its truth).
"""

from online_slam.errors import ConfigError, InputError, OnlineSlamError
from online_slam.evaluation.results import EstimatorResult, OdometryResult, Results
from online_slam.pipeline import ReplayConfig, replay
from online_slam.slam import Slam, SlamEstimate
from online_slam.version import __version__

__all__ = [
    "ConfigError",
    "EstimatorResult",
    "InputError",
    "OdometryResult",
    "OnlineSlamError",
    "ReplayConfig",
    "Results",
    "Slam",
    "SlamEstimate",
    "__version__",
    "replay",
]
