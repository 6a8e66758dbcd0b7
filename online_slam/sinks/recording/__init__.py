"""Rerun recordings: the writer (a replay sink), the reader (summaries, figures, state at a step), the
blueprint (the viewer's default layout) and the layout they share (entities, colours, names).

This package is the only place that imports rerun.
"""

from online_slam.sinks.recording.layout import Layout
from online_slam.sinks.recording.reader import (
    BlueprintView,
    Recording,
    RecordingSeries,
    RecordingSummary,
    blueprint_views,
    check_rrd,
    read_recording,
)
from online_slam.sinks.recording.writer import RerunConfig, RerunSink

__all__ = [
    "BlueprintView",
    "Layout",
    "Recording",
    "RecordingSeries",
    "RecordingSummary",
    "RerunConfig",
    "RerunSink",
    "blueprint_views",
    "check_rrd",
    "read_recording",
]
