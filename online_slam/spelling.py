"""Suggestions for misspelt names (options, commands, worlds): the closest known spelling, case ignored."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def did_you_mean(given: str, known: Iterable[str]) -> str:
    """`` (did you mean X?)`` for the known spelling closest to ``given``, or an empty string when none is close."""
    by_lower = {k.lower(): k for k in known}
    close = difflib.get_close_matches(given.lower(), list(by_lower), n=1, cutoff=0.6)
    return f" (did you mean {by_lower[close[0]]}?)" if close else ""
