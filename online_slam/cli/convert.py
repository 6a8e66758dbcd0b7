"""``online-slam convert FORMAT INPUT -o STREAM``: a dataset to stream v1 (or a stream to g2o); ``--map-out MAP``:
its landmark truth (a survey) as a map file, known exactly (zero covariance)."""

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


def _surveyed(events, found: dict):  # noqa: ANN001, ANN202 - a generator filter
    """Pass the events on, keeping each landmark truth's position in ``found`` by id."""
    from online_slam.sources.events import LandmarkTruth

    for event in events:
        if isinstance(event, LandmarkTruth):
            found[event.landmark] = event.position
        yield event


def _write_survey(path: str, found: dict, source: str) -> None:
    """The landmark truth read as a map file (known exactly)."""
    from online_slam.sources.landmark_map import LandmarkMap, write_map

    if not found:
        raise OnlineSlamError(f"--map-out: {source} holds no landmark truth")
    write_map(path, LandmarkMap.of(list(found), list(found.values()), None, source))
    print(f"online-slam convert: wrote a map of {counted(len(found), 'landmark')} to {path}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Convert and write; a one-line summary on stderr. With ``--map-out`` and no ``-o``, only the map."""
    found: dict = {}
    if args.map_out and not args.output:
        events = _surveyed(_opened(args), found)
        for _ in _first_poses(events, args.poses):
            pass
        _write_survey(args.map_out, found, args.input)
        return 0
    output = args.output or "-"
    if args.format == "stream":
        from online_slam.importers.g2o.reader import write_g2o

        if not str(output).endswith(".g2o"):
            raise OnlineSlamError("convert stream: the output must be a .g2o file")
        lines = write_g2o(output, _first_poses(_surveyed(_opened(args), found), args.poses))
    else:
        try:
            lines = write_stream(output, _first_poses(_surveyed(_opened(args), found), args.poses))
        except OSError as exc:
            raise OnlineSlamError(f"{output}: cannot write ({exc.strerror or exc})") from None
    where = "<stdout>" if output == "-" else output
    print(f"online-slam convert: wrote {counted(lines, 'line')} to {where}", file=sys.stderr)
    if args.map_out:
        _write_survey(args.map_out, found, args.input)
    return 0


def _opened(args: argparse.Namespace):  # noqa: ANN202 - the events of a dataset or a stream
    """The input's events (a dataset, read with its options; or a stream)."""
    if args.format == "stream":
        from online_slam.sources.stream import read_stream

        return read_stream(args.input, report_skip if on_error_of(args.on_error, args.input) == "skip" else None)
    if args.on_error == "skip":
        raise OnlineSlamError("convert: --on-error skip applies to stream input; dataset readers stop at a bad record")
    given = {name: getattr(args, name, None) for name in registry.dataset_options()}
    return registry.open_dataset(args.input, args.format, **{k: v for k, v in given.items() if v is not None})
