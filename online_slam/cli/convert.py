"""``online-slam convert FORMAT INPUT -o STREAM``: a dataset to stream v1 (or a stream to g2o)."""

from __future__ import annotations

import argparse
import sys

from online_slam.cli.replay import report_skip
from online_slam.errors import OnlineSlamError
from online_slam.importers import registry
from online_slam.options import add_options, on_error_of
from online_slam.sources.stream import write_stream
from online_slam.wording import counted


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the command."""
    p = sub.add_parser(
        "convert",
        help=f"convert a dataset ({', '.join(registry.names())}) to stream v1, or a stream to g2o",
        description="Convert a dataset to stream v1 (-o X.jsonl[.gz]), or a stream to g2o (FORMAT stream, -o X.g2o). "
        "Formats: " + "; ".join(f"{i.name}: {i.summary}" for i in registry.importers().values()) + ".",
    )
    p.add_argument("format", choices=(*registry.names(), "stream"), help="input format")
    p.add_argument("input", help="dataset file or folder (MRCLAM), or a stream for FORMAT stream")
    p.add_argument("--poses", type=int, help="keep only the first N poses (for shipped excerpts)")
    add_options(p, "convert")


def _first_poses(events, limit: int | None):  # noqa: ANN001, ANN202 - a generator filter
    from online_slam.sources.events import Observation, Odometry, Truth

    poses = 1
    for event in events:
        if limit is not None and isinstance(event, Odometry):
            poses += 1
            if poses > limit:
                return
        if limit is not None and isinstance(event, (Observation, Truth)) and poses > limit:
            return
        yield event


def run(args: argparse.Namespace) -> int:
    """Convert and write; a one-line summary on stderr."""
    output = args.output or "-"
    if args.format == "stream":
        from online_slam.importers.g2o.reader import write_g2o
        from online_slam.sources.stream import read_stream

        if not str(output).endswith(".g2o"):
            raise OnlineSlamError("convert stream: the output must be a .g2o file")
        on_error = report_skip if on_error_of(args.on_error, args.input) == "skip" else None
        lines = write_g2o(output, _first_poses(read_stream(args.input, on_error), args.poses))
    else:
        if args.on_error == "skip":
            raise OnlineSlamError(
                "convert: --on-error skip applies to stream input; dataset readers stop at a bad record"
            )
        given = {name: getattr(args, name, None) for name in registry.dataset_options()}
        events = registry.open_dataset(args.input, args.format, **{k: v for k, v in given.items() if v is not None})
        try:
            lines = write_stream(output, _first_poses(events, args.poses))
        except OSError as exc:
            raise OnlineSlamError(f"{output}: cannot write ({exc.strerror or exc})") from None
    where = "<stdout>" if output == "-" else output
    print(f"online-slam convert: wrote {counted(lines, 'line')} to {where}", file=sys.stderr)
    return 0
