"""g2o 2D files (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY), as an importer plug-in (:mod:`.reader`; it
writes them too, :func:`.reader.write_g2o`)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from online_slam.importers.registry import option
from online_slam.sources.events import Event


@dataclass(frozen=True)
class G2oOptions:
    """How to read a g2o file."""

    dt: float = option(1.0, "seconds per pose for files without timestamps", kind=float, metavar="S", unset="1 s",
                       positive=True)  # fmt: skip
    """Synthetic time between poses, seconds."""


class G2o:
    """The g2o importer."""

    name = "g2o"
    summary = "g2o 2D file (.g2o)"
    options = G2oOptions

    def detect(self, path: Path) -> bool:
        """A .g2o file."""
        return path.suffix == ".g2o"

    def refuse(self, path: Path) -> str | None:
        """Nothing to say."""
        return None

    def open(self, path: Path, options: G2oOptions) -> Iterator[Event]:
        """The file's events."""
        from online_slam.importers.g2o.reader import read_g2o

        return read_g2o(path, dt=options.dt)


IMPORTER = G2o()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
