"""argparse types of the values a command's list options take: comma-separated values, yes/no words."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from typing import Any

YES_NO = {"true": True, "on": True, "yes": True, "1": True, "false": False, "off": False, "no": False, "0": False}
"""The words :func:`bools` reads (case aside)."""


def bools(text: str) -> tuple[bool, ...]:
    """A comma-separated list of yes/no values (``true,false``; on/off, yes/no, 1/0 too), e.g. a sweep's
    ``--adapt-noise true,false``."""
    items = [v.strip().lower() for v in text.split(",") if v.strip()]
    if not items or any(v not in YES_NO for v in items):
        raise argparse.ArgumentTypeError(f"expected comma-separated true or false, got {text!r}")
    return tuple(YES_NO[v] for v in items)


def list_of(parse: Callable[[str], Any], kind: str, choices: Sequence[Any] = ()) -> Callable[[str], tuple]:
    """A comma-separated list of values, each read by ``parse`` (``kind`` names them in errors) and, with
    ``choices``, one of them."""

    def read(text: str) -> tuple:
        try:
            items = tuple(parse(v.strip()) for v in text.split(",") if v.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated {kind}s, got {text!r}") from None
        if not items:
            raise argparse.ArgumentTypeError("expected at least one value")
        for item in items:
            if choices and item not in choices:
                raise argparse.ArgumentTypeError(f"{item!r} is not one of {', '.join(map(str, choices))}")
        return items

    return read
