"""Progress of a replay: a total, percentage, rate and ETA on a terminal, a line for the batch solve, silence
elsewhere; the pipeline counts the source's items for it."""

from __future__ import annotations

import gzip
import io
import time
from collections.abc import Mapping
from pathlib import Path

from online_slam.estimators.protocol import Snapshot
from online_slam.evaluation.results import Results
from online_slam.frontend.steps import GroundTruth, Step
from online_slam.pipeline import ReplayConfig, replay
from online_slam.sinks.live import Progress
from online_slam.sinks.protocol import ProgressSink, ReplayProgress
from online_slam.sources import square_world, write_stream


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


class Told:
    """A progress sink that keeps what it is told."""

    def __init__(self) -> None:
        self.told: list[ReplayProgress] = []

    def on_step(self, step: Step, snapshots: Mapping[str, Snapshot], truth: GroundTruth) -> None:
        """Nothing."""

    def on_progress(self, progress: ReplayProgress) -> None:
        self.told.append(progress)

    def on_finish(self, results: Results, truth: GroundTruth) -> None:
        """Nothing."""


def test_a_terminal_sees_total_percentage_rate_eta_then_the_batch_phase() -> None:
    terminal = Terminal()
    progress = Progress(terminal)
    assert isinstance(progress, ProgressSink)
    progress.on_progress(ReplayProgress(0, 1000))
    time.sleep(0.15)  # past the redraw interval
    progress.on_progress(ReplayProgress(500, 1000))
    shown = terminal.getvalue()
    assert "500/1000 events" in shown and " 50%|" in shown and "events/s" in shown
    assert "ETA 00:0" in shown
    progress.on_progress(ReplayProgress(1000, 1000, "batch: solving 1012 poses"))
    assert "batch: solving 1012 poses..." in terminal.getvalue()
    progress.on_finish(None, GroundTruth())  # type: ignore[arg-type]
    assert terminal.getvalue().endswith("\r")  # the line is cleared for the table


def test_without_a_total_the_count_and_rate_are_shown() -> None:
    terminal = Terminal()
    progress = Progress(terminal)
    progress.on_progress(ReplayProgress(0, None))
    time.sleep(0.15)
    progress.on_progress(ReplayProgress(40, None))
    assert "replay: 40 events" in terminal.getvalue() and "%" not in terminal.getvalue()


def test_nothing_is_drawn_when_not_a_terminal() -> None:
    stream = io.StringIO()
    replay("square", sinks=[Progress(stream)])
    assert stream.getvalue() == ""


def test_a_replay_on_a_terminal_draws_and_clears() -> None:
    terminal = Terminal()
    replay("square", sinks=[Progress(terminal)])
    shown = terminal.getvalue()
    assert "/158 events" in shown and "batch: solving 25 poses..." in shown


def test_the_pipeline_counts_a_worlds_events_and_a_files_lines(tmp_path: Path) -> None:
    told = Told()
    plain = replay("square")
    watched = replay("square", sinks=[told])
    assert watched.estimators["batch"].final_rmse_m == plain.estimators["batch"].final_rmse_m  # same run
    assert {p.total for p in told.told} == {158}
    reading = [p.read for p in told.told if p.phase is None]
    assert reading == sorted(reading) and reading[-1] == 158 and len(reading) == 25  # one per step
    assert told.told[-1].phase == "batch: solving 25 poses"
    path = tmp_path / "square.jsonl.gz"
    write_stream(path, square_world())
    with gzip.open(path, "rt", encoding="utf-8") as handle:
        lines = sum(1 for _ in handle)
    told = Told()
    replay(path, ReplayConfig(estimators=("ekf",)), sinks=[told])
    assert {p.total for p in told.told} == {lines}
    assert told.told[-1].phase == "scoring" and max(p.read for p in told.told) == lines


def test_iterables_give_a_total_only_when_they_have_a_length() -> None:
    events = list(square_world())
    told = Told()
    replay(events, ReplayConfig(estimators=("ekf",)), sinks=[told])
    assert {p.total for p in told.told} == {len(events)}
    told = Told()
    replay(iter(events), ReplayConfig(estimators=("ekf",)), sinks=[told])
    assert {p.total for p in told.told} == {None}
