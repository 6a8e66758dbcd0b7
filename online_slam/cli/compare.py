"""``online-slam compare SOURCE``: filter versus smoother(s) versus batch, one table, figures, Monte Carlo."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from online_slam.cli.replay import check_outputs, config_from, report_skip, sinks_from, write_json
from online_slam.compare import CompareConfig, compare, replay_config
from online_slam.errors import OnlineSlamError
from online_slam.reports.compare_table import format_comparison


def _ints(text: str, option: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise OnlineSlamError(f"{option}: expected comma-separated integers, got {text!r}") from None
    if not values:
        raise OnlineSlamError(f"{option}: expected at least one value")
    return values


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command (it shares replay's estimator options)."""
    from online_slam.cli import replay as replay_cli

    p = sub.add_parser(
        "compare",
        help="compare EKF, smoother configurations and batch on one stream: table, figures, Monte Carlo",
        description="Run the EKF, every smoother (W, K) and the batch solver on the same stream; print one table.",
    )
    replay_cli.add_options(p)
    p.set_defaults(estimators="ekf,smoother,batch")
    p.add_argument(
        "--window", dest="windows", default="20", metavar="W[,W...]", help="smoother window sizes (default 20)"
    )
    p.add_argument(
        "--relinearize-every",
        dest="relinearize_periods",
        default="1",
        metavar="K[,K...]",
        help="smoother relinearization periods (default 1)",
    )
    p.add_argument(
        "--rrd",
        metavar="PATH",
        help="log every configuration, step by step, to one Rerun recording (.rrd) laid out for comparison",
    )
    p.add_argument(
        "--connect",
        nargs="?",
        const="default",
        metavar="ADDR",
        help="stream that recording to a running Rerun viewer (default address, or a rerun+http:// URL)",
    )
    p.add_argument("--plot", metavar="PATH", help="write the figures (map, error, NEES, latency) to this PNG")
    p.add_argument("--runs", type=int, default=1, help="Monte Carlo runs over noise seeds (simulated worlds only)")
    p.add_argument("--workers", type=int, help="processes for Monte Carlo runs (default: all cores)")


def run(args: argparse.Namespace) -> int:
    """Compare, print the table, write JSON and figures."""
    base = config_from(args)
    windows = _ints(args.windows, "--window")
    ks = _ints(args.relinearize_periods, "--relinearize-every")
    names = tuple(n for n in base.estimators if n != "smoother")
    if len(names) == len(base.estimators):  # no smoother asked for
        windows, ks = (), ()
    try:
        config = CompareConfig(
            windows=windows,
            relinearize_every=ks,
            replay=replace(base, estimators=names),
            runs=args.runs,
            workers=args.workers,
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
