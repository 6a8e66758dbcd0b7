"""What the replay pipeline hands to sinks."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Protocol

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
