"""``online-slam simulate WORLD -o FILE``: write a built-in world as a stream-v1 file."""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import replace
from typing import Any

import numpy as np

from online_slam.errors import OnlineSlamError
from online_slam.models.observation import MODEL_NAMES
from online_slam.options import add_options, readable
from online_slam.sources.stream import write_stream
from online_slam.sources.timing import TimingConfig, timing_world
from online_slam.sources.worlds import (
    CIRCLE_WORLDS,
    WORLDS,
    Contamination,
    GridConfig,
    WaypointConfig,
    contaminate,
    grid_world,
    waypoint_world,
    without_ids,
)
from online_slam.wording import counted


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "simulate",
        help="write a simulated world as a stream file",
        description="Write a built-in world as stream v1 (truth included). Options name the worlds they apply to.",
    )
    worlds = "; ".join(f"{name}: {world.description}" for name, world in WORLDS.items())
    p.add_argument("world", choices=list(WORLDS), help=worlds)
    seeds = ", ".join(f"{name} {world.seed}" for name, world in WORLDS.items())
    p.add_argument("--seed", type=int, help=f"random seed (default: {seeds})")
    g, w = GridConfig(), WaypointConfig()

    def both(flag: str, field: str, what: str, units: tuple[str, ...] = (), **kw: object) -> None:
        shown = (_shown(getattr(g, field), units), _shown(getattr(w, field), units))
        p.add_argument(flag, default=None, help=f"grid, waypoint: {what} (default {shown[0]}; {shown[1]})", **kw)

    both("--poses", "poses", "number of poses", type=int)
    both("--landmarks", "landmarks", "landmarks", type=int)
    both("--step", "step", "metres per pose", type=float)
    both("--sensor-range", "sensor_range", "range limit m", type=float)
    both("--odometry-sigma", "odometry_sigma", "odometry noise", ("m", "m", "rad"), type=float, nargs=3,
         metavar=("SX", "SY", "STH"))  # fmt: skip
    both("--sensor-sigma", "sensor_sigma", "range and bearing noise (--model xy: dx and dy noise, m, default "
         f"{g.xy_sigma[0]:g} each)", ("m", "rad"), type=float, nargs=2, metavar=("SR", "SB"))  # fmt: skip
    p.add_argument("--model", choices=MODEL_NAMES, default=None,
                   help=f"grid, waypoint, circle: what a sighting measures: range and bearing, or xy, the landmark's "
                   f"position in the robot frame (default {g.model}; circle: xy, and range-bearing is the world "
                   "circle-rb)")  # fmt: skip
    p.add_argument("--blocks", type=int, default=g.blocks, help=f"grid: blocks per side (default {g.blocks})")
    p.add_argument(
        "--block-size", type=float, default=g.block_size, help=f"grid: block edge m (default {g.block_size})"
    )
    p.add_argument("--size", type=float, default=w.size, help=f"waypoint: field edge m (default {w.size:g})")
    p.add_argument(
        "--max-turn", type=float, default=w.max_turn, help=f"waypoint: most turn per pose, rad (default {w.max_turn})"
    )
    p.add_argument(
        "--min-range", type=float, default=w.min_range, help=f"waypoint: blind zone, m (default {w.min_range})"
    )
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
    p.add_argument("--delay", type=float, default=0.0, metavar="S",
                   help="timing: each sighting line arrives up to S seconds late (uniform): lines in arrival order, "
                   "to replay with --max-latency")  # fmt: skip
    add_options(p, "simulate")


def _shown(value: object, units: tuple[str, ...]) -> str:
    """A world setting for help, angles in degrees too (a bearing sigma reads ``0.00872665 rad (0.5 deg)``)."""
    if isinstance(value, tuple):
        return ", ".join(readable(v, u) for v, u in zip(value, units))
    return readable(value)


def run(args: argparse.Namespace) -> int:
    """Simulate and write; prints a one-line summary on stderr."""
    output = args.output or "-"
    if args.world == "circle" and args.model is not None:
        args = argparse.Namespace(**{**vars(args), "world": CIRCLE_WORLDS[args.model], "model": None})
    for flag, value in (("--seed", args.seed), ("--outlier-seed", args.outlier_seed)):
        if value is not None and value < 0:
            raise OnlineSlamError(f"simulate: {flag}: expected an integer >= 0, got {value}")
    if args.delay and args.world != "timing" or not 0.0 <= args.delay < math.inf:
        raise OnlineSlamError("simulate: --delay is the timing world's, seconds >= 0")
    if args.world not in ("grid", "waypoint"):
        shaped = ("poses", "landmarks", "step", "sensor_range", "odometry_sigma", "sensor_sigma", "model")
        given = [name for name in shaped if getattr(args, name) is not None]
        if given:
            flag = "--" + given[0].replace("_", "-")
            fixed = "the article's fixed world" if args.world == "square" else "a fixed world"
            raise OnlineSlamError(f"simulate: {flag} shapes the grid and waypoint worlds; {args.world} is {fixed}")
        if args.delay:
            events = timing_world(TimingConfig(seed=WORLDS["timing"].seed if args.seed is None else args.seed,
                                               delay=args.delay))  # fmt: skip
        else:
            events = WORLDS[args.world].events(args.seed)
    else:
        base: GridConfig | WaypointConfig = GridConfig() if args.world == "grid" else WaypointConfig()
        shape: dict[str, Any] = {
            k: tuple(v) if isinstance(v, list) else v
            for k, v in {
                "poses": args.poses,
                "landmarks": args.landmarks,
                "step": args.step,
                "sensor_range": args.sensor_range,
                "odometry_sigma": args.odometry_sigma,
                "xy_sigma" if args.model == "xy" else "sensor_sigma": args.sensor_sigma,
                "model": args.model,
                "seed": args.seed,
            }.items()
            if v is not None
        }
        try:  # a config checks its own values (poses >= 2, landmarks >= 1, a known model)
            if isinstance(base, GridConfig):
                config: GridConfig | WaypointConfig = replace(
                    base, blocks=args.blocks, block_size=args.block_size, **shape
                )
            else:
                config = replace(base, size=args.size, max_turn=args.max_turn, min_range=args.min_range, **shape)
        except ValueError as exc:
            raise OnlineSlamError(f"simulate: {exc}") from None
        values = [*config.odometry_sigma, *config.sensor_sigma, *config.xy_sigma]
        if min(values) <= 0 or not np.all(np.isfinite(values)) or config.sensor_range <= 0:
            raise OnlineSlamError("simulate: noise sigmas and sensor range must be positive")
        try:
            events = grid_world(config) if isinstance(config, GridConfig) else waypoint_world(config)
            first = next(events)  # the world's own checks run on the first draw
        except ValueError as exc:
            raise OnlineSlamError(f"simulate: {exc}") from None
        events = itertools.chain([first], events)
    try:
        contamination = Contamination(args.wrong_ids, args.range_spikes, args.clutter, args.outlier_seed)
    except ValueError as exc:
        raise OnlineSlamError(f"simulate: {exc}") from None
    if contamination.any:
        events = contaminate(events, contamination)
    if args.no_ids:
        events = without_ids(events)
    try:
        lines = write_stream(output, events)
    except ValueError as exc:
        raise OnlineSlamError(f"simulate: {exc}") from None
    except OSError as exc:
        raise OnlineSlamError(f"{output}: cannot write ({exc.strerror or exc})") from None
    print(f"online-slam simulate: wrote {counted(lines, 'line')} to {'<stdout>' if output == '-' else output}",
          file=sys.stderr)  # fmt: skip
    return 0
