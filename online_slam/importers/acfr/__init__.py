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
GPS_ANTENNA = (4.0, 0.6)
"""The GPS antenna ``[forward, left]`` of the rear axle centre, metres, as measured on the log: (3.88, 0.67) on its
first half, (4.11, 0.54) on its second (:mod:`.reader`, docs/datasets.md)."""


@dataclass(frozen=True)
class AcfrOptions:
    """How GPS is used; the noise model and the car's geometry are :mod:`.reader`'s."""

    gps_fix_every: float | None = option(None, "ACFR: one GPS reading every S seconds becomes a position fix (the "
                                         "rest stays truth, for scoring)", kind=float, metavar="S", positive=True,
                                         unset="none: GPS is truth only")  # fmt: skip
    """Seconds between GPS readings given to the estimators as ``position`` fixes; None: none (GPS is truth only)."""
    gps_sigma: float = option(0.5, "ACFR: standard deviation of a GPS position fix, metres", kind=float, metavar="M",
                              unset="0.5 m", positive=True)  # fmt: skip
    """Standard deviation of each axis of a GPS fix, metres: about the GPS's own scatter (0.56 m RMS about dead
    reckoning fitted over 10 s windows), and the best of 0.5, 1 and 3 m on the log's first half (docs/datasets.md)."""
    gps_antenna_forward: float = option(GPS_ANTENNA[0], "ACFR: GPS antenna ahead of the rear axle centre, metres "
                                        "(fixes and truth are of it; measured on the log)", kind=float, metavar="M",
                                        unset=f"{GPS_ANTENNA[0]:g} m")  # fmt: skip
    """GPS antenna ahead of the rear axle centre, metres (measured: 3.88 on the log's first half, 4.11 on its
    second)."""
    gps_antenna_left: float = option(GPS_ANTENNA[1], "ACFR: GPS antenna left of the rear axle centre, metres",
                                     kind=float, metavar="M", unset=f"{GPS_ANTENNA[1]:g} m")  # fmt: skip
    """GPS antenna left of the rear axle centre, metres (measured: 0.67 on the first half, 0.54 on the second)."""


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

        antenna = (options.gps_antenna_forward, options.gps_antenna_left)
        return read_acfr(path, fixes=(options.gps_fix_every, options.gps_sigma), antenna=antenna)


IMPORTER = Acfr()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
