"""online-slam: incremental, online 2D landmark SLAM.

Data flows one way: ``sources`` (stream files, simulated worlds) -> ``engine`` (front-end steps, ``estimators``)
-> snapshots and estimates -> ``evaluation``, ``reports`` and ``sinks``. Two ways to use it as a library:
:class:`Slam` (push events from a robot's loop, read the estimate at once) and :func:`replay` (a whole stream,
scored against its truth); :func:`read_recording` loads a Rerun recording's series back into arrays.

The names below are imported on first use, so that ``import online_slam`` (and ``online-slam --help``) does not
load the numerical libraries.
"""

import importlib as _importlib
import importlib.util as _importlib_util
import typing as _typing

from online_slam.version import __version__

if _typing.TYPE_CHECKING:
    from online_slam.errors import ConfigError, InputError, OnlineSlamError
    from online_slam.evaluation.results import EstimatorResult, OdometryResult, Results
    from online_slam.pipeline import ReplayConfig, replay
    from online_slam.sinks.recording.reader import RecordingSeries, read_recording
    from online_slam.slam import RobotEstimate, Slam, SlamEstimate

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
}
"""Each public name's module."""

__all__ = [
    "ConfigError",
    "EstimatorResult",
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


def __getattr__(name: str) -> _typing.Any:
    """A public name, imported from its module on first use (or a subpackage, as ``online_slam.sources``)."""
    if name not in _HOMES:
        if _importlib_util.find_spec(f"{__name__}.{name}") is None:
            raise AttributeError(f"module 'online_slam' has no attribute {name!r}")
        return _importlib.import_module(f"{__name__}.{name}")
    value = getattr(_importlib.import_module(_HOMES[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public API only (helpers and submodules stay out of ``dir(online_slam)`` and tab completion)."""
    return sorted(__all__)
