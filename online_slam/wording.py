"""How names and counts read: the closest known spelling of a misspelt name, and a count with its noun."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def closest(given: str, known: Iterable[str]) -> str | None:
    """The known spelling closest to ``given``, or None when none is close.

    A name that ``given`` begins (``--out`` for ``--output``; the shortest such) comes first, then the most
    similar one.
    """
    by_lower = {k.lower(): k for k in known}
    lower = given.lower()
    started = sorted((k for k in by_lower if k.startswith(lower) and k != lower), key=len)
    close = started or difflib.get_close_matches(lower, list(by_lower), n=1, cutoff=0.6)
    return by_lower[close[0]] if close else None


def did_you_mean(given: str, known: Iterable[str]) -> str:
    """`` (did you mean X?)`` for :func:`closest`'s spelling, or an empty string when none is close."""
    close = closest(given, known)
    return f" (did you mean {close}?)" if close is not None else ""


def counted(n: int, noun: str) -> str:
    """``1 pose``, ``2 poses``: a count with its noun in the right number (nouns taking an ``s``)."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"
