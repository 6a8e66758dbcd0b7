"""``online-slam replay [SOURCE]``: run the estimators over a stream and print the table."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from online_slam.errors import InputError, OnlineSlamError
from online_slam.options import add_options, flag, replay_config
from online_slam.wording import counted

if TYPE_CHECKING:
    from online_slam.evaluation.results import Results
    from online_slam.pipeline import ReplayConfig
    from online_slam.pipeline.noise import Fit


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "replay",
        help="replay a stream (file, '-' or built-in world) through the estimators",
        description="Replay a stream step by step through the estimators and compare them with the truth.",
    )
    add_options(p, "replay")


def report_skip(error: InputError) -> None:
    """Tell the user about one skipped line, once, on stderr."""
    print(f"online-slam: skipped {error}", file=sys.stderr)


SKIPS_SHOWN = 20
"""Skipped lines told one by one; the rest are counted in the table's notes and the JSON."""


class SkipReport:
    """Tells the user about each skipped line on stderr, up to :data:`SKIPS_SHOWN`, then once that more are
    counted, not shown."""

    def __init__(self) -> None:
        self.told = 0

    def __call__(self, error: InputError) -> None:
        self.told += 1
        if self.told <= SKIPS_SHOWN:
            report_skip(error)
        elif self.told == SKIPS_SHOWN + 1:
            print("online-slam: skipping more lines; they are counted below, not shown", file=sys.stderr)


def report_warning(message: str) -> None:
    """Tell the user, once, that the input looks wrong and why."""
    print(f"online-slam: warning: {message}", file=sys.stderr, flush=True)


def write_json(destination: str, document: dict) -> None:
    """Write a JSON document to a path, or to stdout for ``-``."""
    text = json.dumps(document, indent=2)
    if destination == "-":
        print(text)
        return
    try:
        Path(destination).write_text(text + "\n", encoding="utf-8")
    except OSError as exc:
        raise OnlineSlamError(f"{destination}: cannot write ({exc.strerror or exc})") from None


def check_writable(option: str, path: str | Path) -> None:
    """Refuse a file path that cannot be written (a folder, or no writable folder to hold it)."""
    target = Path(path)
    if target.is_dir():
        raise OnlineSlamError(f"{option}: {path} is a folder, expected a file path")
    folder = target.parent
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise OnlineSlamError(f"{option}: cannot write {path} (no writable folder {str(folder)!r})")


def check_folder(option: str, path: str | Path) -> None:
    """Refuse a folder path that cannot be made or written (a file in the way, no writable parent)."""
    target = Path(path)
    existing = next((p for p in (target, *target.parents) if p.exists()), Path("."))
    if not existing.is_dir():
        raise OnlineSlamError(f"{option}: {existing} is a file, expected a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OnlineSlamError(f"{option}: cannot write in {existing}")


def check_outputs(json_path: str | None = None, tum: str | None = None, plot: str | None = None) -> None:
    """Refuse output paths that cannot be written before any work is done (a long run would be lost)."""
    if plot is not None and not str(plot).endswith(".png"):
        raise OnlineSlamError(f"--plot: expected a path ending in .png, got {plot!r}")
    for option, path in (("--json", None if json_path == "-" else json_path), ("--plot", plot)):
        if path is not None:
            check_writable(option, path)
    if tum is not None:
        check_folder("--tum", tum)


def config_from(args: argparse.Namespace) -> ReplayConfig:
    """The replay configuration that the parsed options ask for."""
    return replay_config(vars(args), naming=flag)


def sinks_from(args: argparse.Namespace, config: ReplayConfig) -> list:
    """Progress bar, pacing, Rerun logging and the estimate stream, as the options ask (a --connect without a viewer
    raises here)."""
    from online_slam.sinks.live import Pacer, Progress

    sinks: list = []
    if getattr(args, "rate", None) is not None:
        try:
            sinks.append(Pacer(args.rate))
        except ValueError as exc:
            raise OnlineSlamError(f"--rate: {exc}") from None
    if args.connect not in (None, "default") and "://" not in args.connect:
        raise OnlineSlamError(
            f"--connect: {args.connect!r} is not a viewer address (rerun+http://HOST:PORT/proxy); "
            "give the source before --connect, or --connect=URL"
        )
    if args.rrd or args.connect:
        from online_slam.pipeline import estimator_names
        from online_slam.sinks.recording import Layout, RerunConfig, RerunSink

        name = "<stdin>" if args.source == "-" else str(args.source)
        layout = Layout(*estimator_names(config))
        sinks.append(RerunSink(RerunConfig(path=args.rrd, connect=args.connect), name, layout))
    if getattr(args, "emit", None) is not None:  # replay's, not compare's
        from online_slam.sinks.emit import EstimateStream

        sinks.append(EstimateStream(args.emit, emitted(args, config), tell=report))
    elif getattr(args, "emit_estimator", None) is not None:
        raise OnlineSlamError("--emit-estimator: give --emit DEST too")
    progress = Progress()
    if progress.enabled and not args.quiet:  # a source is counted for its total only when a bar is drawn
        sinks.append(progress)
    return sinks


def emitted(args: argparse.Namespace, config: ReplayConfig) -> tuple[str, ...]:
    """The estimators whose estimates ``--emit`` writes: ``--emit-estimator``'s, by default the first online one."""
    from online_slam.pipeline import estimator_names

    online = estimator_names(config)[0]  # dead reckoning first
    choice = args.emit_estimator
    if choice is None:
        return online[1:2] or online[:1]
    if choice == "all":
        return online[1:] or online[:1]
    if choice not in online:
        expected = ", ".join((*online, "all"))
        raise OnlineSlamError(f"--emit-estimator: {choice!r} estimates no step here; expected one of {expected}")
    return (choice,)


def report(message: str) -> None:
    """Say something about the run on stderr."""
    print(f"online-slam: {message}", file=sys.stderr, flush=True)


def write_final_map(path: str, results: Results, quiet: bool = False) -> None:
    """Write the run's final map (``--map-out``), and say so on stderr (unless ``quiet``)."""
    from online_slam.sources.landmark_map import write_map

    final = None if results.map is None else results.map.final
    if final is None:
        raise OnlineSlamError("--map-out: the map's covariances come from the smoother or the EKF; run one")
    write_map(path, final)
    if not quiet:
        print(f"online-slam: wrote a map of {counted(len(final), 'landmark')} to {path}", file=sys.stderr)


def print_noise_fit(fit: Fit, stderr: bool) -> None:
    """Print what ``--noise fit`` or ``--noise self`` fitted, before the replay that uses it (on stderr when stdout
    is the JSON's)."""
    from online_slam.evaluation import noise_fit, noise_self

    text = noise_fit.describe(fit) if isinstance(fit, noise_fit.NoiseFit) else noise_self.describe(fit)
    print(text, file=sys.stderr if stderr else sys.stdout, flush=True)


def run(args: argparse.Namespace) -> int:
    """Replay, print the table, write JSON; exit 2 if the input turned bad part-way."""
    from online_slam.evaluation.results import INTERRUPTED
    from online_slam.pipeline import Checkpointing, replay
    from online_slam.reports.table import format_results

    config = config_from(args)
    check_outputs(args.json, args.tum)
    stdout_taken = args.json == "-" or args.emit == "-"  # the table then goes to stderr
    if args.json == "-" and args.emit == "-":
        raise OnlineSlamError("--json - and --emit -: both would write to stdout; give one of them a path")
    if args.emit not in (None, "-") and "://" not in args.emit:
        check_writable("--emit", args.emit)
    if args.map_out:
        check_writable("--map-out", args.map_out)
        if not {"smoother", "ekf"} & set(config.estimators):  # refused before the run, not after it
            raise OnlineSlamError("--map-out: the map's covariances come from the smoother or the EKF; run one")
    if args.rrd and not str(args.rrd).endswith(".rrd"):
        raise OnlineSlamError(f"--rrd: expected a path ending in .rrd, got {args.rrd!r}")
    if args.resume and (args.rrd or args.connect):
        raise OnlineSlamError("--resume: a Rerun recording cannot be continued; resume without --rrd/--connect")
    if args.checkpoint:
        check_folder("--checkpoint", args.checkpoint)
    checkpoint = Checkpointing(Path(args.checkpoint), args.checkpoint_every) if args.checkpoint else None
    sinks = sinks_from(args, config)
    with interrupts() as stopped:
        results = replay(
            args.source, config, sinks=sinks, on_skip=SkipReport(), checkpoint=checkpoint, resume=args.resume,
            on_noise_fit=None if args.quiet else lambda fit: print_noise_fit(fit, stdout_taken),
            stop=stopped.is_set, on_warning=report_warning,
        )  # fmt: skip
    if not args.quiet:  # with --json - (or --emit -) stdout is the JSON's: the table goes to stderr
        print(format_results(results), file=sys.stderr if stdout_taken else sys.stdout)
    if args.json:
        write_json(args.json, results.to_json())
    if args.tum:
        from online_slam.sinks.tum import write_tum

        write_tum(args.tum, results)
    if args.map_out:
        write_final_map(args.map_out, results, args.quiet)
    interrupted = results.error == INTERRUPTED
    failures = [None if interrupted else results.error] + [getattr(sink, "error", None) for sink in sinks]
    for failure in filter(None, failures):
        print(f"online-slam: error: {failure}", file=sys.stderr)
    if interrupted:
        print(f"online-slam: interrupted after {results.poses} poses; their figures are above", file=sys.stderr)
        return 130
    return 2 if any(failures) else 0


@contextlib.contextmanager
def interrupts() -> Iterator[threading.Event]:
    """SIGINT and SIGTERM set the event (the replay ends at the next step and keeps its work); a second one
    interrupts at once, as before. Outside the main thread (no handlers can be set there) nothing changes."""
    stopped = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stopped
        return

    def handle(signum: int, frame: object) -> None:
        if stopped.is_set():
            raise KeyboardInterrupt
        stopped.set()

    saved = {sig: signal.signal(sig, handle) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stopped
    finally:
        for sig, previous in saved.items():
            signal.signal(sig, previous)
