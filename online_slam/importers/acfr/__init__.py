"""ACFR Victoria Park's raw log (``inputs.dat``, ``measurements.dat``, ``gps.dat``), as an importer plug-in
(:mod:`.reader`)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from online_slam.sources.events import Event

FILES = ("inputs.dat", "measurements.dat", "gps.dat")
"""The log's files."""


@dataclass(frozen=True)
class AcfrOptions:
    """The raw log takes no option: its noise model and the car's geometry are :mod:`.reader`'s."""


class Acfr:
    """The raw Victoria Park importer."""

    name = "acfr"
    summary = "raw Victoria Park folder (inputs.dat, measurements.dat, gps.dat)"
    options = AcfrOptions

    def detect(self, path: Path) -> bool:
        """A folder with the log's three files."""
        return path.is_dir() and all((path / name).is_file() for name in FILES)

    def refuse(self, path: Path) -> str | None:
        """Nothing to say."""
        return None

    def open(self, path: Path, options: AcfrOptions) -> Iterator[Event]:
        """The log's events."""
        from online_slam.importers.acfr.reader import read_acfr

        return read_acfr(path)


IMPORTER = Acfr()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
