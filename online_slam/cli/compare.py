"""``online-slam compare SOURCE``: filter versus smoother(s) versus batch, one table, figures, Monte Carlo."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from online_slam import options
from online_slam.cli.replay import check_outputs, report_skip, sinks_from, write_json
from online_slam.errors import OnlineSlamError

GRID = ("window", "relinearize_every", "peer")
"""Options compare takes as lists: one smoother per (W, K)."""


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command (replay's options; --window and --relinearize-every take lists)."""
    p = sub.add_parser(
        "compare",
        help="compare EKF, smoother configurations and batch on one stream: table, figures, Monte Carlo",
        description="Run the estimators (--estimators: by default the EKF, every smoother (W, K) and the batch "
        "solver) on the same stream; print one table. "
        "With --runs N (simulated worlds), Monte Carlo over N noise seeds: ANEES, share of steps in its 95% band, "
        "RMSE per online estimator, and with --peer isam2 GTSAM's iSAM2 beside them (--peer ideal: the EKF "
        "linearized at the truth).",
    )
    options.add_options(p, "compare", lists=GRID)


def run(args: argparse.Namespace) -> int:
    """Compare, print the table, write JSON and figures."""
    from online_slam.compare import CompareConfig, compare, replay_config
    from online_slam.reports.compare_table import format_comparison

    windows = args.window or CompareConfig.windows
    ks = args.relinearize_every or CompareConfig.relinearize_every
    base = options.replay_config({**vars(args), "window": windows[0], "relinearize_every": ks[0]}, options.flag)
    names = tuple(n for n in base.estimators if n != "smoother")
    if len(names) == len(base.estimators):  # no smoother asked for
        windows, ks = (), ()
    if args.peer and args.runs < 2:
        raise OnlineSlamError(f"compare: --peer {args.peer[0]} runs beside Monte Carlo runs: give --runs 2 or more")
    try:
        config = CompareConfig(
            windows=windows,
            relinearize_every=ks,
            replay=replace(base, estimators=names),
            runs=args.runs,
            workers=args.workers,
            peers=tuple(args.peer or ()),
        )
    except ValueError as exc:
        raise OnlineSlamError(f"compare: {exc}") from None
    check_outputs(args.json, plot=args.plot)
    if args.rrd and not str(args.rrd).endswith(".rrd"):
        raise OnlineSlamError(f"--rrd: expected a path ending in .rrd, got {args.rrd!r}")
    sinks = sinks_from(args, replay_config(config))  # one recording holds every configuration
    comparison = compare(args.source, config, on_skip=report_skip, sinks=sinks)
    if not args.quiet:  # with --json - stdout is the JSON's: the table goes to stderr
        print(format_comparison(comparison), file=sys.stderr if args.json == "-" else sys.stdout)
    if args.json:
        write_json(args.json, comparison.to_json())
    if args.plot:
        from online_slam.reports.plots import plot_comparison

        plot_comparison(comparison, args.plot)
    failures = [comparison.results.error] + [getattr(sink, "error", None) for sink in sinks]
    for failure in filter(None, failures):
        print(f"online-slam: error: {failure}", file=sys.stderr)
    return 2 if any(failures) else 0
