"""online-slam: incremental, online 2D landmark SLAM.

Data flows one way: ``sources`` (stream files, simulated worlds) -> ``engine`` (front-end steps, ``estimators``)
-> snapshots and estimates -> ``evaluation``, ``reports`` and ``sinks``. Two ways to use it as a library:
:class:`Slam` (push events from a robot's loop, read the estimate at once) and :func:`replay` (a whole stream,
scored against its truth); :func:`read_recording` loads a Rerun recording's series back into arrays.

The names below are imported on first use, so that ``import online_slam`` (and ``online-slam --help``) does not
load the numerical libraries.
"""

import typing as _typing

from online_slam.lazy import lazy_exports as _lazy_exports
from online_slam.version import __version__

if _typing.TYPE_CHECKING:
    from online_slam.errors import ConfigError, InputError, OnlineSlamError
    from online_slam.evaluation.results import EstimatorResult, OdometryResult, Results
    from online_slam.pipeline import ReplayConfig, replay
    from online_slam.sinks.recording.reader import RecordingSeries, read_recording
    from online_slam.slam import RobotEstimate, Slam, SlamEstimate
    from online_slam.sources.events import GeneratedId

_HOMES = {
    "ConfigError": "online_slam.errors",
    "InputError": "online_slam.errors",
    "OnlineSlamError": "online_slam.errors",
    "EstimatorResult": "online_slam.evaluation.results",
    "OdometryResult": "online_slam.evaluation.results",
    "Results": "online_slam.evaluation.results",
    "ReplayConfig": "online_slam.pipeline",
    "replay": "online_slam.pipeline",
    "RecordingSeries": "online_slam.sinks.recording.reader",
    "read_recording": "online_slam.sinks.recording.reader",
    "RobotEstimate": "online_slam.slam",
    "Slam": "online_slam.slam",
    "SlamEstimate": "online_slam.slam",
    "GeneratedId": "online_slam.sources.events",
}
"""Each public name's module."""

__all__ = [
    "ConfigError",
    "EstimatorResult",
    "GeneratedId",
    "InputError",
    "OdometryResult",
    "OnlineSlamError",
    "RecordingSeries",
    "ReplayConfig",
    "Results",
    "RobotEstimate",
    "Slam",
    "SlamEstimate",
    "__version__",
    "read_recording",
    "replay",
]


__getattr__, __dir__ = _lazy_exports(__name__, _HOMES)
