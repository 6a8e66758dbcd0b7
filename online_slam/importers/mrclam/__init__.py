"""UTIAS MRCLAM (multi-robot cooperative localization and mapping), as an importer plug-in.

A folder with ``Barcodes.dat``; one robot's stream (:mod:`.reader`) or all five robots' in one stream
(:mod:`.robots`), under a noise model fitted against Vicon (:mod:`.noise`; ``--refit`` repeats the fit on the
folder), with the cameras' sightings placed through :mod:`.sightings`.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from online_slam.errors import InputError
from online_slam.importers.registry import option
from online_slam.sources.events import Event

FILE = re.compile(r"(Robot[1-5]_(Odometry|Measurement|Groundtruth)|Barcodes|Landmark_Groundtruth)\.dat")
"""The files of an MRCLAM folder (one of them alone is no source: the folder is)."""

HALVES = ("first", "second")
"""The parts of a recording a held-out check fits on and scores on (:func:`.reader.half_span`)."""


def robot_choice(text: str) -> int | str:
    """An MRCLAM robot on the command line: its number, or ``all``."""
    if text == "all":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a robot number or all, got {text!r}") from None


@dataclass(frozen=True)
class MrclamOptions:
    """How to read an MRCLAM folder."""

    robot: int | str | None = option(
        None, "MRCLAM: robot number 1..5, or all: the five robots in one stream (sweep: a list)", kind=int,
        metavar="N", parse=robot_choice, required=True, listed=True,
    )  # fmt: skip
    """1..5, or ``all``: the five robots in one stream, with their sightings of each other."""
    refit: bool = option(
        False, "MRCLAM: refit the conversion's noise model against the folder's Vicon data (all five robots) first",
        kind=bool,
    )  # fmt: skip
    """Refit the model (:func:`.noise.fit_mrclam_noise`) instead of the built-in coefficients fitted on Dataset 6."""
    half: str | None = option(
        None, "MRCLAM: replay only the first or the second half of the recording (by time, one cut for all robots)",
        choices=HALVES, unset="all of it",
    )  # fmt: skip
    """``first`` or ``second``: only that half, starting at its first sighting's Vicon pose (None: all of it)."""
    fit_half: str | None = option(
        None, "MRCLAM: refit the model against Vicon on this half of the folder's recording only (with --half the "
        "other: a held-out check)", choices=HALVES, unset="no refit",
    )  # fmt: skip
    """Refit on ``first`` or ``second`` half only (:func:`.reader.half_span`); None: as ``refit`` says."""


class Mrclam:
    """The MRCLAM importer."""

    name = "mrclam"
    summary = "MRCLAM folder (Barcodes.dat, RobotN_*.dat)"
    options = MrclamOptions

    def detect(self, path: Path) -> bool:
        """A folder with Barcodes.dat."""
        return path.is_dir() and (path / "Barcodes.dat").is_file()

    def refuse(self, path: Path) -> str | None:
        """One file of a folder: the folder is the source."""
        if path.is_file() and FILE.fullmatch(path.name):
            example = f"online-slam replay {path.parent} --robot 1"
            return f"a file of an MRCLAM folder: pass the folder with --robot N, e.g. '{example}'"
        return None

    def open(self, path: Path, options: MrclamOptions) -> Iterator[Event]:
        """One robot's events, or all five robots' (``robot="all"``), under the built-in or a refitted model."""
        from online_slam.importers.mrclam.reader import half_of, read_mrclam, recording_span
        from online_slam.importers.mrclam.robots import read_mrclam_robots

        if options.robot is None:
            raise InputError(str(path), 0, "robot", "an MRCLAM folder needs --robot N (1..5) or --robot all")
        noise = None
        recording = recording_span(path) if options.half or options.fit_half else None  # read once for both
        if options.refit or options.fit_half is not None:
            from online_slam.importers.mrclam.noise import fit_mrclam_noise

            fit_span = None if recording is None or options.fit_half is None else half_of(recording, options.fit_half)
            noise = fit_mrclam_noise(path, span=fit_span).noise
        span = None if recording is None or options.half is None else half_of(recording, options.half)
        if options.robot == "all":
            return read_mrclam_robots(path, noise, span)
        try:
            number = int(options.robot)
        except (TypeError, ValueError):
            expected = f"expected a robot number 1..5 or all, got {options.robot!r}"
            raise InputError(str(path), 0, "robot", expected) from None
        return read_mrclam(path, number, noise, span)


IMPORTER = Mrclam()
"""The plug-in (:data:`online_slam.importers.registry.REGISTRY`)."""
