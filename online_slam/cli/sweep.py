"""``online-slam sweep SOURCE...``: replays over sources x settings x seeds, as tasks on Dask."""

from __future__ import annotations

import argparse
import sys

from online_slam.errors import OnlineSlamError
from online_slam.estimators.presets import ROBUST_CHOICES
from online_slam.pipeline import ESTIMATORS


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "sweep",
        help="replay every combination of sources, settings and seeds on a Dask cluster; one tidy row each",
        description="Replay the cartesian product of sources (x MRCLAM robots, x seeds for square/grid), smoother "
        "windows and outlier settings, one Dask task per replay (a LocalCluster on this machine's cores, or "
        "--scheduler). One row per replay and estimator; re-running with the same --out skips the replays it holds.",
    )
    p.add_argument("sources", nargs="+", help="built-in worlds (square, grid), stream files, dataset paths")
    p.add_argument("--window", default="20", help="smoother windows, comma-separated (default 20)")
    p.add_argument("--robust", default="auto", help=f"outlier settings, comma-separated ({', '.join(ROBUST_CHOICES)})")
    p.add_argument("--estimators", default=",".join(ESTIMATORS), help="estimators to run (default all)")
    p.add_argument("--runs", type=int, default=1, help="noise seeds per simulated world (default 1)")
    p.add_argument("--robot", default="", help="MRCLAM folders: robots, comma-separated (e.g. 1,2,3,4,5)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--workers", type=int, help="local cluster: worker processes (default: all cores)")
    p.add_argument("--out", metavar="FILE", help="rows to .csv or .parquet, written as replays finish (resumable)")
    p.add_argument("--quiet", action="store_true", help="no progress and no summary")


def _list(text: str, kind: type, option: str) -> list:
    try:
        return [kind(v.strip()) for v in text.split(",") if v.strip()]
    except ValueError:
        raise OnlineSlamError(f"{option}: expected comma-separated values, got {text!r}") from None


def _mean_std(figures: dict, name: str, digits: int = 3) -> str:
    if name not in figures:
        return "-"
    mean, std, _ = figures[name]
    return f"{mean:.{digits}f} +- {std:.{digits}f}"


def _mean_std(figures: dict, name: str, digits: int = 3) -> str:
    if name not in figures:
        return "-"
    mean, std, _ = figures[name]
    return f"{mean:.{digits}f} +- {std:.{digits}f}"


def run(args: argparse.Namespace) -> int:
    """Build the cells, run them, print the summary (mean +- std over seeds)."""
    from online_slam.sweep import make_cells, summary, sweep

    robust = _list(args.robust, str, "--robust")
    unknown = [r for r in robust if r not in ROBUST_CHOICES]
    if unknown:
        raise OnlineSlamError(f"--robust: unknown setting {unknown[0]!r}; expected some of {', '.join(ROBUST_CHOICES)}")
    estimators = _list(args.estimators, str, "--estimators")
    if not set(estimators) <= set(ESTIMATORS):
        raise OnlineSlamError(f"--estimators: expected some of {', '.join(ESTIMATORS)}")
    from online_slam.cli.replay import check_writable
    from online_slam.importers.resolve import check_source

    for source in args.sources:  # usage errors, told before any cluster starts (a failing replay is a row)
        check_source(source)
    if args.out is not None:
        check_writable("--out", args.out)
    cells = make_cells(
        args.sources,
        windows=_list(args.window, int, "--window"),
        robust=robust,
        estimators=estimators,
        runs=args.runs,
        robots=_list(args.robot, int, "--robot"),
    )

    def progress(done: int, total: int) -> None:
        if not args.quiet:
            width = 30
            bar = "#" * (width * done // max(total, 1))
            print(f"\rsweep [{bar:<{width}}] {done}/{total} replays", end="", file=sys.stderr, flush=True)

    report = sweep(cells, out=args.out, scheduler=args.scheduler, workers=args.workers, progress=progress)
    if not args.quiet:
        print(file=sys.stderr)
        print(f"{len(cells)} replays: {report.computed} computed, {report.skipped} already in the output, "
              f"{report.failed} failed")  # fmt: skip
        header = f"{'source':<28}{'robot':>6}{'W':>5}{'robust':>8}{'estimator':>11}"
        print(f"{header}{'online RMSE m':>20}{'final RMSE m':>20}{'step median ms':>17}{'n':>4}")
        for (source, robot, window, setting, estimator), figures in summary(report.rows):
            n = max((v[2] for v in figures.values()), default=0)
            name = source if len(source) <= 27 else "..." + source[-24:]
            online, final = _mean_std(figures, "online_rmse_m"), _mean_std(figures, "final_rmse_m")
            step = _mean_std(figures, "step_median_ms", 2)
            print(f"{name:<28}{robot if robot is not None else '-':>6}{window:>5}{setting:>8}{estimator:>11}"
                  f"{online:>20}{final:>20}{step:>17}{n:>4}")  # fmt: skip
        for row in report.rows:
            if row["error"]:
                print(f"failed: {row['source']} W={row['window']} {row['robust']} seed={row['seed']}: {row['error']}")
    return 1 if report.failed else 0
