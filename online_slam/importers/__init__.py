"""Importers: dataset files -> stream-v1 events. They yield events; they never call estimators."""

from online_slam.importers.detect import DATASET_FORMATS, open_dataset

__all__ = ["DATASET_FORMATS", "open_dataset"]
