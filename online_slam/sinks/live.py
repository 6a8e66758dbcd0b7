"""Live-replay helpers: pace the replay to the stream's clock, and show progress on a terminal."""

from __future__ import annotations

import sys
import time
from collections.abc import Mapping
from typing import IO, TYPE_CHECKING

from online_slam.estimators.protocol import Snapshot
from online_slam.frontend.steps import GroundTruth, Step

if TYPE_CHECKING:
    from online_slam.evaluation.results import Results


class Pacer:
    """Sleeps so that stream time advances at ``rate`` times the wall clock (like ``rosbag play -r``).

    Args:
        rate: Speed-up over the stream's own clock (> 0).
    """

    def __init__(self, rate: float) -> None:
        if not rate > 0:
            raise ValueError("rate must be > 0")
        self.rate = rate
        self._origin: tuple[float, float] | None = None

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Wait until the wall clock catches up with the step's time."""
        now = time.perf_counter()
        if self._origin is None:
            self._origin = (step.t, now)
            return
        due = self._origin[1] + (step.t - self._origin[0]) / self.rate
        if due > now:
            time.sleep(due - now)

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Nothing to do."""


class Progress:
    """A one-line progress counter on a terminal (stderr), redrawn at most 10 times a second.

    Args:
        total: Expected number of steps, if known.
        stream: Where to draw (default stderr); nothing is drawn unless it is a terminal.
    """

    def __init__(self, total: int | None = None, stream: IO[str] | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.total = total
        self._last = 0.0
        self._started = time.perf_counter()

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Redraw the counter."""
        now = time.perf_counter()
        if not self.enabled or now - self._last < 0.1:
            return
        self._last = now
        rate = (step.index + 1) / max(now - self._started, 1e-9)
        of = f"/{self.total}" if self.total else ""
        self.stream.write(f"\rstep {step.index + 1}{of}  t={step.t:.2f} s  {rate:.0f} steps/s ")
        self.stream.flush()

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Clear the line."""
        if self.enabled:
            self.stream.write("\r\033[K")
            self.stream.flush()
