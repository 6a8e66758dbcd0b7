"""``online-slam`` entry point: builds the parser, dispatches, turns package errors into one line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from online_slam import __version__
from online_slam.cli import compare, convert, inspect, replay, simulate, sweep
from online_slam.errors import OnlineSlamError

COMMANDS = {
    "replay": replay,
    "compare": compare,
    "simulate": simulate,
    "convert": convert,
    "inspect": inspect,
    "sweep": sweep,
}


class Parser(argparse.ArgumentParser):
    """A parser whose usage errors are one line with the package's prefix (the usage is one --help away)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"online-slam: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, one sub-command per module."""
    parser = Parser(
        prog="online-slam",
        description="Incremental, online 2D landmark SLAM: replay streams, compare estimators, simulate worlds.",
    )
    parser.add_argument("--version", action="version", version=f"online-slam {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS.values():
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 bad input or usage)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["replay", *(argv or [])])
    try:
        return int(COMMANDS[args.command].run(args))
    except OnlineSlamError as exc:
        print(f"online-slam: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except KeyboardInterrupt:
        print("online-slam: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
