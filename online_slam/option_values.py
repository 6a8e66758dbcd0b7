"""argparse types of the values a command's options take: comma-separated values, yes/no words, numbers > 0."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from typing import Any

YES_NO = {"true": True, "on": True, "yes": True, "1": True, "false": False, "off": False, "no": False, "0": False}
"""The words :func:`yes_no` reads (case aside)."""


def yes_no(text: str) -> bool:
    """One of :data:`YES_NO`'s words (case aside) -> its value; ValueError for any other."""
    try:
        return YES_NO[text.lower()]
    except KeyError:
        raise ValueError(text) from None


def positive(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """``parse``, refusing a value that is not > 0 (an option's ``positive``: told at parsing, for every command
    that takes the option)."""

    def read(text: str) -> Any:
        value = parse(text)
        if not value > 0:
            raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
        return value

    read.__name__ = getattr(parse, "__name__", "value")  # argparse's "invalid float value: 'x'"
    return read


def list_of(parse: Callable[[str], Any], kinds: str, choices: Sequence[Any] = ()) -> Callable[[str], tuple]:
    """A comma-separated list of values, each read by ``parse`` (``kinds`` names them in errors, e.g. ``ints``)
    and, with ``choices``, one of them."""

    def read(text: str) -> tuple:
        parts = [v.strip() for v in text.split(",")]
        if not any(parts):
            raise argparse.ArgumentTypeError("expected at least one value")
        if not all(parts):  # "10,,20": a value left out, not a list of two
            raise argparse.ArgumentTypeError(f"expected comma-separated {kinds}, got an empty item in {text!r}")
        try:
            items = tuple(parse(v) for v in parts)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated {kinds}, got {text!r}") from None
        for item in items:
            if choices and item not in choices:
                raise argparse.ArgumentTypeError(f"{item!r} is not one of {', '.join(map(str, choices))}")
        return items

    return read


bools = list_of(yes_no, "true or false")
"""A comma-separated list of yes/no values (``true,false``; on/off, yes/no, 1/0 too), e.g. a sweep's
``--adapt-noise true,false``."""
