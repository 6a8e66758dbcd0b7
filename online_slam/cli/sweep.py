"""``online-slam sweep SOURCE...``: replays over sources x settings x seeds, as tasks on Dask."""

from __future__ import annotations

import argparse
import sys

from online_slam.errors import OnlineSlamError
from online_slam.options import add_options, estimator_options
from online_slam.wording import counted


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command: every estimator option takes a comma-separated list."""
    p = sub.add_parser(
        "sweep",
        help="replay every combination of sources, settings and seeds on a Dask cluster; one tidy row each",
        description="Replay the cartesian product of sources (x MRCLAM robots, x seeds for built-in worlds) and "
        "estimator settings (each a comma-separated list, e.g. --window 5,20 --robust auto,huber), one Dask task "
        "per replay (a LocalCluster on this machine's cores, or --scheduler); a replay's figures equal those of "
        "'replay' with the same options. One row per replay and estimator; re-running with the same --output skips "
        "the replays it holds.",
    )
    add_options(p, "sweep", lists=(*estimator_options(), "robot"))


def _mean_std(figures: dict, name: str, digits: int = 3) -> str:
    if name not in figures:
        return "-"
    mean, std, _ = figures[name]
    return f"{mean:.{digits}f} +- {std:.{digits}f}"


def _settings_text(settings: tuple) -> str:
    return " ".join(f"{name}={value}" for name, value in settings) or "-"


def run(args: argparse.Namespace) -> int:
    """Build the cells, run them, print the summary (mean +- std over seeds)."""
    from online_slam.cli.replay import check_writable
    from online_slam.importers.resolve import check_source
    from online_slam.pipeline import ESTIMATORS
    from online_slam.sweep import make_cells, summary, sweep

    estimators = [n.strip() for n in args.estimators.split(",") if n.strip()]
    if not set(estimators) <= set(ESTIMATORS):
        raise OnlineSlamError(f"--estimators: expected some of {', '.join(ESTIMATORS)}")
    for source in args.sources:  # usage errors, told before any cluster starts (a failing replay is a row)
        check_source(source)
    if args.output is not None:
        check_writable("--output", args.output)
    settings = {name: getattr(args, name) for name in estimator_options() if getattr(args, name) is not None}
    cells = make_cells(args.sources, settings, estimators, runs=args.runs, robots=args.robot or ())

    def progress(done: int, total: int) -> None:
        if not args.quiet:
            width = 30
            bar = "#" * (width * done // max(total, 1))
            print(f"\rsweep [{bar:<{width}}] {done}/{counted(total, 'replay')}", end="", file=sys.stderr, flush=True)

    report = sweep(cells, out=args.output, scheduler=args.scheduler, workers=args.workers, progress=progress)
    if not args.quiet:
        print(file=sys.stderr)
        print(f"{counted(len(cells), 'replay')}: {report.computed} computed, {report.skipped} already in the output, "
              f"{report.failed} failed")  # fmt: skip
        _print_summary(summary(report.rows))
        for row in report.rows:
            if row["error"]:
                given = _settings_text(tuple((n, row[n]) for n in settings))
                print(f"failed: {row['source']} {given} seed={row['seed']}: {row['error']}")
    return 1 if report.failed else 0


def _print_summary(groups: list) -> None:
    """One line per (source, robot, settings that vary, estimator): mean +- std over seeds."""
    width = max([len(_settings_text(key[2])) for key, _ in groups] + [8]) + 2
    named = max([len(key[3]) for key, _ in groups] + [9]) + 2  # e.g. "ekf robot 1" on a stream of several robots
    header = f"{'source':<28}{'robot':>6}  {'settings':<{width}}{'estimator':>{named}}"
    print(f"{header}{'online RMSE m':>20}{'final RMSE m':>20}{'step median ms':>17}{'n':>4}")
    for (source, robot, settings, estimator), figures in groups:
        n = max((v[2] for v in figures.values()), default=0)
        name = source if len(source) <= 27 else "..." + source[-24:]
        online, final = _mean_std(figures, "online_rmse_m"), _mean_std(figures, "final_rmse_m")
        step = _mean_std(figures, "step_median_ms", 2)
        print(f"{name:<28}{robot if robot is not None else '-':>6}  {_settings_text(settings):<{width}}"
              f"{estimator:>{named}}{online:>20}{final:>20}{step:>17}{n:>4}")  # fmt: skip
