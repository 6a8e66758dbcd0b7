"""online-slam: incremental, online 2D landmark SLAM.

Data flows one way: ``sources`` (stream files, simulated worlds) -> ``engine`` (front-end steps, ``estimators``)
-> snapshots and estimates -> ``evaluation``, ``reports`` and ``sinks``. Two ways to use it as a library:
:class:`Slam` (push events from a robot's loop, read the estimate at once) and :func:`replay` (a whole stream,
scored against its truth); :func:`read_recording` loads a Rerun recording's series back into arrays.

Names are imported on first use, so ``import online_slam`` (and the command line's ``--help``) stays quick and
rerun is loaded only by what needs it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from online_slam.errors import ConfigError, InputError, OnlineSlamError
from online_slam.version import __version__

if TYPE_CHECKING:
    from online_slam.evaluation.results import EstimatorResult, OdometryResult, Results
    from online_slam.pipeline import ReplayConfig, replay
    from online_slam.sinks.recording.reader import RecordingSeries, read_recording
    from online_slam.slam import Slam, SlamEstimate

_LAZY = {
    "EstimatorResult": "online_slam.evaluation.results",
    "OdometryResult": "online_slam.evaluation.results",
    "Results": "online_slam.evaluation.results",
    "ReplayConfig": "online_slam.pipeline",
    "replay": "online_slam.pipeline",
    "RecordingSeries": "online_slam.sinks.recording.reader",
    "read_recording": "online_slam.sinks.recording.reader",
    "Slam": "online_slam.slam",
    "SlamEstimate": "online_slam.slam",
}
"""Public name -> the module that defines it, imported on first access."""

__all__ = [
    "ConfigError",
    "EstimatorResult",
    "InputError",
    "OdometryResult",
    "OnlineSlamError",
    "RecordingSeries",
    "ReplayConfig",
    "Results",
    "Slam",
    "SlamEstimate",
    "__version__",
    "read_recording",
    "replay",
]


def __getattr__(name: str) -> Any:
    """Import a public name on first access (PEP 562)."""
    if name not in _LAZY:
        raise AttributeError(f"module 'online_slam' has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
