"""ACFR Victoria Park's raw log (``inputs.dat``, ``measurements.dat``, ``gps.dat``), as an importer plug-in
(:mod:`.reader`)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from online_slam.importers.registry import option
from online_slam.sources.events import Event

FILES = ("inputs.dat", "measurements.dat", "gps.dat")
"""The log's files."""


@dataclass(frozen=True)
class AcfrOptions:
    """How GPS is used; the noise model and the car's geometry are :mod:`.reader`'s."""

    gps_fix_every: float | None = option(None, "ACFR: one GPS reading every S seconds becomes a position fix (the "
                                         "rest stays truth, for scoring)", kind=float, metavar="S", positive=True,
                                         unset="none: GPS is truth only")  # fmt: skip
    """Seconds between GPS readings given to the estimators as ``position`` fixes; None: none (GPS is truth only)."""
    gps_sigma: float = option(3.0, "ACFR: standard deviation of a GPS position fix, metres", kind=float, metavar="M",
                              unset="3 m", positive=True)  # fmt: skip
    """Standard deviation of each axis of a GPS fix, metres."""


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

        return read_acfr(path, fixes=(options.gps_fix_every, options.gps_sigma))


IMPORTER = Acfr()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
