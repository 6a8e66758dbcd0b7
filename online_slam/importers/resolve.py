"""Resolve a user's SOURCE argument: a built-in world, a stream file (``.gz`` allowed), ``-``, or a dataset.

It lives with the importers, which it dispatches to, so that ``sources`` never depends on ``importers``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

from online_slam.errors import InputError
from online_slam.importers.detect import detect_format, open_dataset
from online_slam.sources.events import Event
from online_slam.sources.stream import read_stream, source_name
from online_slam.sources.worlds import WORLDS


def open_source(
    spec: str | Path, on_error: Callable[[InputError], None] | None = None, **dataset_options: object
) -> tuple[str, Iterator[Event]]:
    """Open a source lazily.

    Args:
        spec: A built-in world name (``square``, ``grid``) unless a file of that name exists; a path to a
            stream-v1 file (``.gz`` allowed); ``-`` for standard input; or a dataset (an MRCLAM folder, a
            GTSAM/iSAM text file, a ``.g2o`` file), converted on the fly.
        on_error: Stream files and stdin: given each bad line, which is then skipped (None: the first one
            raises). Datasets and built-in worlds ignore it (an importer stops at its first bad record).
        dataset_options: Passed to the dataset importer (``robot``, ``truth``, ``dt``, ``convention``, ``format``).

    Returns:
        (name for messages and reports, event iterator).

    Raises:
        InputError: When the path does not exist (raised at once, not on first read).
    """
    text = str(spec)
    if text in WORLDS and not Path(text).exists():
        return text, WORLDS[text].events()
    kind = dataset_options.pop("format", None) or (detect_format(text) if text != "-" else None)
    if kind is not None:
        options = {k: v for k, v in dataset_options.items() if v is not None}
        return text, open_dataset(text, kind, **options)
    if text != "-" and not Path(text).is_file():
        raise _not_found(text)
    return source_name(text), read_stream(text, on_error)


def check_source(spec: str | Path) -> None:
    """Raise :class:`InputError` at once when ``spec`` is neither ``-``, a built-in world nor an existing path."""
    text = str(spec)
    if text != "-" and text not in WORLDS and not Path(text).exists():
        raise _not_found(text)


def _not_found(text: str) -> InputError:
    return InputError(text, 0, "", f"no such file (and not a built-in world: {', '.join(sorted(WORLDS))})")
