"""``online-slam simulate WORLD -o FILE``: write a built-in world as a stream-v1 file."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from online_slam.errors import OnlineSlamError
from online_slam.sources.stream import write_stream
from online_slam.sources.worlds import (
    WORLDS,
    Contamination,
    GridConfig,
    contaminate,
    grid_world,
    square_world,
    without_ids,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "simulate",
        help="write a simulated world as a stream file",
        description="Write a built-in world as stream v1 (truth included). Grid options apply to 'grid'.",
    )
    p.add_argument("world", choices=sorted(WORLDS), help="square (the article's) or grid")
    p.add_argument("-o", "--output", default="-", help="output path (.gz compresses; '-' for stdout, the default)")
    p.add_argument("--seed", type=int, help="random seed (square: 1616, grid: 7)")
    g = GridConfig()
    p.add_argument("--poses", type=int, default=g.poses, help=f"grid: number of poses (default {g.poses})")
    p.add_argument("--landmarks", type=int, default=g.landmarks, help=f"grid: landmarks (default {g.landmarks})")
    p.add_argument("--blocks", type=int, default=g.blocks, help=f"grid: blocks per side (default {g.blocks})")
    p.add_argument(
        "--block-size", type=float, default=g.block_size, help=f"grid: block edge m (default {g.block_size})"
    )
    p.add_argument("--step", type=float, default=g.step, help=f"grid: metres per pose (default {g.step})")
    p.add_argument(
        "--sensor-range",
        type=float,
        default=g.sensor_range,
        help=f"grid: range limit m (default {g.sensor_range})",
    )
    p.add_argument(
        "--odometry-sigma", type=float, nargs=3, default=g.odometry_sigma, metavar=("SX", "SY", "STH"),
        help="grid: odometry noise (m, m, rad)",
    )  # fmt: skip
    p.add_argument("--wrong-ids", type=float, default=0.0, metavar="F", help="fraction of sightings given a wrong id")
    p.add_argument(
        "--range-spikes", type=float, default=0.0, metavar="F", help="fraction of sightings with a range spike"
    )
    p.add_argument(
        "--clutter", type=float, default=0.0, metavar="F", help="sightings of non-existent landmarks, per real sighting"
    )
    p.add_argument("--outlier-seed", type=int, default=0, help="seed of the outlier draws (default 0)")
    p.add_argument(
        "--no-ids", action="store_true", help="write sightings without landmark ids (unknown data association)"
    )
    p.add_argument(
        "--sensor-sigma", type=float, nargs=2, default=g.sensor_sigma, metavar=("SR", "SB"),
        help="grid: range (m) and bearing (rad) noise",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Simulate and write; prints a one-line summary on stderr."""
    if args.world == "square":
        events = square_world(1616 if args.seed is None else args.seed)
    else:
        config = GridConfig(
            poses=args.poses,
            landmarks=args.landmarks,
            blocks=args.blocks,
            block_size=args.block_size,
            step=args.step,
            sensor_range=args.sensor_range,
            odometry_sigma=tuple(args.odometry_sigma),
            sensor_sigma=tuple(args.sensor_sigma),
            seed=7 if args.seed is None else args.seed,
        )
        values = [*config.odometry_sigma, *config.sensor_sigma]
        if min(values) <= 0 or not np.all(np.isfinite(values)) or config.landmarks < 1 or config.sensor_range <= 0:
            raise OnlineSlamError("simulate: noise sigmas, sensor range and landmark count must be positive")
        events = grid_world(config)
    try:
        contamination = Contamination(args.wrong_ids, args.range_spikes, args.clutter, args.outlier_seed)
    except ValueError as exc:
        raise OnlineSlamError(f"simulate: {exc}") from None
    if contamination.any:
        events = contaminate(events, contamination)
    if args.no_ids:
        events = without_ids(events)
    try:
        lines = write_stream(args.output, events)
    except ValueError as exc:
        raise OnlineSlamError(f"simulate: {exc}") from None
    except OSError as exc:
        raise OnlineSlamError(f"{args.output}: cannot write ({exc.strerror or exc})") from None
    print(f"online-slam simulate: wrote {lines} lines to {'<stdout>' if args.output == '-' else args.output}",
          file=sys.stderr)  # fmt: skip
    return 0
