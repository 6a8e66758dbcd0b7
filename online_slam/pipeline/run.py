"""Running a replay: the engine, what is recorded of each estimator, the position in the source, the lines
skipped, and the checkpoints that hold all of it (written every N steps, resumed from)."""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from online_slam.checkpoint import read_checkpoint, write_checkpoint
from online_slam.engine import Engine, EngineCheckpoint, StepRecord
from online_slam.errors import ConfigError, InputError, OnlineSlamError
from online_slam.estimators.batch import BatchEstimator
from online_slam.estimators.dead_reckoning import DeadReckoning
from online_slam.estimators.protocol import Estimator, Snapshot
from online_slam.evaluation.results import INTERRUPTED
from online_slam.faults import crash_point
from online_slam.pipeline.config import Checkpointing, ReplayConfig, build_estimators
from online_slam.pipeline.source import OpenedSource
from online_slam.pipeline.units import FIRST, SuspectInput, UnitWatch, probe_with
from online_slam.sinks.protocol import ProgressSink, ReplayProgress, ReplaySink
from online_slam.sources.events import Event, LandmarkId, Observation
from online_slam.sources.landmark_map import LandmarkMap, read_map
from online_slam.wording import counted

Array = NDArray[np.float64]

CHECKPOINT_FILE = "replay.ckpt"
"""Name of the checkpoint file inside a checkpoint folder."""
_FINGERPRINT_EVENTS = 1000


@dataclass(eq=False)
class Track:
    """What a replay records of one estimator while it runs (a checkpoint holds it)."""

    poses: list[Array] = field(default_factory=list)
    """The newest pose after each step, shape (3,)."""
    covariances: list[Array | None] = field(default_factory=list)
    """Its covariance (3, 3), or None."""
    seconds: list[float] = field(default_factory=list)
    """Wall time of each step."""
    times: list[float] = field(default_factory=list)
    """Time of each step."""
    nis: list[float] = field(default_factory=list)
    """Mean NIS of each step's sightings (NaN without)."""

    def record(self, snapshot: Snapshot, seconds: float) -> None:
        self.poses.append(snapshot.pose)
        self.covariances.append(snapshot.pose_cov)
        self.seconds.append(seconds)
        self.times.append(snapshot.t)
        nis = np.asarray(snapshot.info.get("nis", ()), dtype=float)
        self.nis.append(float(np.nanmean(nis)) if np.isfinite(nis).any() else np.nan)


class _SourcePosition:
    """Counts the events taken from the source and fingerprints them (the first 1000, and the last one)."""

    def __init__(self) -> None:
        self.consumed = 0
        self._head = hashlib.sha256()
        self.last = ""

    def take(self, event: Event) -> None:
        self.consumed += 1
        self.last = repr(event)
        if self.consumed <= _FINGERPRINT_EVENTS:
            self._head.update(self.last.encode())

    @property
    def fingerprint(self) -> str:
        return f"{self.consumed}:{self._head.hexdigest()}:{hashlib.sha256(self.last.encode()).hexdigest()}"


@dataclass(eq=False)
class ReplayCheckpoint:
    """What a replay's checkpoint holds."""

    source: str
    """The source's name (a resumed replay must read the same)."""
    settings: str
    """The replay's configuration (``repr``; a resumed replay must have the same)."""
    consumed: int
    """Events taken from the source."""
    fingerprint: str
    """Of those events (see :class:`_SourcePosition`)."""
    skipped: dict[str, int]
    """Lines skipped so far, by reason."""
    engine: EngineCheckpoint
    """The engine, its front-end and its estimators."""
    tracks: dict[str, Track]
    """What was recorded of each estimator, by name."""
    step_times: list[float]
    """Time of each complete step."""
    sighting_ids: list[LandmarkId | None]
    """The stream's id of every sighting (association scoring)."""
    without_id: int
    """Sightings without an id."""
    not_in_map: int = 0
    """Sightings skipped by ``--map-only``."""


class _CheckpointFailure(OnlineSlamError):
    """A checkpoint could not be written: the replay stops there and reports what it estimated."""


@dataclass(frozen=True)
class _Resumption:
    """Where a resumed replay's source must be read again to (the events its checkpoint had consumed)."""

    folder: str | Path
    """The checkpoint folder, as given."""
    consumed: int
    """Events to read again."""
    fingerprint: str
    """Theirs when the checkpoint was written."""


class ReplayRun:
    """A replay as it runs: the engine (front-end, dead reckoning, estimators), what is recorded of each estimator,
    the position in the source and the lines skipped; it writes checkpoints of all of it and resumes from one.

    Args:
        opened: The source, opened.
        config: What the replay runs (its estimators set to associate as ``opened`` says).
        sinks: Given every step with all estimators' snapshots (``wall_s`` set); those that are progress sinks
            are also told where the run stands, out of ``opened.total``.
        checkpoint: Where and how often to write checkpoints (None: never).
        stop: Asked after each step; True ends the run there as if the stream had ended, ``error`` saying
            :data:`~online_slam.evaluation.results.INTERRUPTED` (a signal handler's flag: Ctrl-C keeps the work).
        on_warning: Told, once, when the first sightings or lines look like wrong units
            (:mod:`~online_slam.pipeline.units`); with ``config.strict`` the run stops there instead, ``error``
            saying why.
    """

    def __init__(
        self,
        opened: OpenedSource,
        config: ReplayConfig,
        sinks: Sequence[ReplaySink] = (),
        checkpoint: Checkpointing | None = None,
        stop: Callable[[], bool] | None = None,
        on_warning: Callable[[str], None] | None = None,
    ) -> None:
        self.source = opened.name
        """The source's name."""
        self.association = opened.association
        """How sightings are associated: ``known``, ``nn`` or ``jcbb``."""
        self.skipped = opened.skipped
        """Bad lines skipped."""
        self.settings = repr(config)
        """The configuration as a checkpoint records it."""
        self.odometry = DeadReckoning()
        """Dead reckoning, the baseline."""
        self.estimators = build_estimators(config.with_association(opened.association))
        """The estimators, in table order."""
        self.landmark_map = _load_map(config, self.estimators)
        """The map the estimators started from (``--map``), or None."""
        self.not_in_map = 0
        """Sightings ``--map-only`` skipped: of landmarks not in the map."""
        self.map_fixed = config.map.fixed
        """The map's landmarks are held (``--map-fixed``)."""
        self.map_path = config.map.path or ""
        """The map's file (empty: none, or a map given as an object)."""
        by_id = self.landmark_map is not None and config.map.only and opened.association == "known"
        self._map_only = frozenset(self.landmark_map.ids) if by_id and self.landmark_map else None
        """With ids, ``--map-only`` leaves out the sightings of other landmarks here (without ids, each estimator's
        association starts no landmark instead: a stream's ids are never used then)."""
        frontend = dataclasses.replace(config.frontend, max_latency=opened.latency)
        self.engine = Engine([self.odometry, *self.estimators], frontend)
        """The engine: front-end, dead reckoning and estimators."""
        self.tracks = {e.name: Track() for e in self.estimators}
        """What was recorded of each estimator, by name."""
        self.step_times: list[float] = []
        """Time of each complete step."""
        self.sighting_ids: list[LandmarkId | None] = []
        """The stream's id of every sighting, to score association by (``nn``, ``jcbb``)."""
        self.without_id = 0
        """Sightings the stream gave without an id (reported under known association)."""
        self.error: str | None = None
        """The input error, or failed checkpoint write, that ended the run early."""
        self._events = opened.events
        self._position = _SourcePosition()
        self._sinks = sinks
        self._watchers = [sink for sink in sinks if isinstance(sink, ProgressSink)]
        self._total = opened.total
        self._checkpoint = checkpoint
        self._resumption: _Resumption | None = None
        self._stop = stop
        ekf = "ekf" if "ekf" in config.estimators else None
        self.units = UnitWatch(ekf, probe_with(_ekf_run(config, opened.association)))
        """Watches the first sightings and lines for wrong units."""
        self.warning: str | None = None
        """The warning about suspect input, when one was given."""
        self._strict = config.strict
        self._on_warning = on_warning

    def resume(self, folder: str | Path) -> None:
        """Continue from the checkpoint in ``folder`` (:meth:`run` then reads again what it had consumed).

        Raises:
            InputError: A damaged checkpoint, one of another source, of other settings or of another version.
        """
        where = Path(folder) / CHECKPOINT_FILE
        saved = read_checkpoint(where, "replay", ReplayCheckpoint)
        if saved.source != self.source:
            raise InputError(str(where), 0, "", f"checkpoint of another source ({saved.source!r}, not {self.source!r})")
        if saved.settings != self.settings:
            raise InputError(
                str(where),
                0,
                "",
                f"checkpoint made with other settings ({_first_difference(self.settings, saved.settings)}); "
                "give the same options (a version with other defaults reads as other settings too)",
            )
        try:
            left = saved.engine.state.left  # estimators that left at a second robot's start
            self.estimators = [e for e in self.estimators if e.name not in left]
            self.tracks = {name: track for name, track in self.tracks.items() if name not in left}
            if sorted(saved.tracks) != sorted(self.tracks):
                raise ValueError("the checkpoint holds other estimators")
            self.engine.restore(saved.engine)
            self.tracks.update(saved.tracks)
            self.step_times.extend(saved.step_times)
            self.sighting_ids.extend(saved.sighting_ids)
            self.without_id = saved.without_id
            self.not_in_map = saved.not_in_map
            self.skipped.by_reason.update(saved.skipped)
            if saved.consumed:
                self._resumption = _Resumption(folder, saved.consumed, saved.fingerprint)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise InputError(str(where), 0, "", f"not a usable checkpoint: inconsistent state ({exc})") from None

    def run(self) -> None:
        """Push every event of the source through the engine, then close it.

        A bad line part-way, or a checkpoint that cannot be written, ends the run there: ``error`` holds it.

        Raises:
            InputError: The input is bad before the first step is complete, or holds no pose; a resumed run's
                source differs from its checkpoint's.
        """
        self._catch_up()
        try:
            for event in self._events:
                self._position.take(event)
                if self._map_only is not None and _off_map(event, self._map_only):
                    self.not_in_map += 1
                    continue
                self.units.take(event)
                records = self.engine.push(event)
                for record in records:
                    self._take(record)
                    self._suspect(self.units.step(record, self.skipped.by_reason, self._position.consumed))
                if records and self._interrupted():  # at a step's end
                    break
            else:
                self._interrupted()  # a live source ends when asked to stop
        except InputError as exc:
            if self.engine.steps == 0 and self.engine.frontend.pending is None:
                raise
            self.error = str(exc)
        except (_CheckpointFailure, SuspectInput) as exc:
            self.error = str(exc)
            if isinstance(exc, _CheckpointFailure):
                self._checkpoint = None  # no more writes: the last one written stays
        try:
            while (last := self.engine.close()) is not None:  # several robots: a step per robot is left
                self._take(last)
        except _CheckpointFailure as exc:
            self.error = str(exc)
        if self.engine.steps == 0:
            raise InputError(self.source, 0, "", "the stream holds no pose")
        try:
            self._suspect(self.units.judge(self.skipped.by_reason, self._position.consumed))
        except SuspectInput as exc:
            self.error = self.error or str(exc)
        batch = any(isinstance(e, BatchEstimator) for e in self.estimators)
        self._tell(f"batch: solving {counted(self.engine.steps, 'pose')}" if batch else "scoring")

    def _interrupted(self) -> bool:
        """Whether to stop here (``stop`` says so): then ``error`` says :data:`INTERRUPTED`, and a checkpoint is
        written, so that the run is resumable from here, not only from the last periodic one."""
        if self._stop is None or not self._stop():
            return False
        self.error = INTERRUPTED
        if self._checkpoint is not None:
            self._save(self._checkpoint)
        return True

    def _suspect(self, message: str | None) -> None:
        """Give the warning about suspect input (once); with ``strict``, raise it instead."""
        if message is None:
            return
        self.warning = message
        if self._strict:
            raise SuspectInput(f"{message} (--strict)")
        if self._on_warning is not None:
            self._on_warning(message)

    def _tell(self, phase: str | None = None) -> None:
        """Tell the progress sinks how much of the source is read, or what runs once it is."""
        if not self._watchers:
            return
        progress = ReplayProgress(self._position.consumed + sum(self.skipped.by_reason.values()), self._total, phase)
        for sink in self._watchers:
            sink.on_progress(progress)

    def _catch_up(self) -> None:
        """Read again the events a resumed checkpoint had consumed; they must be the same."""
        if self._resumption is None:
            return
        self.skipped.muted = True  # counted before the checkpoint was written
        for event in itertools.islice(self._events, self._resumption.consumed):
            self._position.take(event)
        self.skipped.muted = False
        if self._position.fingerprint != self._resumption.fingerprint:
            raise InputError(
                str(self._resumption.folder), 0, "", "checkpoint of another source (its events differ from this one's)"
            )

    def _take(self, record: StepRecord | None) -> None:
        """Record a complete step, give it to the sinks, and write a checkpoint when one is due."""
        if record is None:
            return
        if len(self.tracks) > len(record.snapshots) - 1:  # estimators left (one robot at a time): dead reckoning aside
            self.estimators = [e for e in self.estimators if e.name in record.snapshots]
            self.tracks = {name: track for name, track in self.tracks.items() if name in record.snapshots}
            if not self.tracks:
                raise OnlineSlamError(
                    f"several robots: the {', '.join(self.engine.state.left)} takes one robot at a time"
                )
        self.step_times.append(record.step.t)
        if self.association != "known":
            self.sighting_ids.extend(record.step.landmarks)
        self.without_id += record.step.landmarks.count(None)
        for name, track in self.tracks.items():
            track.record(record.snapshots[name], record.seconds[name])
        if self._sinks:
            snapshots = {n: dataclasses.replace(s, wall_s=record.seconds[n]) for n, s in record.snapshots.items()}
            for sink in self._sinks:
                sink.on_step(record.step, snapshots, self.engine.frontend.truth)
            self._tell()
        if self._checkpoint is not None and self.engine.steps % self._checkpoint.every == 0:
            self._save(self._checkpoint)
        crash_point("steps", self.engine.steps)

    def _save(self, checkpoint: Checkpointing) -> None:
        state = ReplayCheckpoint(
            self.source, self.settings, self._position.consumed, self._position.fingerprint, self.skipped.by_reason,
            self.engine.checkpoint(), self.tracks, self.step_times, self.sighting_ids, self.without_id, self.not_in_map,
        )  # fmt: skip
        try:
            write_checkpoint(Path(checkpoint.directory) / CHECKPOINT_FILE, "replay", state)
        except OnlineSlamError as exc:  # stop here as at a bad line: report what was estimated
            raise _CheckpointFailure(str(exc)) from None


def _first_difference(here: str, there: str) -> str:
    """Where two settings' texts (``repr`` of a configuration) first differ: the field here and what stands there."""
    at = next((i for i, (a, b) in enumerate(zip(here, there)) if a != b), min(len(here), len(there)))
    begin = max(here.rfind(", ", 0, at + 1) + 2, here.rfind("(", 0, at + 1) + 1)  # the field holding ``at``

    def field(text: str) -> str:
        if at < len(text) and text[at] not in ",)":
            return re.split(r"[,)]", text[begin:], maxsplit=1)[0]
        rest = text[at:].lstrip(", ")  # the texts part at a field's end: here the next field, or none
        return re.split(r"[,)]", rest, maxsplit=1)[0] or "nothing"

    return f"here {field(here)}, there {field(there)}"


def _load_map(config: ReplayConfig, estimators: list[Estimator]) -> LandmarkMap | None:
    """Read ``--map`` and start every estimator from it (None: no map).

    Raises:
        InputError: A bad map file. ConfigError: ``--map-fixed``/``--map-only`` without a map.
    """
    settings = config.map
    if settings.path is None:
        if settings.fixed or settings.only:
            raise ConfigError(f"--map-{'fixed' if settings.fixed else 'only'} needs --map")
        return None
    landmark_map = read_map(settings.path)
    for estimator in estimators:
        estimator.load_map(landmark_map, settings.fixed)  # type: ignore[attr-defined]
    return landmark_map


def _off_map(event: Event, ids: frozenset[LandmarkId]) -> bool:
    """Whether ``--map-only`` skips this event: a landmark sighting of no map landmark (or without an id)."""
    return isinstance(event, Observation) and event.robot_seen is None and event.landmark not in ids


def _ekf_run(config: ReplayConfig, association: str) -> Callable[[Iterable[Event]], tuple[Array, int]]:
    """Runs an EKF of the replay's settings over events: its sightings' NIS in order (NaN for a landmark's first),
    and how many of the first :data:`~online_slam.pipeline.units.FIRST` repeated ones its gate rejected."""

    def run(events: Iterable[Event]) -> tuple[Array, int]:
        from online_slam.estimators.ekf import EkfSlam

        alone = dataclasses.replace(config, estimators=("ekf",), extra_smoothers=())
        ekf = EkfSlam(alone.with_association(association).ekf)
        engine = Engine([ekf], config.frontend)
        nis: list[Array] = []
        rejected = 0

        def take(record: StepRecord | None) -> None:
            nonlocal rejected
            if record is None:
                return
            info = record.snapshots[ekf.name].info
            if sum(int(np.isfinite(v).sum()) for v in nis) < FIRST:
                rejected += len(info.get("gated", ()))
            nis.append(np.asarray(info.get("nis", ()), dtype=float))

        for event in events:
            for record in engine.push(event):
                take(record)
        while (last := engine.close()) is not None:
            take(last)
        return (np.concatenate(nis) if nis else np.zeros(0)), rejected

    return run
