"""Stream format v1 (JSON Lines): a lazy validating reader and a writer that round-trips.

Every line is checked by :class:`~online_slam.sources.validate.EventValidator` (the rules the engine API uses
too); the first bad line raises :class:`~online_slam.errors.InputError` naming ``file:line``, the field and
what was expected. Memory use does not grow with the length of the stream.
"""

from __future__ import annotations

import gzip
import io
import json
import os
import sys
import zlib
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import IO, cast

from online_slam.errors import InputError
from online_slam.sources.events import Event
from online_slam.sources.validate import EventValidator, until_end


def source_name(path: str | Path) -> str:
    """The name used for a source in messages: the path, or ``<stdin>`` for ``-``."""
    return "<stdin>" if str(path) == "-" else str(path)


def _open_text(path: str | Path) -> IO[str]:
    if str(path) == "-":
        return io.TextIOWrapper(sys.stdin.buffer, encoding="utf-8")
    p = Path(path)
    try:
        if p.suffix == ".gz":
            return gzip.open(p, "rt", encoding="utf-8")
        return p.open("r", encoding="utf-8")
    except OSError as exc:
        raise InputError(str(path), 0, "", f"cannot open: {exc.strerror or exc}") from None


def read_stream(
    path: str | Path, on_error: Callable[[InputError], None] | None = None, max_latency: float = 0.0
) -> Iterator[Event]:
    """Read a stream v1 file lazily.

    Args:
        path: A ``.jsonl`` path, a ``.gz`` path, or ``-`` for standard input.
        on_error: None: the first bad line raises. Otherwise each bad line is given to this function and
            skipped (the validator's state is as if the line were absent); data that cannot be read on
            (truncated gzip, bytes that are not UTF-8) still raises.
        max_latency: Seconds a line's time may lie before the newest line's (see
            :class:`~online_slam.sources.validate.EventValidator`); an older line is a
            :class:`~online_slam.errors.LateInput`.

    Yields:
        Events in file order, up to an ``end`` line (not given on: the lines after it are not read).

    Raises:
        InputError: On the first bad line without ``on_error`` (or an unreadable/truncated file).
    """
    name = source_name(path)
    handle = _open_text(path)
    try:
        with handle:
            yield from parse_lines(name, _file_lines(name, handle), on_error, max_latency)
    finally:
        handle.close()


def _file_lines(name: str, handle: IO[str]) -> Iterator[str]:
    """A text file's lines; data that cannot be read on raises (naming the line it would have been)."""
    number = 0
    while True:
        try:
            line = handle.readline()
        except (EOFError, OSError, zlib.error) as exc:
            raise InputError(name, number + 1, "", f"truncated or corrupt gzip data ({exc})") from None
        except UnicodeDecodeError as exc:
            raise InputError(name, number + 1, "", f"not UTF-8 text ({exc.reason})") from None
        if not line:
            return
        number += 1
        yield line


def parse_lines(
    name: str,
    lines: Iterable[str | InputError],
    on_error: Callable[[InputError], None] | None = None,
    max_latency: float = 0.0,
) -> Iterator[Event]:
    """Stream-v1 lines as validated events, up to an ``end`` line (see :func:`read_stream` for the arguments).

    Args:
        lines: The lines in order, numbered from 1; an :class:`InputError` in their place is a line that could not
            be read (a live source's cut line), raised or skipped as a bad line is.
    """
    validator = EventValidator(name, max_latency=max_latency)

    def parse(line: str | InputError, number: int) -> Event | None:
        if isinstance(line, InputError):
            raise InputError(name, number, line.field, line.message)
        return validator.parse_line(line, number) if line.strip() else None

    return until_end(parse, lines, on_error)


def write_stream(destination: str | Path | IO[str], events: Iterable[Event]) -> int:
    """Write events as stream v1.

    Args:
        destination: A path (``.gz`` compresses), ``-`` for standard output, or an open text file.
        events: Events to write, in order.

    Returns:
        Number of lines written.

    A path is written whole or not at all: the lines go to ``<path>.part`` first, renamed to the path at the
    end; if reading the events fails (a missing or bad input file), the partial file is removed and an existing
    file at the path is left as it was.
    """
    if hasattr(destination, "write"):
        return _write_lines(cast("IO[str]", destination), events)  # it has write: an open text file
    if str(destination) == "-":
        return _write_lines(sys.stdout, events)
    p = Path(destination)
    part = p.with_name(p.name + ".part")
    opener = gzip.open if p.suffix == ".gz" else open
    try:
        with opener(part, "wt", encoding="utf-8") as handle:
            count = _write_lines(handle, events)
        os.replace(part, p)  # onto a folder: IsADirectoryError, and the partial file goes too
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    return count


def _write_lines(handle: IO[str], events: Iterable[Event]) -> int:
    count = 0
    for event in events:
        handle.write(json.dumps(event.to_record(), allow_nan=False, separators=(", ", ": ")))
        handle.write("\n")
        count += 1
    return count
