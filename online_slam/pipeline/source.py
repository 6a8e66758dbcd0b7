"""Opening a replay's source: a world, a file, stdin or an iterable, as validated events; bad lines skipped and
counted (``on_error="skip"``); the association method chosen (``auto``: by the stream's first sighting)."""

from __future__ import annotations

import functools
import gzip
import itertools
import zlib
from collections.abc import Callable, Iterable, Iterator, Sized
from dataclasses import dataclass
from pathlib import Path

from online_slam.errors import InputError, LateInput
from online_slam.frontend.steps import STDIN_LATENCY
from online_slam.importers import registry
from online_slam.importers.resolve import open_source
from online_slam.pipeline.config import ReplayConfig
from online_slam.sources.address import is_live
from online_slam.sources.events import Event, Observation, Scan
from online_slam.sources.validate import validate_events
from online_slam.sources.worlds import WORLDS


class SkippedLines:
    """Bad lines skipped so far (``on_error="skip"``): counted by reason, and told to a callback as they come."""

    def __init__(self, on_skip: Callable[[InputError], None] | None = None) -> None:
        self.by_reason: dict[str, int] = {}
        """Lines skipped, by reason."""
        self.muted = False
        """While True, skipped lines are neither counted nor told (a resumed replay reading again what its
        checkpoint had consumed: counted before the checkpoint was written)."""
        self._on_skip = on_skip

    def __call__(self, error: InputError) -> None:
        if self.muted:
            return
        self.by_reason[error.reason] = self.by_reason.get(error.reason, 0) + 1
        if self._on_skip is not None:
            self._on_skip(error)


@dataclass(frozen=True, eq=False)
class OpenedSource:
    """A source opened for a replay (read lazily: opening reads at most up to its first sighting)."""

    name: str
    """Its name for reports and checkpoints (the path, ``<stdin>``, the world, ``<events>`` or the given name)."""
    events: Iterator[Event]
    """Its events, validated, from the first."""
    association: str
    """How the replay associates sightings: ``known``, ``nn`` or ``jcbb`` (``auto`` resolved)."""
    skipped: SkippedLines
    """The bad lines skipped while reading it."""
    total: int | None = None
    """Items it holds (see :class:`~online_slam.sinks.protocol.ReplayProgress`), when counted and countable."""
    latency: float = 0.0
    """Seconds its lines may arrive late (``max_latency`` resolved: :data:`~online_slam.frontend.steps.STDIN_LATENCY`
    for a live source, stdin or TCP, when not given)."""


def open_events(
    source: str | Path | Iterable[Event],
    config: ReplayConfig,
    *,
    name: str | None = None,
    on_skip: Callable[[InputError], None] | None = None,
    validate: bool = True,
    count: bool = False,
    stop: Callable[[], bool] | None = None,
) -> OpenedSource:
    """Open a replay's source (see :func:`~online_slam.pipeline.replay` for the other arguments).

    Args:
        count: Count the items the source holds, for a progress display (see :func:`count_items`).
        stop: A TCP source asks it while it waits for a client or a line: True ends the stream.

    Raises:
        InputError: A path that does not exist; a bad line before the first sighting (``on_error="stop"``).
    """
    skipped = SkippedLines(on_skip)
    latency = config.frontend.max_latency
    if latency is None:
        latency = STDIN_LATENCY if isinstance(source, (str, Path)) and is_live(str(source)) else 0.0
    on_error: Callable[[InputError], None] | None = skipped if config.on_error == "skip" else None
    if on_error is None and latency > 0.0:
        on_error = functools.partial(_late_only, skipped)
    events: Iterable[Event]
    if isinstance(source, (str, Path)):
        label, events = open_source(source, on_error, latency, stop, **importer_options(source, config.dataset))
    else:
        label, events = "<events>", validate_events(source, on_error, max_latency=latency) if validate else iter(source)
    total = None
    if count and not config.dataset.get("format"):  # a format named: a dataset, whose records are not events
        total, events = count_items(source, events)
    method = config.association
    if method == "auto":
        has_id, events = first_sighting_has_id(events)
        method = "known" if has_id else "jcbb"
    return OpenedSource(name or label, iter(events), method, skipped, total, latency)


def _late_only(skipped: SkippedLines, error: InputError) -> None:
    """``on_error="stop"`` with a latency budget: a line beyond it is skipped and counted, any other bad line
    raises."""
    if not isinstance(error, LateInput):
        raise error
    skipped(error)


def importer_options(source: str | Path, dataset: dict) -> dict:
    """The dataset options that reach the source's reader: ``format`` and those its importer reads (``noise`` is
    the replay's, :mod:`online_slam.pipeline.noise`); the others are left for it to refuse."""
    return {name: value for name, value in dataset.items() if name != "noise"}


def count_items(source: str | Path | Iterable[Event], events: Iterable[Event]) -> tuple[int | None, Iterable[Event]]:
    """How many items a source holds, and its events to read from the start.

    A stream file's lines are counted (decompressed on the fly for ``.gz``, a pass over the bytes that costs a
    small part of the replay); a built-in world's events are generated once and kept; a list is measured. Standard
    input, datasets (whose records are not one event each) and other iterables give None.
    """
    if not isinstance(source, (str, Path)):
        return (len(source) if isinstance(source, Sized) else None), events
    text = str(source)
    path = Path(text)
    if text in WORLDS and not path.exists():
        events = list(events)
        return len(events), events
    if is_live(text) or not path.is_file() or registry.detect(path) is not None:
        return None, events
    opener = gzip.open if path.suffix == ".gz" else open
    lines, last = 0, b"\n"
    try:
        with opener(path, "rb") as handle:
            while chunk := handle.read(1 << 20):
                lines, last = lines + chunk.count(b"\n"), chunk[-1:]
    except (OSError, EOFError, zlib.error):  # the reader reports what is wrong with the file
        return None, events
    return lines + (last != b"\n"), events


def first_sighting_has_id(events: Iterable[Event]) -> tuple[bool, Iterable[Event]]:
    """Whether the stream's first sighting carries a landmark id, and the same events to read from the start.

    Events are read up to the first observation or scan (buffered and replayed); a stream without any sighting
    counts as having ids.
    """
    iterator = iter(events)
    buffered: list[Event] = []
    has_id = True
    for event in iterator:
        buffered.append(event)
        if isinstance(event, Observation):
            has_id = event.landmark is not None
            break
        if isinstance(event, Scan) and event.landmarks:
            has_id = event.landmarks[0] is not None
            break
    return has_id, itertools.chain(buffered, iterator)
