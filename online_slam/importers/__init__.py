"""Importers: dataset files -> stream-v1 events. They yield events; they never call estimators.

Each format is a plug-in registered in :mod:`online_slam.importers.registry`.
"""

from online_slam.importers.registry import detect, names, open_dataset

__all__ = ["detect", "names", "open_dataset"]
