"""GTSAM / iSAM text files (``victoria_park.txt``, ``cityTrees10000.txt``), as an importer plug-in (:mod:`.reader`)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from online_slam.importers.registry import option
from online_slam.sources.events import Event

FIRST_WORDS = ("ODOMETRY", "EDGE2", "LANDMARK", "BR")
"""What a GTSAM/iSAM text file's first line starts with."""


@dataclass(frozen=True)
class GtsamTextOptions:
    """How to read a GTSAM/iSAM text file."""

    truth: str | None = option(
        None, "GTSAM/iSAM text: the noise-free twin file (truth); ROS bag: the truth topic", metavar="PATH|TOPIC"
    )
    """The file's noise-free twin (same lines), for truth poses and landmarks."""
    dt: float = option(1.0, "seconds per pose for files without timestamps", kind=float, metavar="S", unset="1 s",
                       positive=True)  # fmt: skip
    """Synthetic time between poses, seconds."""
    convention: str | None = option(None, "GTSAM/iSAM text noise convention", choices=("gtsam", "isam"),
                                    unset="detected")  # fmt: skip
    """``gtsam`` or ``isam`` (None: ``isam`` if the file uses EDGE2, else ``gtsam``)."""


class GtsamText:
    """The GTSAM/iSAM text importer."""

    name = "gtsam"
    summary = "GTSAM/iSAM text file (ODOMETRY/EDGE2, LANDMARK/BR lines)"
    options = GtsamTextOptions

    def detect(self, path: Path) -> bool:
        """A .txt or .dat file whose first line is an ODOMETRY, EDGE2, LANDMARK or BR record."""
        if not (path.is_file() and path.suffix in (".txt", ".dat")):
            return False
        with path.open("r", encoding="utf-8", errors="replace") as handle:
            head = handle.readline().split()
        return bool(head) and head[0] in FIRST_WORDS

    def refuse(self, path: Path) -> str | None:
        """Nothing to say."""
        return None

    def open(self, path: Path, options: GtsamTextOptions) -> Iterator[Event]:
        """The file's events."""
        from online_slam.importers.gtsam_text.reader import read_gtsam_text

        return read_gtsam_text(path, truth=options.truth, dt=options.dt, convention=options.convention)


IMPORTER = GtsamText()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
