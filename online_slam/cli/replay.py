"""``online-slam replay [SOURCE]``: run the estimators over a stream and print the table."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

from online_slam.errors import InputError, OnlineSlamError
from online_slam.estimators.batch import BatchConfig
from online_slam.estimators.ekf import EkfConfig
from online_slam.estimators.landmark_book import ASSOCIATION_CHOICES, AssociationConfig
from online_slam.estimators.presets import robust_settings
from online_slam.estimators.smoother import SmootherConfig
from online_slam.factors.robust import RobustLoss
from online_slam.frontend.steps import FrontEndConfig, KeyframeConfig
from online_slam.importers.detect import DATASET_FORMATS, NOISE_HELP
from online_slam.pipeline import ESTIMATORS, Checkpointing, ReplayConfig, replay
from online_slam.reports.table import format_results
from online_slam.sinks.live import Pacer, Progress
from online_slam.solvers.least_squares import SolverConfig


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "replay",
        help="replay a stream (file, '-' or built-in world) through the estimators",
        description="Replay a stream step by step through the estimators and compare them with the truth.",
    )
    add_options(p)
    p.add_argument("--window", type=int, default=SmootherConfig.window, help="smoother: poses kept in the window (W)")
    p.add_argument(
        "--relinearize-every",
        type=int,
        default=SmootherConfig.relinearize_every,
        metavar="K",
        help="smoother: relinearize and solve every K steps (default 1)",
    )
    p.add_argument("--rrd", metavar="PATH", help="log every step to a Rerun recording (.rrd) for the Rerun viewer")
    p.add_argument(
        "--connect",
        nargs="?",
        const="default",
        metavar="ADDR",
        help="stream to a running Rerun viewer (default address, or a rerun+http:// URL)",
    )
    p.add_argument(
        "--tum",
        metavar="DIR",
        help="write TUM trajectory files for evo (truth, odometry, each estimator final and _online) in the "
        "table's frame",
    )
    p.add_argument(
        "--checkpoint",
        metavar="DIR",
        help="save the whole replay state to DIR/replay.ckpt every --checkpoint-every steps (atomically)",
    )
    p.add_argument("--checkpoint-every", type=int, default=100, metavar="N", help="steps between checkpoints (100)")
    p.add_argument(
        "--resume",
        metavar="DIR",
        help="continue from DIR's checkpoint: same SOURCE and options; the figures equal an uninterrupted run's",
    )
    p.add_argument(
        "--rate",
        type=float,
        metavar="R",
        help="pace the replay at R times the stream's clock (default: as fast as possible)",
    )


def add_options(p: argparse.ArgumentParser) -> None:
    """The options shared by replay and compare: source, output, front-end and estimator settings."""
    p.add_argument("source", nargs="?", default="square", help="stream file (.jsonl/.gz), '-', or world (square, grid)")
    p.add_argument("--json", metavar="PATH", help="write the results as JSON ('-': stdout, the table then on stderr)")
    p.add_argument(
        "--estimators",
        default=",".join(ESTIMATORS),
        help=f"comma-separated estimators to run (default and choices: {','.join(ESTIMATORS)})",
    )
    p.add_argument(
        "--first-observation-only",
        action="store_true",
        help="keep only the first observation of each landmark (the article's ablation)",
    )
    p.add_argument("--align", choices=("anchor", "se2"), default="anchor", help="frame for errors (default anchor)")
    p.add_argument("--keyframe-distance", type=float, metavar="M", help="merge observation-free steps up to M metres")
    p.add_argument("--keyframe-angle", type=float, metavar="RAD", help="... and up to RAD radians")
    p.add_argument("--keyframe-time", type=float, metavar="S", help="... and up to S seconds")
    p.add_argument("--max-iterations", type=int, default=SolverConfig.max_iterations, help="batch solver limit")
    p.add_argument(
        "--gate-probability",
        type=float,
        default=EkfConfig.gate_probability,
        metavar="P",
        help=f"EKF chi-square gate on each observation's NIS, 2 dof (default {EkfConfig.gate_probability}; 1 = off)",
    )
    p.add_argument(
        "--gate-persistence",
        type=int,
        default=EkfConfig.gate_persistence,
        metavar="N",
        help="EKF: use a landmark's sighting after N-1 gated ones in a row (the filter drifted; default "
        f"{EkfConfig.gate_persistence}; 0 = always reject)",
    )
    p.add_argument(
        "--robust",
        choices=("auto", "none", "huber", "cauchy"),
        default="auto",
        help="outliers: auto (default: smoother least squares with a Cauchy tail beyond 5.3 sigmas, outliers judged at "
        "marginalization; batch plain "
        "least squares unless its residuals show outliers, then a robust pass); none (plain least squares); "
        "huber/cauchy (that loss, --robust-scale, for the smoother and the batch)",
    )
    p.add_argument(
        "--robust-scale", type=float, default=RobustLoss.scale, help="huber/cauchy threshold in sigmas (default 1.345)"
    )
    p.add_argument(
        "--ekf-update",
        choices=("joint", "sequential"),
        default=EkfConfig.update,
        help="EKF: one update per step with all observations (joint, default) or one per observation",
    )
    p.add_argument(
        "--batch-init",
        choices=("auto", "odometry", "ekf", "smoother"),
        default="auto",
        help="start the batch solver from composed odometry or an online estimator's final estimate (default auto: "
        "the smoother's if it runs, else the EKF's, else odometry)",
    )
    p.add_argument(
        "--window-distance",
        type=float,
        default=SmootherConfig.window_distance,
        metavar="M",
        help="smoother: keep poses beyond W until the window's path is M metres long, up to --window-max poses "
        f"(a window sized by motion; default {SmootherConfig.window_distance:g}; 0 = exactly W poses)",
    )
    p.add_argument(
        "--window-max",
        type=int,
        default=SmootherConfig.window_max,
        metavar="N",
        help=f"smoother: most poses the window keeps for --window-distance (default {SmootherConfig.window_max})",
    )
    p.add_argument(
        "--global-every",
        type=int,
        default=SmootherConfig.global_every,
        metavar="N",
        help="smoother: re-solve the whole history from the current estimate every N steps and re-anchor the "
        f"marginal prior there (default {SmootherConfig.global_every}; 0 = never)",
    )
    p.add_argument(
        "--global-delay",
        type=int,
        default=SmootherConfig.global_delay,
        metavar="D",
        help="smoother: run each global relinearization in a background thread and hand its result over D steps "
        f"later, or N/50 steps after step N if longer (deterministic; default {SmootherConfig.global_delay}; "
        "0 = solve at once, inside the step)",
    )
    p.add_argument(
        "--global-information-max",
        type=int,
        default=SmootherConfig.global_information_max,
        metavar="L",
        help="smoother: at each re-anchoring also relinearize the prior's covariance (the history's exact marginal) "
        f"while it holds at most L landmarks (default {SmootherConfig.global_information_max}: never)",
    )
    p.add_argument(
        "--association",
        choices=("auto", *ASSOCIATION_CHOICES),
        default="auto",
        help="data association: known (the stream's ids), nn (nearest neighbour) or jcbb (joint compatibility) - "
        "each online estimator against its own belief, new landmarks tentative until confirmed, the stream's ids "
        "only score it; default auto: known when the first sighting has an id, else jcbb",
    )
    p.add_argument(
        "--new-density",
        type=float,
        default=AssociationConfig.new_density,
        metavar="D",
        help="nn/jcbb: a pairing less likely than a sighting of an unmapped landmark at D per m^2 starts a new "
        "landmark instead (default 0: off; see the README for what it does on MRCLAM and Victoria Park)",
    )
    p.add_argument("--format", choices=DATASET_FORMATS, help="dataset format (default: detected)")
    p.add_argument("--robot", type=int, help="MRCLAM: robot number 1..5")
    p.add_argument("--noise", choices=("builtin", "fit"), help=NOISE_HELP)
    p.add_argument("--truth", metavar="PATH", help="GTSAM/iSAM text: the noise-free twin file (truth)")
    p.add_argument("--dt", type=float, help="synthetic seconds per pose for files without timestamps (default 1)")
    p.add_argument(
        "--convention", choices=("gtsam", "isam"), help="GTSAM/iSAM text noise convention (default: detected)"
    )
    add_on_error(p)
    p.add_argument("--quiet", action="store_true", help="print no table and no progress")


def add_on_error(p: argparse.ArgumentParser) -> None:
    """``--on-error``, shared by replay, compare and convert."""
    p.add_argument(
        "--on-error",
        choices=("stop", "skip"),
        help="a bad line of a stream: stop there (default for files) or report it on stderr and skip it "
        "(default for stdin: a live stream goes on)",
    )


def on_error_of(args: argparse.Namespace, source: str) -> str:
    """The ``--on-error`` policy asked for, or the default for this source (skip for stdin, else stop)."""
    return args.on_error or ("skip" if str(source) == "-" else "stop")


def report_skip(error: InputError) -> None:
    """Tell the user about one skipped line, once, on stderr."""
    print(f"online-slam: skipped {error}", file=sys.stderr)


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
    names = tuple(n.strip() for n in args.estimators.split(",") if n.strip())
    if args.dt is not None and not args.dt > 0.0:
        raise OnlineSlamError(f"--dt: seconds per pose must be > 0, got {args.dt}")
    if not args.robust_scale > 0.0:
        raise OnlineSlamError(f"--robust-scale: must be > 0 sigmas, got {args.robust_scale}")
    try:
        keyframing = None
        if any(v is not None for v in (args.keyframe_distance, args.keyframe_angle, args.keyframe_time)):
            defaults = KeyframeConfig()
            keyframing = KeyframeConfig(
                max_distance=args.keyframe_distance if args.keyframe_distance is not None else defaults.max_distance,
                max_angle=args.keyframe_angle if args.keyframe_angle is not None else defaults.max_angle,
                max_time=args.keyframe_time if args.keyframe_time is not None else math.inf,
            )
        association = AssociationConfig(new_density=args.new_density)
        ekf = EkfConfig(
            gate_probability=args.gate_probability,
            gate_persistence=args.gate_persistence,
            update=args.ekf_update,
            association=association,
        )
        window = getattr(args, "window", SmootherConfig.window)  # compare sets W and K lists of its own
        every = getattr(args, "relinearize_every", SmootherConfig.relinearize_every)
        smoother, batch = robust_settings(
            args.robust,
            args.robust_scale,
            SmootherConfig(
                window=window,
                relinearize_every=every,
                global_every=args.global_every,
                global_delay=args.global_delay,
                global_information_max=args.global_information_max,
                window_distance=args.window_distance,
                window_max=args.window_max,
                association=association,
            ),
            BatchConfig(solver=SolverConfig(max_iterations=args.max_iterations), initial=args.batch_init),
        )
    except ValueError as exc:
        raise OnlineSlamError(f"replay: {exc}") from None
    return ReplayConfig(
        estimators=names,
        frontend=FrontEndConfig(keyframing=keyframing, first_observation_only=args.first_observation_only),
        ekf=ekf,
        smoother=smoother,
        batch=batch,
        dataset={
            "format": args.format,
            "robot": args.robot,
            "noise": args.noise,
            "truth": args.truth,
            "dt": args.dt,
            "convention": args.convention,
        },
        alignment=args.align,
        association=args.association,
        on_error=on_error_of(args, args.source),
    )


def sinks_from(args: argparse.Namespace, config: ReplayConfig) -> list:
    """Progress bar, pacing and Rerun logging, as the options ask."""
    sinks: list = []
    if getattr(args, "rate", None) is not None:
        try:
            sinks.append(Pacer(args.rate))
        except ValueError as exc:
            raise OnlineSlamError(f"--rate: {exc}") from None
    if args.rrd or args.connect:
        from online_slam.pipeline import estimator_names
        from online_slam.sinks.recording import Layout, RerunConfig, RerunSink

        name = "<stdin>" if args.source == "-" else str(args.source)
        layout = Layout(*estimator_names(config))
        sinks.append(RerunSink(RerunConfig(path=args.rrd, connect=args.connect), name, layout))
    if not args.quiet:
        sinks.append(Progress())
    return sinks


def run(args: argparse.Namespace) -> int:
    """Replay, print the table, write JSON; exit 2 if the input turned bad part-way."""
    config = config_from(args)
    check_outputs(args.json, args.tum)
    if args.rrd and not str(args.rrd).endswith(".rrd"):
        raise OnlineSlamError(f"--rrd: expected a path ending in .rrd, got {args.rrd!r}")
    if args.resume and (args.rrd or args.connect):
        raise OnlineSlamError("--resume: a Rerun recording cannot be continued; resume without --rrd/--connect")
    if args.checkpoint:
        check_folder("--checkpoint", args.checkpoint)
    checkpoint = Checkpointing(Path(args.checkpoint), args.checkpoint_every) if args.checkpoint else None
    sinks = sinks_from(args, config)
    results = replay(args.source, config, sinks=sinks, on_skip=report_skip, checkpoint=checkpoint, resume=args.resume)
    if not args.quiet:  # with --json - stdout is the JSON's: the table goes to stderr
        print(format_results(results), file=sys.stderr if args.json == "-" else sys.stdout)
    if args.json:
        write_json(args.json, results.to_json())
    if args.tum:
        from online_slam.sinks.tum import write_tum

        write_tum(args.tum, results)
    failures = [results.error] + [getattr(sink, "error", None) for sink in sinks]
    for failure in filter(None, failures):
        print(f"online-slam: error: {failure}", file=sys.stderr)
    return 2 if any(failures) else 0
