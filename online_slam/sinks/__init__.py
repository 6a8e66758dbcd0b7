"""Sinks: consumers of step snapshots and final results (Rerun recordings, progress, pacing)."""

from online_slam.sinks.live import Pacer, Progress
from online_slam.sinks.protocol import ProgressSink, ReplayProgress, ReplaySink

__all__ = ["Pacer", "Progress", "ProgressSink", "ReplayProgress", "ReplaySink"]
