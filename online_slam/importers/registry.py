"""The importers, as plug-ins: one registry from which detection, SOURCE resolution, the dataset options of the
command line and sweeps all derive.

An importer is a light module (no numerical library at import: ``--help`` lists its options from it) holding
``IMPORTER``, an object that follows :class:`Importer`; its reader is imported when a source is opened. Adding a
format is its own package and one line of :data:`REGISTRY` (docs/architecture.md shows one).
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path
from typing import Any, Protocol

from online_slam.errors import InputError
from online_slam.sources.events import Event

REGISTRY = (
    "online_slam.importers.mrclam",
    "online_slam.importers.acfr",
    "online_slam.importers.g2o",
    "online_slam.importers.gtsam_text",
    "online_slam.importers.bag",
)
"""The importers' modules, in the order detection asks them; each holds ``IMPORTER``."""


class Importer(Protocol):
    """A dataset format: how to recognise it, its options, and how to read it as events."""

    name: str
    """The format's name (``convert FORMAT``, ``--format``)."""
    summary: str
    """What it reads, in a few words (``convert --help``)."""
    options: type
    """Its options: a frozen dataclass whose fields are declared with :func:`option` (each becomes a flag)."""

    def detect(self, path: Path) -> bool:
        """Whether ``path`` is a source of this format."""
        ...

    def refuse(self, path: Path) -> str | None:
        """Why ``path``, no source itself, is no source (a file inside a dataset's folder), or None."""
        ...

    def open(self, path: Path, options: Any) -> Iterator[Event]:
        """The source's events (options: an instance of :attr:`options`).

        Raises:
            InputError: Options that do not fit the source, or a bad record.
        """
        ...


def option(
    default: Any,
    help: str,
    *,
    kind: type = str,
    metavar: str | None = None,
    choices: tuple[str, ...] = (),
    unset: str = "",
    positive: bool = False,
    parse: Callable[[str], Any] | None = None,
    required: bool = False,
    listed: bool = False,
) -> Any:
    """A field of an importer's options dataclass, with what its flag needs.

    Args:
        default: The value when the option is not given.
        help: One line for ``--help`` and docs/options.md (name the format: ``MRCLAM: ...``).
        kind: Value type on the command line (``bool``: a flag without a value).
        metavar, choices, unset, positive, parse: As :class:`online_slam.options.Option` has them.
        required: The source cannot be read without it (a sweep refuses such a source without the option).
        listed: A sweep takes a list of values and replays the source once per value.
    """
    metadata = {"help": help, "kind": kind, "metavar": metavar, "choices": choices, "unset": unset,
                "positive": positive, "parse": parse, "required": required, "listed": listed}  # fmt: skip
    return dataclasses.field(default=default, metadata=metadata)


@cache
def importers() -> dict[str, Importer]:
    """Every registered importer by name, in detection order."""
    found = [importlib.import_module(module).IMPORTER for module in REGISTRY]
    return {importer.name: importer for importer in found}


def names() -> tuple[str, ...]:
    """The registered formats."""
    return tuple(importers())


def detect(path: str | Path) -> str | None:
    """The format of a dataset path, or None (a stream-v1 file, or nothing an importer reads)."""
    p = Path(path)
    return next((name for name, importer in importers().items() if importer.detect(p)), None)


def refusal(path: str | Path) -> str | None:
    """Why a path is no source though an importer knows it (a file of a dataset's folder), or None."""
    p = Path(path)
    return next((why for importer in importers().values() if (why := importer.refuse(p)) is not None), None)


def fields(name: str) -> dict[str, dataclasses.Field]:
    """An importer's option fields by name."""
    return {f.name: f for f in dataclasses.fields(importers()[name].options)}


def takes(name: str | None) -> tuple[str, ...]:
    """The option names an importer reads (none for None: a stream or a world)."""
    return tuple(fields(name)) if name is not None else ()


def dataset_options() -> dict[str, tuple[dataclasses.Field, tuple[str, ...]]]:
    """Every importer option by name: its field (the first importer's that declares it) and the formats taking it."""
    out: dict[str, tuple[dataclasses.Field, tuple[str, ...]]] = {}
    for name in importers():
        for field_name, f in fields(name).items():
            first, formats = out.get(field_name, (f, ()))
            out[field_name] = (first, (*formats, name))
    return out


def open_dataset(path: str | Path, format: str | None = None, **options: Any) -> Iterator[Event]:
    """A dataset's events, by format (detected when None); ``options`` are the importer's (unknown ones refused).

    Raises:
        InputError: No importer reads the path or knows the format; an option it does not read, or a bad value.
    """
    kind = format or detect(path)
    if kind not in importers():
        raise InputError(str(path), 0, "", f"unknown dataset format {kind!r}; expected one of {', '.join(names())}")
    importer = importers()[kind]
    extra = sorted(set(options) - set(takes(kind)))
    if extra:
        raise InputError(str(path), 0, extra[0], f"{kind} data takes no option {extra[0]}")
    try:
        chosen = importer.options(**options)
    except (TypeError, ValueError) as exc:
        raise InputError(str(path), 0, "", str(exc)) from None
    return importer.open(Path(path), chosen)
