"""``online-slam`` entry point: builds the parser, dispatches, turns package errors into one line.

Every error is one line ``online-slam: error: ...`` on stderr and exit code 2: usage errors (with a "did you
mean" when a close spelling exists and the command's ``--help`` to see), bad input and bad options alike.
Importing it loads no numerical library beyond numpy: the commands import what they run when they run.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from online_slam.cli import compare, convert, inspect, replay, simulate, sweep
from online_slam.errors import OnlineSlamError
from online_slam.options import ADVANCED
from online_slam.sources.worlds import WORLDS
from online_slam.version import __version__
from online_slam.wording import closest, did_you_mean

COMMANDS = {
    "replay": replay,
    "compare": compare,
    "simulate": simulate,
    "convert": convert,
    "inspect": inspect,
    "sweep": sweep,
}
PREFIX = "online-slam: error:"
"""How every error line starts."""


class Parser(argparse.ArgumentParser):
    """A parser whose usage errors are one line with the package's prefix (the usage is one --help away).

    A flag has one spelling: no abbreviations (``--out`` would take ``--output``, and break the day another
    option starts the same way); a misspelt flag gets the closest one suggested instead.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**{"allow_abbrev": False, **kwargs})

    def error(self, message: str) -> NoReturn:
        """Print one line and exit 2 (pointing at ``--help-all`` when the option at fault is an advanced one)."""
        flag = message.split(":", 1)[0].removeprefix("argument ")
        advanced = flag.startswith("--") and flag[2:].replace("-", "_") in ADVANCED
        self.exit(2, f"{PREFIX} {message}; see '{self.prog} {'--help-all' if advanced else '--help'}'\n")

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        """Refuse a value out of the choices with the closest one named (commands: 'unknown command')."""
        if action.choices is None or value in action.choices:
            return
        if isinstance(action, argparse._SubParsersAction):
            hint = did_you_mean(value, action.choices)
            if not hint and (value in WORLDS or Path(value).exists()):
                hint = f" (to replay it: online-slam replay {value})"
            raise argparse.ArgumentError(None, f"unknown command {value!r}{hint}")
        choices = ", ".join(map(str, action.choices))
        raise argparse.ArgumentError(action, f"invalid choice {value!r}{did_you_mean(str(value), choices.split(', '))}"
                                     f"; choose from {choices}")  # fmt: skip


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


def unknown(extras: list[str], parser: argparse.ArgumentParser, commands: dict[str, argparse.ArgumentParser]) -> str:
    """The usage error for arguments no option took: the first unknown option, the commands that have it, or the
    closest spelling."""
    options = [o for o in extras if o.startswith("-") and o != "-"]
    if not options:
        return f"unexpected argument{'s' if len(extras) > 1 else ''}: {' '.join(extras)}"
    given = options[0].split("=", 1)[0]
    owners = [name for name, command in commands.items() if given in _flags(command)]
    if owners:
        named = ", ".join(owners[:-1]) + " and " + owners[-1] if len(owners) > 1 else owners[0]
        return f"{given} is an option of {named}, not of {parser.prog.split()[-1]}"
    close = closest(given, _flags(parser))
    if close is None:
        return f"unknown option {given}"
    advanced = close.removeprefix("--").replace("-", "_") in ADVANCED
    return f"unknown option {given} (did you mean {close}?)" + (
        "; an advanced option: --help-all lists it" if advanced else ""
    )


def _flags(parser: argparse.ArgumentParser) -> list[str]:
    return [s for action in parser._actions for s in action.option_strings if s.startswith("--")]


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line (no command: ``replay``); a usage error exits 2 with one line."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args, extras = parser.parse_known_args(argv)
    if args.command is None:
        args, extras = parser.parse_known_args(["replay", *argv])
    if extras:
        (commands,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        command = commands.choices[args.command]
        command.error(unknown(extras, command, commands.choices))
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 bad input or usage)."""
    args = parse(argv)
    try:
        return int(COMMANDS[args.command].run(args))
    except OnlineSlamError as exc:
        print(f"{PREFIX} {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except KeyboardInterrupt:
        print("online-slam: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
