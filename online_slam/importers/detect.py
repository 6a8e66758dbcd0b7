"""Recognise a dataset path and open it as events."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from online_slam.errors import InputError
from online_slam.sources.events import Event

DATASET_FORMATS = ("mrclam", "gtsam", "g2o", "acfr")
"""Formats ``convert`` reads (besides stream v1)."""


def detect_format(path: str | Path) -> str | None:
    """``mrclam`` for a folder with Barcodes.dat, ``acfr`` for one with inputs.dat, measurements.dat and gps.dat
    (Victoria Park's raw log), ``g2o`` for .g2o, ``gtsam`` for a text file of ODOMETRY/EDGE2
    lines; None for anything else (a stream-v1 file)."""
    p = Path(path)
    if p.is_dir() and (p / "Barcodes.dat").is_file():
        return "mrclam"
    if p.is_dir() and all((p / name).is_file() for name in ("inputs.dat", "measurements.dat", "gps.dat")):
        return "acfr"
    if p.suffix == ".g2o":
        return "g2o"
    if p.is_file() and p.suffix in (".txt", ".dat"):
        with p.open("r", encoding="utf-8", errors="replace") as handle:
            head = handle.readline().split()
        if head and head[0] in ("ODOMETRY", "EDGE2", "LANDMARK", "BR"):
            return "gtsam"
    return None


def open_dataset(path: str | Path, format: str | None = None, **options: Any) -> Iterator[Event]:
    """Events of a dataset, by format (detected when None).

    Options: ``robot`` (MRCLAM: 1..5, or ``"all"``: every robot in one stream) and ``noise`` (MRCLAM: ``None`` or
    ``"builtin"`` for the built-in coefficients, ``"fit"`` to fit them against the folder's Vicon data, or a
    ``MrclamNoise``), ``truth``, ``dt``, ``convention`` (GTSAM text).
    """
    kind = format or detect_format(path)
    if kind == "mrclam":
        return _open_mrclam(path, options.get("robot"), options.get("noise"))
    if kind == "gtsam":
        from online_slam.importers.gtsam_text import read_gtsam_text

        return read_gtsam_text(
            path, truth=options.get("truth"), dt=options.get("dt") or 1.0, convention=options.get("convention")
        )
    if kind == "acfr":
        from online_slam.importers.acfr import read_acfr

        return read_acfr(path)
    if kind == "g2o":
        from online_slam.importers.g2o import read_g2o

        return read_g2o(path, dt=options.get("dt") or 1.0)
    raise InputError(str(path), 0, "", f"unknown dataset format {kind!r}; expected one of {', '.join(DATASET_FORMATS)}")


def _open_mrclam(path: str | Path, robot: Any, noise: Any) -> Iterator[Event]:
    """One MRCLAM robot's events, or all five robots' (``robot="all"``), with the noise model asked for."""
    from online_slam.importers.mrclam import read_mrclam
    from online_slam.importers.mrclam_robots import read_mrclam_robots

    if robot is None:
        raise InputError(str(path), 0, "robot", "an MRCLAM folder needs --robot N (1..5) or --robot all")
    if noise == "fit":
        from online_slam.importers.mrclam_noise import fit_mrclam_noise

        noise = fit_mrclam_noise(path).noise
    elif noise == "builtin":
        noise = None
    if robot == "all":
        return read_mrclam_robots(path, noise)
    try:
        number = int(robot)
    except (TypeError, ValueError):
        raise InputError(str(path), 0, "robot", f"expected a robot number 1..5 or all, got {robot!r}") from None
    return read_mrclam(path, number, noise)
