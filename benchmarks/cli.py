"""``python -m benchmarks``: the options, the choice of sections, and one-line errors."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from benchmarks.sections import DEFAULT_SECTIONS, MRCLAM_SECTIONS, SECTIONS
from online_slam.errors import OnlineSlamError
from online_slam.sources.worlds import GridConfig


def build_parser() -> argparse.ArgumentParser:
    """The benchmarks' argument parser."""
    p = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Measure online-slam beside peers (filterpy, GTSAM with the 'peers' extra) in the same run, "
        "and print figures and ratios. Run from the repository root.",
    )
    p.add_argument("--poses", type=int, default=GridConfig.poses, help="poses of the grid world (default 2000)")
    p.add_argument("--seed", type=int, default=GridConfig.seed, help="seed of the grid world")
    p.add_argument(
        "--repeats",
        type=int,
        default=None,
        help="timed repeats of each measurement; the best counts (default 3, 5 for the library API overhead)",
    )
    p.add_argument(
        "--landmarks",
        default="50,200,500,1000",
        help="map sizes for the EKF update benchmark (default 50,200,500,1000)",
    )
    p.add_argument("--windows", default="10,20,50", help="smoother window sizes to time (default 10,20,50)")
    p.add_argument(
        "--only",
        default=",".join(DEFAULT_SECTIONS),
        help=f"sections to run, of {', '.join(SECTIONS)} (default: {','.join(DEFAULT_SECTIONS)}; "
        "'soak' runs 100,000 poses, minutes)",
    )
    p.add_argument(
        "--recording-source",
        metavar="SOURCE",
        help="recording: the stream to compare with and without --rrd (default: the shipped MRCLAM robot 1 stream)",
    )
    p.add_argument("--fuzz-cases", type=int, default=2500, help="fuzz: cases per property (4 properties; 2500)")
    p.add_argument("--circle-runs", type=int, default=100, help="circle: Monte Carlo runs (esde's 100)")
    p.add_argument("--timing-seeds", type=int, default=12, help="timing: seeded worlds per comparison (12)")
    p.add_argument(
        "--wrong-ids",
        default="0.05,0.1,0.2",
        help="robust: fractions of sightings given a wrong id, each beside the clean stream (default 0.05,0.1,0.2)",
    )
    p.add_argument("--scans", type=int, default=20, help="association: random scans per map and scan size (20)")
    p.add_argument(
        "--workers", type=int, default=None, help="circle, heldout: processes for the runs (default: all cores)"
    )
    p.add_argument("--soak-poses", type=int, default=100_000, help="soak: poses of the long stream (100,000)")
    p.add_argument(
        "--record",
        action="store_true",
        help="measure the baseline (every estimator on the built-in worlds and replay/'s streams, iSAM2 beside; the "
        "live input's cost per step) and write benchmarks/baseline.json and RESULTS.md's table of current figures",
    )
    p.add_argument(
        "--gate",
        action="store_true",
        help="measure the baseline again and exit 1 if a figure moved beyond benchmarks/baseline.json's tolerances",
    )
    p.add_argument(
        "--mrclam",
        metavar="PATH",
        default=SHARED_MRCLAM if (Path(SHARED_MRCLAM) / "Barcodes.dat").is_file() else None,
        help="mrclam, sweep, heldout: the MRCLAM Dataset 6 folder (not shipped with the repository; default "
        f"{SHARED_MRCLAM} when it is there)",
    )
    return p


SHARED_MRCLAM = "../shared/data/MRCLAM_Dataset6"
"""Where the project's machines keep MRCLAM Dataset 6 (the folder's default)."""


def chosen_sections(args: argparse.Namespace) -> list[str]:
    """The sections ``--only`` names, in run order; checks the MRCLAM folder up front when one of them needs it."""
    chosen = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = sorted(set(chosen) - set(SECTIONS))
    if unknown:
        raise OnlineSlamError(f"--only: unknown section {unknown[0]!r}; expected some of {', '.join(SECTIONS)}")
    needs = [s for s in MRCLAM_SECTIONS if s in chosen]
    if needs and args.mrclam is None:
        raise OnlineSlamError(f"{needs[0]}: give --mrclam PATH, the MRCLAM Dataset 6 folder (it holds Barcodes.dat)")
    if needs and not (Path(args.mrclam) / "Barcodes.dat").is_file():
        raise OnlineSlamError(f"--mrclam: no MRCLAM Dataset 6 folder at {args.mrclam} (no Barcodes.dat there)")
    return [s for s in SECTIONS if s in chosen]


def run_baseline(args: argparse.Namespace) -> int:
    """``--record``: measure and write the baseline; ``--gate``: measure and compare (1 if something moved)."""
    from benchmarks import baseline, results_page

    if args.record and args.gate:
        raise OnlineSlamError("--record and --gate: give one")
    if args.gate and not baseline.BASELINE.is_file():
        raise OnlineSlamError(f"--gate: no baseline at {baseline.BASELINE} (record one with --record)")
    rows = baseline.measure()
    live_ms = baseline.measure_live()
    if args.record:
        document = baseline.record(rows, live_ms=live_ms)
        results_page.update(document)
        print(f"wrote {baseline.BASELINE} ({len(rows)} rows) and the table in {results_page.RESULTS}")
        return 0
    failures = baseline.gate(baseline.read(), rows, live_ms)
    for line in failures:
        print(f"moved: {line}")
    print(f"gate: {'FAILED' if failures else 'passed'} ({len(rows)} rows against {baseline.BASELINE.name})")
    return 1 if failures else 0


def run(args: argparse.Namespace) -> int:
    """Run the selected sections, a blank line between their tables (or the baseline, with --record/--gate)."""
    if args.record or args.gate:
        return run_baseline(args)
    world = GridConfig(poses=args.poses, seed=args.seed)
    for k, section in enumerate(chosen_sections(args)):
        if k:
            print()
        SECTIONS[section](args, world)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Parse, run; returns the exit code (0 ok, 1 the gate failed, 2 bad input or usage, 130 interrupted)."""
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except OnlineSlamError as exc:
        print(f"benchmarks: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("benchmarks: interrupted", file=sys.stderr)
        return 130
