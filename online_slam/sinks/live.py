"""Live-replay helpers: pace the replay to the stream's clock, and show progress on a terminal."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from typing import IO, TYPE_CHECKING

from online_slam.estimators.protocol import Snapshot
from online_slam.frontend.steps import GroundTruth, Step

if TYPE_CHECKING:
    from tqdm import tqdm

    from online_slam.evaluation.results import Results
    from online_slam.sinks.protocol import ReplayProgress


class Pacer:
    """Sleeps so that stream time advances at ``rate`` times the wall clock (like ``rosbag play -r``).

    Args:
        rate: Speed-up over the stream's own clock (> 0).
        clock: The wall clock, seconds.
        sleep: Waits that many seconds.
    """

    def __init__(
        self, rate: float, clock: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep
    ) -> None:
        if not rate > 0:
            raise ValueError("rate must be > 0")
        self.rate = rate
        self._clock, self._sleep = clock, sleep
        self._origin: tuple[float, float] | None = None

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Wait until the wall clock catches up with the step's time."""
        now = self._clock()
        if self._origin is None:
            self._origin = (step.t, now)
            return
        due = self._origin[1] + (step.t - self._origin[0]) / self.rate
        if due > now:
            self._sleep(due - now)

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Nothing to do."""


_WITH_TOTAL = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} events, {rate_fmt}, ETA {remaining}{postfix}"
_WITHOUT_TOTAL = "{desc}: {n_fmt} events, {rate_fmt}{postfix}"


class Progress:
    """A replay's progress on a terminal (stderr), drawn by tqdm: how much of the source is read out of its total,
    the percentage, the rate and the time left (a count and the rate when the total is unknown, e.g. stdin), then
    a line while the final phase runs (the batch solve). Nothing at all unless the stream is a terminal.

    A :class:`~online_slam.sinks.protocol.ProgressSink`.

    Args:
        stream: Where to draw (default stderr).
    """

    def __init__(self, stream: IO[str] | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        """Whether anything is drawn (the stream is a terminal)."""
        self._bar: tqdm | None = None

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Show the step reached beside the count."""
        if self._bar is not None:
            self._bar.set_postfix_str(f"step {step.index + 1}", refresh=False)

    def on_progress(self, progress: ReplayProgress) -> None:
        """Advance the bar while the source is read; replace it with the phase's line once it is."""
        if not self.enabled:
            return
        if progress.phase is not None:
            self._close()
            self._bar = self._open(progress.phase + "...", None, "{desc}")
            return
        if self._bar is None:
            known = progress.total is not None
            self._bar = self._open("replay", progress.total, _WITH_TOTAL if known else _WITHOUT_TOTAL)
        self._bar.update(progress.read - self._bar.n)

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Clear the line."""
        self._close()

    def _open(self, description: str, total: int | None, layout: str) -> tqdm:
        from tqdm import tqdm

        return tqdm(total=total, desc=description, bar_format=layout, unit=" events", file=self.stream,
                    leave=False, mininterval=0.1, dynamic_ncols=True)  # fmt: skip

    def _close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
