"""The replay pipeline: source -> events -> engine (front-end steps, estimators) -> snapshots -> sinks.

:func:`replay` is the library call behind ``online-slam replay``; it returns one :class:`Results` that the table,
the JSON file and later sinks all read. Its parts: :mod:`~online_slam.pipeline.config` (what a replay runs),
:mod:`~online_slam.pipeline.source` (the source opened as events, the association method),
:mod:`~online_slam.pipeline.run` (the engine, its records, checkpoints) and :mod:`~online_slam.pipeline.score`
(the results).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from online_slam.lazy import lazy_exports

if TYPE_CHECKING:
    from online_slam.pipeline.api import replay
    from online_slam.pipeline.config import ESTIMATORS, Checkpointing, MapConfig, ReplayConfig, estimator_names

_HOMES = {
    "ESTIMATORS": "online_slam.pipeline.config",
    "Checkpointing": "online_slam.pipeline.config",
    "MapConfig": "online_slam.pipeline.config",
    "ReplayConfig": "online_slam.pipeline.config",
    "estimator_names": "online_slam.pipeline.config",
    "replay": "online_slam.pipeline.api",
}
"""Each public name's module (imported on first use: the configuration without the engine)."""

__all__ = ["ESTIMATORS", "Checkpointing", "MapConfig", "ReplayConfig", "estimator_names", "replay"]
__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
