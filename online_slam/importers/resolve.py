"""Resolve a user's SOURCE argument: a built-in world, a stream file (``.gz`` allowed), ``-``, or a dataset.

It lives with the importers, which it dispatches to, so that ``sources`` never depends on ``importers``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from online_slam.errors import InputError
from online_slam.importers import registry
from online_slam.sources.address import is_tcp
from online_slam.sources.events import Event
from online_slam.sources.stream import read_stream, source_name
from online_slam.sources.worlds import WORLDS
from online_slam.wording import did_you_mean


def open_source(
    spec: str | Path,
    on_error: Callable[[InputError], None] | None = None,
    max_latency: float = 0.0,
    stop: Callable[[], bool] | None = None,
    **dataset_options: Any,
) -> tuple[str, Iterator[Event]]:
    """Open a source lazily.

    Args:
        spec: A built-in world name (``square``, ``grid``) unless a file of that name exists; a path to a
            stream-v1 file (``.gz`` allowed); ``-`` for standard input; or a dataset (an MRCLAM folder, a
            GTSAM/iSAM text file, a ``.g2o`` file), converted on the fly; or ``tcp://HOST:PORT``: listen there
            and read a stream from one client at a time (:mod:`online_slam.sources.tcp`).
        on_error: Stream files, stdin and TCP: given each bad line, which is then skipped (None: the first one
            raises). Datasets and built-in worlds ignore it (an importer stops at its first bad record).
        max_latency: Stream files, stdin and TCP: seconds a line may lie before the newest (a later stage reorders).
        stop: TCP: asked while waiting for a client or a line; True ends the stream.
        dataset_options: Passed to the dataset importer (``robot``, ``truth``, ``dt``, ``convention``, ``format``).

    Returns:
        (name for messages and reports, event iterator).

    Raises:
        InputError: At once, not on first read: the path does not exist, is a folder or a file of no dataset the
            importers read, or a dataset option is given that this source does not read (``--robot`` for a world).
    """
    text = str(spec)
    options = {k: v for k, v in dataset_options.items() if v is not None}
    if is_tcp(text):
        from online_slam.sources.tcp import open_tcp

        if options:
            flag = "--" + next(iter(options)).replace("_", "-")
            raise InputError(text, 0, "", f"{flag} applies to dataset files, not to a TCP stream")
        return open_tcp(text, on_error, max_latency, stop)
    is_world = text in WORLDS and not Path(text).exists()
    forced = options.pop("format", None)
    if forced is not None and (is_world or text == "-"):
        what = "a built-in world" if is_world else "standard input"
        raise InputError(text, 0, "", f"--format applies to dataset files, not to {what}")
    kind = forced or (registry.detect(text) if text != "-" and not is_world else None)
    if forced is not None and Path(text).exists() and not registry.importers()[forced].detect(Path(text)):
        detected = registry.detect(text)
        told = f"; it reads as {detected} data (drop --format)" if detected else ""
        raise InputError(
            text, 0, "", f"--format {forced}: not {forced} data ({registry.importers()[forced].summary}){told}"
        )
    _check_options(text, kind, is_world, options)
    if is_world:
        return text, WORLDS[text].events()
    if kind is not None:
        return text, registry.open_dataset(text, kind, **options)
    if text != "-" and not Path(text).is_file():
        raise _not_found(text)
    if text.endswith(".rrd"):
        raise InputError(text, 0, "", "a Rerun recording, not a stream: read it with 'online-slam inspect' or rerun")
    why = registry.refusal(text)
    if why is not None:
        raise InputError(text, 0, "", why)
    return source_name(text), read_stream(text, on_error, max_latency)


def _check_options(text: str, kind: str | None, is_world: bool, options: dict[str, object]) -> None:
    """Refuse dataset options this source does not read (``--robot 2`` with a world would be ignored)."""
    extra = [name for name in options if name not in registry.takes(kind)]
    if not extra:
        return
    what = (
        "a built-in world" if is_world else "standard input" if text == "-" else f"{kind} data" if kind else "a stream"
    )
    readers = [f for f in registry.names() if extra[0] in registry.takes(f)]
    flag = "--" + extra[0].replace("_", "-")
    raise InputError(source_name(text), 0, "", f"{flag} applies to {' and '.join(readers) or 'no'} data, not to {what}")


def check_source(spec: str | Path) -> None:
    """Raise :class:`InputError` at once when ``spec`` is neither ``-``, a built-in world nor an existing path."""
    text = str(spec)
    if text != "-" and not is_tcp(text) and text not in WORLDS and not Path(text).exists():
        raise _not_found(text)


def _not_found(text: str) -> InputError:
    """Why a source that is neither a world nor a readable file cannot be opened, with what to pass instead."""
    path = Path(text)
    if path.is_dir():
        inside = sorted(p.name for p in path.iterdir() if registry.detect(p) is not None)
        files = ", ".join(str(path / name) for name in inside[:3])
        hint = f"pass one of its files: {files}" if inside else "none of its files is a dataset"
        return InputError(text, 0, "", f"a folder, but no dataset folder an importer reads; {hint}")
    worlds = ", ".join(sorted(WORLDS))
    guess = did_you_mean(text, WORLDS) if "/" not in text else ""
    return InputError(text, 0, "", f"no such file, and not a built-in world{guess}; worlds: {worlds}")
