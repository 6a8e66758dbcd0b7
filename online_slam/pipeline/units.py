"""Wrong units caught early: when most of a run's first sightings are rejected, or its first lines skipped, one
warning names the likely cause (angles in degrees, ranges in centimetres, sigmas too small).

The cause is not guessed from magnitudes alone (a bearing of 5 is 5 radians as well as 5 degrees): each
candidate fix is tried on the run's first events, by an EKF of its own, and the one that makes the sightings
agree is named. ``--strict`` makes the warning an error (:class:`SuspectInput`).
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from online_slam.engine import StepRecord
from online_slam.errors import OnlineSlamError
from online_slam.sources.events import Event, Observation, Odometry, Scan
from online_slam.wording import counted

FIRST = 100
"""How many of the run's first sightings (with a NIS: landmarks seen before) and lines are judged."""
FEWEST = 20
"""Fewer sightings than this by the end of the run, and nothing is judged."""
ABSURD_NIS = 18.4
"""A median NIS above this (the EKF's default gate on 2 dof) is absurd: most sightings disagree with the map."""
_HEAD_EVENTS = 20_000
"""Most events kept to try the fixes on."""


class SuspectInput(OnlineSlamError):
    """The input's units (or its sigmas) look wrong, and ``--strict`` was given."""


@dataclass(frozen=True)
class Fix:
    """A candidate cause of sightings that disagree: its name, and the change that would undo it."""

    cause: str
    """What the input likely holds, for the warning (``bearings in degrees``)."""
    undo: Callable[[Event], Event]
    """The event as it would be if the cause were fixed."""


def _scaled(field: str, scale: float) -> Callable[[Event], Event]:
    """Undo a unit on one measured field (``bearing`` or ``range``) of sightings and scans."""
    many = field + "s"

    def undo(event: Any) -> Any:
        if isinstance(event, Observation) and getattr(event, field) is not None:
            return dataclasses.replace(event, **{field: getattr(event, field) * scale})
        if isinstance(event, Scan):
            values: dict[str, Any] = {many: tuple(v * scale for v in getattr(event, many))}
            return dataclasses.replace(event, **values)
        return event

    return undo


def _scaled_bearings(scale: float) -> Callable[[Event], Event]:
    return _scaled("bearing", scale)


def _scaled_ranges(scale: float) -> Callable[[Event], Event]:
    return _scaled("range", scale)


def _turns_in_degrees(event: Event) -> Event:
    if isinstance(event, Odometry):
        dx, dy, turn = event.delta
        return dataclasses.replace(event, delta=(dx, dy, math.radians(turn)))
    return event


FIXES = (
    Fix("odometry headings in degrees", _turns_in_degrees),
    Fix("bearings in degrees", _scaled_bearings(math.pi / 180)),
    Fix("ranges in centimetres", _scaled_ranges(0.01)),
    Fix("ranges in millimetres", _scaled_ranges(0.001)),
)
"""The causes tried, in order."""


@dataclass(frozen=True)
class Verdict:
    """How a run's first sightings went: what was rejected and how far off they were."""

    sightings: int
    """Sightings judged (of landmarks seen before)."""
    rejected: int
    """Of those, rejected by the EKF's gate."""
    median_nis: float
    """Their median NIS (NaN without any)."""

    @property
    def suspect(self) -> bool:
        """Most were rejected, or their NIS is absurd."""
        return self.sightings >= FEWEST and (2 * self.rejected > self.sightings or self.median_nis > ABSURD_NIS)


class UnitWatch:
    """Watches a run's first steps and lines; says once, when they look like wrong units, what the cause likely is.

    Args:
        estimator: The EKF's name, whose gate and NIS are read (None: no EKF runs; only skipped lines are judged).
        probe: Runs an EKF over events and returns its :class:`Verdict` (to try each fix on the first events).
    """

    def __init__(self, estimator: str | None, probe: Callable[[list[Event]], Verdict]) -> None:
        self._estimator = estimator
        self._probe = probe
        self._head: list[Event] = []
        self._nis: list[float] = []
        self._rejected = 0
        self._lines = 0
        self.message: str | None = None
        """The warning, once given."""
        self.done = False
        """Judged (once): nothing more is watched."""

    def take(self, event: Event) -> None:
        """An event of the source, before the engine gets it."""
        if not self.done and len(self._head) < _HEAD_EVENTS:
            self._head.append(event)

    def step(self, record: StepRecord, skipped: Mapping[str, int], consumed: int) -> str | None:
        """A complete step; the warning when this step settles it (else None)."""
        if self.done:
            return None
        snapshot = record.snapshots.get(self._estimator or "")
        if snapshot is not None:
            nis = np.asarray(snapshot.info.get("nis", ()), dtype=float)
            self._nis += [float(v) for v in nis[np.isfinite(nis)]]
            self._rejected += len(snapshot.info.get("gated", ()))
        lines = consumed + sum(skipped.values())
        if len(self._nis) >= FIRST or lines >= FIRST and 2 * sum(skipped.values()) > lines:
            return self.judge(skipped, consumed)
        return None

    def judge(self, skipped: Mapping[str, int], consumed: int) -> str | None:
        """Judge what was seen so far (at the latest when the run ends), once; the warning or None."""
        if self.done:
            return None
        self.done = True
        bad = sum(skipped.values())
        lines = consumed + bad
        if lines >= FEWEST and 2 * bad > min(lines, FIRST) and bad:
            self.message = _skipped_message(skipped, lines)
        else:
            seen = self._nis[:FIRST]
            verdict = Verdict(len(seen), min(self._rejected, len(seen)), float(np.median(seen)) if seen else math.nan)
            if verdict.suspect:
                self.message = self._rejected_message(verdict)
        self._head = []
        return self.message

    def _rejected_message(self, verdict: Verdict) -> str:
        """Most sightings rejected: try each fix on the first events; name the one that makes them agree."""
        found = f"{verdict.rejected} of the first {counted(verdict.sightings, 'repeated sighting')} rejected"
        found += f" (median NIS {verdict.median_nis:.3g}, 1.39 if consistent)"
        tried = [(fix, self._probe([fix.undo(e) for e in self._head])) for fix in FIXES]
        fixed = [(fix, v) for fix, v in tried if not v.suspect and v.sightings >= FEWEST]
        if fixed:
            fix, better = min(fixed, key=lambda pair: abs(math.log(max(pair[1].median_nis, 1e-9) / 1.39)))
            cause = (
                f"{fix.cause}? converted, {better.rejected} of {better.sightings} are rejected "
                f"(median NIS {better.median_nis:.3g})"
            )
        else:
            factor = math.sqrt(verdict.median_nis / 1.39) if math.isfinite(verdict.median_nis) else math.nan
            cause = (
                f"no change of units tried (degrees, centimetres) fixes them: sigmas too small (by about "
                f"{factor:.3g}x), or the wrong landmark ids?"
            )
        return f"suspect input: {found}; {cause}"


def _skipped_message(skipped: Mapping[str, int], lines: int) -> str:
    """Most lines skipped: name the main reason, and what it likely means."""
    reason, count = Counter(skipped).most_common(1)[0]
    meaning = {
        "out_of_range": "angles in degrees? (radians lie within [-2 pi, 2 pi])",
        "range_not_positive": "ranges of another sensor, or signed?",
        "time_order": "lines out of time order (merged logs?)",
        "invalid_json": "not a stream v1 file?",
        "unknown_type": "not a stream v1 file?",
        "bad_noise": "sigmas or covariances in the wrong form?",
    }.get(reason, "see the skipped lines above")
    total = sum(skipped.values())
    return (
        f"suspect input: {total} of the first {counted(lines, 'line')} skipped, most as {reason} ({count}); {meaning}"
    )


def probe_with(run_ekf: Callable[[Iterable[Event]], tuple[np.ndarray, int]]) -> Callable[[list[Event]], Verdict]:
    """A probe from a function that runs an EKF over events and returns its sightings' NIS in order (NaN for a
    landmark's first) and how many of the first :data:`FIRST` repeated ones it rejected."""

    def probe(events: list[Event]) -> Verdict:
        try:
            nis, rejected = run_ekf(events)
        except OnlineSlamError:
            return Verdict(0, 0, math.nan)
        seen = nis[np.isfinite(nis)][:FIRST]
        return Verdict(len(seen), rejected, float(np.median(seen)) if len(seen) else math.nan)

    return probe
