"""What the replay pipeline hands to sinks: every step and the results; where it stands, to those that ask."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from online_slam.estimators.protocol import Snapshot
from online_slam.frontend.steps import GroundTruth, Step

if TYPE_CHECKING:
    from online_slam.evaluation.results import Results


class ReplaySink(Protocol):
    """Receives every step once all estimators have consumed it, then the results."""

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """After step ``step.index``: one snapshot per estimator (``odometry`` included), and the truth so far."""
        ...

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """End of stream (or of the valid part of it): the results, final estimates included."""
        ...


@dataclass(frozen=True)
class ReplayProgress:
    """Where a replay stands."""

    read: int
    """Items of the source read so far: events, and bad lines skipped."""
    total: int | None
    """Items the source holds, when known before reading it: the lines of a stream file, the events of a built-in
    world or of a list; None for standard input and datasets."""
    phase: str | None = None
    """What runs once the source is read (e.g. ``batch: solving 1012 poses``); None while reading."""


@runtime_checkable
class ProgressSink(ReplaySink, Protocol):
    """A sink that is also told where the replay stands (a progress display); the pipeline counts the source's
    items up front only when one is given."""

    def on_progress(self, progress: ReplayProgress) -> None:
        """After every step (and its ``on_step``), and once when the final phase begins."""
        ...
