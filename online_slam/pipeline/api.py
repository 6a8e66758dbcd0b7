"""The library call behind ``online-slam replay``: :func:`replay` (see the package's docstring)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from online_slam.errors import InputError
from online_slam.evaluation.results import Results
from online_slam.pipeline.config import Checkpointing, ReplayConfig
from online_slam.pipeline.noise import Fit, fit_source_noise, fits_noise, with_noise_fit
from online_slam.pipeline.run import ReplayRun
from online_slam.pipeline.score import score_run
from online_slam.pipeline.source import open_events
from online_slam.sinks.protocol import ProgressSink, ReplaySink
from online_slam.sources.events import Event


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
    on_noise_fit: Callable[[Fit], None] | None = None,
    stop: Callable[[], bool] | None = None,
    on_warning: Callable[[str], None] | None = None,
) -> Results:
    """Replay a stream through the front-end and the estimators, step by step, and evaluate.

    Args:
        source: A built-in world name, a stream path (``.gz`` allowed), ``-`` for stdin, ``tcp://HOST:PORT`` (listen
            there: :mod:`online_slam.sources.tcp`), or an iterable of events.
        config: What to run; defaults run dead reckoning, the EKF, the smoother and the batch solver.
        name: Source name for reports (defaults to the path or world name).
        sinks: Given every step with all estimators' snapshots (``wall_s`` set), then the results; progress sinks
            are also told how much of the source is read (counted up front for them) and what runs after.
        on_skip: With ``config.on_error == "skip"``, told of each skipped line (e.g. to print it).
        checkpoint: Save the whole state (estimators, position in the source, figures gathered so far) every
            ``checkpoint.every`` steps, atomically.
        resume: A checkpoint folder: continue the same source, with the same settings, from there. The source
            is read again from its start and the events the checkpoint had consumed are skipped (and checked
            against its fingerprint); the figures equal those of a run that never stopped (timings aside).
        validate: Check events given as an iterable (objects or ``dict`` records) by the stream's rules, as a
            file's lines are (an item's position stands for its line). False trusts them: for events this package
            generates (its worlds), whose checks would only cost time.
        on_noise_fit: With ``--noise fit`` or ``--noise self`` (``config.dataset["noise"]``), told of the fit
            before the replay, which runs with its scales (see :mod:`online_slam.pipeline.noise`).
        stop: Asked after each step (and by a TCP source while it waits); True ends the replay there, scored like a
            stream that ended there, with ``Results.error`` ``"interrupted"`` (how ``online-slam replay`` keeps its
            work on Ctrl-C).
        on_warning: Told, once, when most of the first sightings are rejected or lines skipped, with the likely
            cause (wrong units?); also in ``Results.warning``. With ``config.strict`` the replay stops there
            instead, ``Results.error`` saying why.

    Returns:
        The results. When the input turns bad part-way, or a checkpoint cannot be written, the results cover
        every step before that and ``Results.error`` holds the message (the last checkpoint written stays).

    Raises:
        InputError: When the input is bad before the first step is complete (nothing to report); a damaged
            checkpoint, one of another source, of other settings or of another format version.
        OnlineSlamError: ``--noise fit`` or ``self`` on standard input; ``fit`` on a source without truth, ``self``
            on one without a landmark sighting with an id.
    """
    cfg = config or ReplayConfig()
    if fits_noise(cfg):
        fit, source = fit_source_noise(source, cfg)
        cfg = with_noise_fit(cfg, fit)
        if on_noise_fit is not None:
            on_noise_fit(fit)
    watched = any(isinstance(sink, ProgressSink) for sink in sinks)
    opened = open_events(source, cfg, name=name, on_skip=on_skip, validate=validate, count=watched, stop=stop)
    run = ReplayRun(opened, cfg, sinks, checkpoint, stop, on_warning)
    if resume is not None:
        run.resume(resume)
    run.run()
    results = score_run(run, cfg)
    for sink in sinks:
        sink.on_finish(results, run.engine.frontend.truth)
    return results
