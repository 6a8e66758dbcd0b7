"""Reports: sinks that turn results into text for people (tables) and files (JSON)."""

from online_slam.reports.table import format_results

__all__ = ["format_results"]
