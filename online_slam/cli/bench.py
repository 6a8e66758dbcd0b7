"""``online-slam bench``: benchmarks that print figures and ratios against peers measured in the same run."""

from __future__ import annotations

import argparse

from online_slam.bench.batch import run_batch_bench
from online_slam.sources.worlds import GridConfig


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "bench",
        help="benchmark against peers (GTSAM, with the 'peers' extra) on a simulated grid world",
        description="Measure solve times on a grid world beside GTSAM, in the same run, and print ratios.",
    )
    p.add_argument("--poses", type=int, default=GridConfig.poses, help="poses of the grid world (default 2000)")
    p.add_argument("--seed", type=int, default=GridConfig.seed, help="seed of the grid world")
    p.add_argument("--repeats", type=int, default=3, help="timed repeats per solver; the best counts (default 3)")


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks and print their table."""
    bench = run_batch_bench(GridConfig(poses=args.poses, seed=args.seed), repeats=max(1, args.repeats))
    print(
        f"batch solve: grid world, {bench.poses} poses, {bench.landmarks} landmarks, "
        f"{bench.observations} observations (best of {args.repeats}, from composed odometry)"
    )
    print(f"{'solver':<28}{'time s':>10}{'iterations':>12}{'final 0.5*chi2':>18}")
    rows = [bench.ours] + ([bench.peer] if bench.peer else [])
    for t in rows:
        print(f"{t.label:<28}{t.seconds:>10.3f}{t.iterations:>12d}{t.final_cost:>18.3f}")
    if bench.peer:
        print(f"ratio online-slam / GTSAM: {bench.ours.seconds / bench.peer.seconds:.2f}x (target <= 2x)")
    else:
        print("GTSAM not installed: pip install '.[peers]' to measure the ratio")
    return 0
