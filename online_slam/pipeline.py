"""The replay pipeline: source -> events -> engine (front-end steps, estimators) -> snapshots -> sinks.

:func:`replay` is the library call behind ``online-slam replay``; it returns one :class:`Results` that the table,
the JSON file and later sinks all read.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.checkpoint import read_checkpoint, write_checkpoint
from online_slam.engine import Engine, EngineCheckpoint, StepRecord
from online_slam.errors import InputError, OnlineSlamError
from online_slam.estimators.batch import BatchConfig, BatchEstimator
from online_slam.estimators.dead_reckoning import DeadReckoning
from online_slam.estimators.ekf import EkfConfig, EkfSlam
from online_slam.estimators.landmark_book import ASSOCIATION_CHOICES
from online_slam.estimators.presets import smoother_label
from online_slam.estimators.protocol import Estimate, Estimator, Snapshot
from online_slam.estimators.smoother import SlidingWindowSmoother, SmootherConfig
from online_slam.evaluation.association import majority, score_association, true_labels, with_true_ids
from online_slam.evaluation.results import EstimatorResult, InputReport, OdometryResult, Results, Series
from online_slam.evaluation.scoring import evaluate, online_figures, outlier_report, truth_array
from online_slam.frontend.steps import FrontEndConfig
from online_slam.importers.resolve import open_source
from online_slam.sinks.protocol import ReplaySink
from online_slam.sources.events import Event, LandmarkId, Observation, Scan
from online_slam.sources.validate import validate_events

Array = NDArray[np.float64]

ESTIMATORS = ("ekf", "smoother", "batch")
"""Names of the estimators ``replay`` can run (all run by default)."""


@dataclass(frozen=True)
class ReplayConfig:
    """What a replay runs and how it is evaluated."""

    estimators: tuple[str, ...] = ESTIMATORS
    """Estimators to run beside dead reckoning, by name."""
    frontend: FrontEndConfig = field(default_factory=FrontEndConfig)
    """How events become steps (keyframing, first-observation-only ablation)."""
    ekf: EkfConfig = field(default_factory=EkfConfig)
    """Settings of the EKF."""
    smoother: SmootherConfig = field(default_factory=SmootherConfig)
    """Settings of the sliding-window smoother."""
    extra_smoothers: tuple[SmootherConfig, ...] = ()
    """Further smoother configurations run side by side, each named by what its window is
    (:func:`~online_slam.estimators.presets.smoother_label`)."""
    batch: BatchConfig = field(default_factory=BatchConfig)
    """Settings of the batch solver."""
    alignment: str = "anchor"
    """Frame for errors: ``anchor`` (first pose with truth) or ``se2`` (least-squares rigid alignment)."""
    dataset: dict = field(default_factory=dict)
    """Options for dataset sources: ``format``, ``robot`` (MRCLAM), ``truth``, ``dt``, ``convention``."""
    association: str = "auto"
    """Data association: ``known`` (the stream's ids; a sighting without one is associated by JCBB), ``nn`` or
    ``jcbb`` (every sighting associated by each online estimator against its own belief; ids only score it;
    batch solves with the associations of the estimate it starts from), or ``auto`` (default): ``known`` when the
    stream's first sighting has an id, else ``jcbb``."""
    on_error: str = "stop"
    """A bad line of a stream file or stdin: ``stop`` the replay there (figures cover what came before), or
    ``skip`` it and go on (counted in ``Results.input``; the results equal those of the stream without it)."""

    def __post_init__(self) -> None:
        if self.on_error not in ("stop", "skip"):
            raise OnlineSlamError(f"on_error must be 'stop' or 'skip', not {self.on_error!r}")
        if self.association not in ("auto", *ASSOCIATION_CHOICES):
            raise OnlineSlamError(
                f"association must be one of auto, {', '.join(ASSOCIATION_CHOICES)}, not {self.association!r}"
            )

    def with_association(self, method: str) -> ReplayConfig:
        """This configuration with every estimator set to associate by ``method`` (``known``, ``nn``, ``jcbb``)."""
        config = dataclasses.replace(
            self,
            association=method,
            ekf=_associating(self.ekf, method),
            smoother=_associating(self.smoother, method),
            extra_smoothers=tuple(_associating(s, method) for s in self.extra_smoothers),
            batch=dataclasses.replace(self.batch, use_ids=method == "known"),
        )
        if method != "known" and "batch" in config.estimators:
            online = {"ekf", "smoother"} & set(config.estimators) or config.extra_smoothers
            if config.batch.initial == "odometry" or not online:
                raise OnlineSlamError(
                    "batch without ids solves with the associations of an EKF or a smoother of the same run: "
                    "run one, and do not start batch from odometry"
                )
        return config


def _associating(config: Any, method: str) -> Any:
    """An EKF or smoother configuration with its association method replaced."""
    return dataclasses.replace(config, association=dataclasses.replace(config.association, method=method))


def first_sighting_has_id(events: Iterable[Event]) -> tuple[bool, Iterable[Event]]:
    """Whether the stream's first sighting carries a landmark id, and the same events to read from the start.

    Events are read up to the first observation or scan (buffered and replayed); a stream without any sighting
    counts as having ids.
    """
    iterator = iter(events)
    buffered: list[Event] = []
    has_id = True
    for event in iterator:
        buffered.append(event)
        if isinstance(event, Observation):
            has_id = event.landmark is not None
            break
        if isinstance(event, Scan) and event.landmarks:
            has_id = event.landmarks[0] is not None
            break
    return has_id, itertools.chain(buffered, iterator)


def make_estimator(name: str, config: ReplayConfig) -> Estimator:
    """Build an estimator by name."""
    if name == "ekf":
        return EkfSlam(config.ekf)
    if name == "smoother":
        return SlidingWindowSmoother(config.smoother)
    if name == "batch":
        return BatchEstimator(config.batch)
    raise OnlineSlamError(f"unknown estimator {name!r}; expected one of {', '.join(ESTIMATORS)}")


def build_estimators(config: ReplayConfig) -> list[Estimator]:
    """The estimators a replay with this configuration runs, in table order (extra smoothers after the rest)."""
    estimators = [make_estimator(n, config) for n in config.estimators]
    for extra in config.extra_smoothers:
        estimators.append(SlidingWindowSmoother(extra, name=smoother_label(extra)))
    names = [e.name for e in estimators]
    if len(set(names)) != len(names):
        raise OnlineSlamError(f"estimator names repeat: {', '.join(names)}")
    return estimators


def estimator_names(config: ReplayConfig) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Names of the estimators a replay runs: (online ones, dead reckoning first; those with a final estimate only)."""
    estimators = build_estimators(config)
    online = ("odometry", *(e.name for e in estimators if e.online))
    return online, tuple(e.name for e in estimators if not e.online)


@dataclass(eq=False)
class _Track:
    """What the pipeline records of one estimator while it runs (a checkpoint holds it)."""

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


@dataclass(frozen=True)
class Checkpointing:
    """Where and how often a replay saves its whole state (see :func:`replay`)."""

    directory: Path
    """Folder of the checkpoint (``replay.ckpt`` inside it, replaced atomically each time)."""
    every: int = 100
    """Steps between checkpoints (>= 1)."""

    def __post_init__(self) -> None:
        if self.every < 1:
            raise OnlineSlamError("--checkpoint-every must be >= 1")


class _CheckpointFailure(OnlineSlamError):
    """A checkpoint could not be written: the replay stops there and reports what it estimated."""


CHECKPOINT_FILE = "replay.ckpt"
"""Name of the checkpoint file inside a checkpoint folder."""
_FINGERPRINT_EVENTS = 1000


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
class _ReplayCheckpoint:
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
    tracks: dict[str, _Track]
    """What was recorded of each estimator, by name."""
    step_times: list[float]
    """Time of each complete step."""
    sighting_ids: list[LandmarkId | None]
    """The stream's id of every sighting (association scoring)."""


def replay(
    source: str | Path | Iterable[Event],
    config: ReplayConfig | None = None,
    *,
    name: str | None = None,
    sinks: Sequence[ReplaySink] = (),
    on_skip: Callable[[InputError], None] | None = None,
    checkpoint: Checkpointing | None = None,
    resume: str | Path | None = None,
    validate: bool = True,
) -> Results:
    """Replay a stream through the front-end and the estimators, step by step, and evaluate.

    Args:
        source: A built-in world name, a stream path (``.gz`` allowed), ``-`` for stdin, or an iterable of events.
        config: What to run; defaults run dead reckoning, the EKF, the smoother and the batch solver.
        name: Source name for reports (defaults to the path or world name).
        sinks: Given every step with all estimators' snapshots (``wall_s`` set), then the results.
        on_skip: With ``config.on_error == "skip"``, told of each skipped line (e.g. to print it).
        checkpoint: Save the whole state (estimators, position in the source, figures gathered so far) every
            ``checkpoint.every`` steps, atomically.
        resume: A checkpoint folder: continue the same source, with the same settings, from there. The source
            is read again from its start and the events the checkpoint had consumed are skipped (and checked
            against its fingerprint); the figures equal those of a run that never stopped (timings aside).
        validate: Check events given as an iterable (objects or ``dict`` records) by the stream's rules, as a
            file's lines are (an item's position stands for its line). False trusts them: for events this package
            generates (its worlds), whose checks would only cost time.

    Returns:
        The results. When the input turns bad part-way, or a checkpoint cannot be written, the results cover
        every step before that and ``Results.error`` holds the message (the last checkpoint written stays).

    Raises:
        InputError: When the input is bad before the first step is complete (nothing to report); a damaged
            checkpoint, one of another source, of other settings or of another format version.
    """
    cfg = config or ReplayConfig()
    skipped: dict[str, int] = {}
    position = _SourcePosition()
    catching_up = 0  # events still to skip when resuming

    def skip(error: InputError) -> None:
        if catching_up:  # counted before the checkpoint was written
            return
        skipped[error.reason] = skipped.get(error.reason, 0) + 1
        if on_skip is not None:
            on_skip(error)

    if isinstance(source, (str, Path)):
        label, events = open_source(source, skip if cfg.on_error == "skip" else None, **dict(cfg.dataset))
    else:
        checked = validate_events(source, skip if cfg.on_error == "skip" else None) if validate else iter(source)
        label, events = "<events>", checked
    label = name or label
    method = cfg.association
    if method == "auto":
        has_id, events = first_sighting_has_id(events)
        method = "known" if has_id else "jcbb"
    run_cfg = cfg.with_association(method)
    estimators = build_estimators(run_cfg)
    sighting_ids: list = []  # the stream's id of every sighting, to score association (nn/jcbb) with
    odometry = DeadReckoning()
    engine = Engine([odometry, *estimators], cfg.frontend)
    tracks = {e.name: _Track() for e in estimators}
    step_times: list[float] = []
    settings = repr(cfg)
    expected_fingerprint = None
    if resume is not None:
        where = Path(resume) / CHECKPOINT_FILE
        saved = read_checkpoint(where, "replay", _ReplayCheckpoint)
        if saved.source != label:
            raise InputError(str(where), 0, "", f"checkpoint of another source ({saved.source!r}, not {label!r})")
        if saved.settings != settings:
            raise InputError(str(where), 0, "", "checkpoint made with other settings; give the same options")
        try:
            if sorted(saved.tracks) != sorted(tracks):
                raise ValueError("the checkpoint holds other estimators")
            engine.restore(saved.engine)
            tracks.update(saved.tracks)
            step_times.extend(saved.step_times)
            sighting_ids.extend(saved.sighting_ids)
            skipped.update(saved.skipped)
            catching_up, expected_fingerprint = saved.consumed, saved.fingerprint
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise InputError(str(where), 0, "", f"not a usable checkpoint: inconsistent state ({exc})") from None

    def save() -> None:
        assert checkpoint is not None
        state = _ReplayCheckpoint(
            label, settings, position.consumed, position.fingerprint, skipped, engine.checkpoint(), tracks,
            step_times, sighting_ids,
        )  # fmt: skip
        try:
            write_checkpoint(Path(checkpoint.directory) / CHECKPOINT_FILE, "replay", state)
        except OnlineSlamError as exc:  # stop here as at a bad line: report what was estimated
            raise _CheckpointFailure(str(exc)) from None

    def take(record: StepRecord | None) -> None:
        if record is None:
            return
        step_times.append(record.step.t)
        if method != "known":
            sighting_ids.extend(record.step.landmarks)
        for estimator_name, track in tracks.items():
            track.record(record.snapshots[estimator_name], record.seconds[estimator_name])
        if sinks:
            snapshots = {n: dataclasses.replace(s, wall_s=record.seconds[n]) for n, s in record.snapshots.items()}
            for sink in sinks:
                sink.on_step(record.step, snapshots, engine.frontend.truth)
        if checkpoint is not None and engine.steps % checkpoint.every == 0:
            save()

    events = iter(events)
    if catching_up:  # read again what the checkpoint had consumed; it must be the same
        for event in itertools.islice(events, catching_up):
            position.take(event)
        catching_up = 0
        if position.fingerprint != expected_fingerprint:
            raise InputError(str(resume), 0, "", "checkpoint of another source (its events differ from this one's)")
    error: str | None = None
    try:
        for event in events:
            position.take(event)
            take(engine.push(event))
    except InputError as exc:
        if engine.steps == 0 and engine.frontend.pending is None:
            raise
        error = str(exc)
    except _CheckpointFailure as exc:
        error, checkpoint = str(exc), None  # no more writes: the last one written stays
    try:
        take(engine.close())
    except _CheckpointFailure as exc:
        error = str(exc)
    steps = engine.steps
    if steps == 0:
        raise InputError(label, 0, "", "the stream holds no pose")
    truth = engine.frontend.truth
    header_meta = engine.frontend.header.meta if engine.frontend.header is not None else {}
    estimates: dict[str, Estimate] = {"odometry": odometry.finish()}
    ordered = sorted(estimators, key=lambda e: isinstance(e, BatchEstimator))  # batch may start from another
    figures: dict[str, EstimatorResult] = {}
    series: dict[str, Series] = {}
    for estimator in ordered:
        track = tracks[estimator.name]
        started = time.perf_counter()
        source = cfg.batch.initial
        if source == "auto":  # the (first) smoother's estimate, else the EKF's, else composed odometry
            smoothers = [n for n in estimates if n.startswith("smoother")]
            source = smoothers[0] if smoothers else "ekf" if "ekf" in estimates else "odometry"
        initial = estimates.get(source) if isinstance(estimator, BatchEstimator) and source != "odometry" else None
        if isinstance(estimator, BatchEstimator) and source != "odometry" and initial is None:
            raise OnlineSlamError(f"batch initial values from {source!r}, which did not run")
        estimate = estimator.finish(initial) if initial is not None else estimator.finish()
        final_s = time.perf_counter() - started
        estimates[estimator.name] = estimate
        details = dict(estimate.info)
        rejected = details.pop("rejected", None)
        labels = details.pop("labels", None)
        outliers = association = None
        scored = estimate
        if labels is not None and method != "known":
            truth_labels = true_labels(sighting_ids, truth.outliers)
            owner = majority(labels, truth_labels)
            association = score_association(method, labels, truth_labels, estimate.landmark_ids, owner)
            scored = with_true_ids(estimate, owner)
            rejected = None  # per used sighting, not per stream sighting
        if rejected is not None:
            marked = bool(truth.outliers) or bool(header_meta.get("contamination"))
            outliers = outlier_report(rejected, truth, marked)
        errors = evaluate(scored, truth, cfg.alignment)
        online = None
        if estimator.online:
            online = online_figures(
                estimate,
                np.array(track.poses),
                track.covariances,
                np.array(track.times),
                np.array(track.nis),
                np.array(track.seconds),
                truth,
                cfg.alignment,
            )
            series[estimator.name] = online.series
        figures[estimator.name] = EstimatorResult(
            final_rmse_m=errors.rmse_m,
            endpoint_gap_m=errors.endpoint_gap_m,
            landmark_rmse_m=errors.landmark_rmse_m,
            total_s=float(np.sum(track.seconds)) + final_s,
            online_rmse_m=None if online is None else online.rmse_m,
            nees_mean=None if online is None else online.nees_mean,
            step_ms=None if online is None else online.latency,
            details=details,
            outliers=outliers,
            association=association,
        )
    odo = evaluate(estimates["odometry"], truth, cfg.alignment)
    results = Results(
        source=label,
        poses=steps,
        landmarks=len(estimates["odometry"].landmark_ids),
        observations=engine.observations,
        odometry=OdometryResult(odo.rmse_m, odo.endpoint_gap_m, odo.landmark_rmse_m),
        estimators=figures,
        estimates=estimates,
        alignment=cfg.alignment,
        series=series,
        truth_poses=truth_array(truth, steps),
        truth_landmarks=dict(truth.landmarks),
        error=error,
        input=InputReport(sum(skipped.values()), skipped),
        step_times=np.array(step_times, dtype=float),
        robot=header_meta.get("robot"),
    )
    for sink in sinks:
        sink.on_finish(results, truth)
    return results
