"""The engine: validated events in, one snapshot per estimator and step out — the one way in.

:class:`Engine` drives the front-end and any set of estimators together. ``replay``, ``compare``, the
benchmarks and the library class :class:`~online_slam.slam.Slam` all push events through it.

When a step is complete (the next odometry arrives, or the stream ends) every estimator gets it in one
``step`` call, exactly as a replay always did. A query (:meth:`Engine.sync`) may come earlier: then the newest
pose is shown to the estimators at once with the sightings it has so far, and later sightings of that pose
reach them through ``extend``. So an estimate never lags the sensors; and a replay, which queries only at
complete steps, gives the same numbers whether or not anyone queries it that way.

When a second robot begins (a step with a start pose after step 0), the estimators that take one robot at a
time (no ``several_robots`` attribute set) leave the engine, named in ``state.left``; if no estimator would be
left, that is one :class:`~online_slam.errors.OnlineSlamError`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from online_slam.errors import OnlineSlamError
from online_slam.estimators.protocol import Estimator, Snapshot
from online_slam.frontend.steps import FrontEnd, FrontEndConfig, Step
from online_slam.sources.events import Event, RobotId, Scan


@dataclass(frozen=True)
class StepRecord:
    """A complete step and what every estimator made of it."""

    step: Step
    """The step (pose index, odometry, all of its observations)."""
    snapshots: dict[str, Snapshot]
    """Each estimator's estimate right after the step, by name."""
    seconds: dict[str, float]
    """Wall time each estimator spent on this step (all of its calls), by name."""


@dataclass(eq=False)
class EngineState:
    """What the engine itself remembers between events (its front-end and estimators hold the rest)."""

    steps: int = 0
    """Complete steps so far."""
    observations: int = 0
    """Observations in complete steps so far."""
    given: int = -1
    """Observations of the pending step the estimators have (-1: not even its pose)."""
    given_fixes: int = 0
    """Absolute fixes of the pending step the estimators have."""
    seconds: dict[str, float] = field(default_factory=dict)
    """Wall time each estimator spent on the pending step so far, by name."""
    left: list[str] = field(default_factory=list)
    """Estimators that left when a second robot began (they take one robot at a time)."""
    times: list[float] = field(default_factory=list)
    """Time of every complete step, in index order."""
    robots: list[RobotId | None] = field(default_factory=list)
    """Robot of every complete step, in index order (None: the stream names none)."""


@dataclass(eq=False)
class EngineCheckpoint:
    """An engine's whole state (:meth:`Engine.checkpoint`, :meth:`Engine.restore`)."""

    state: EngineState
    """The engine's own counters."""
    frontend: FrontEnd
    """The front-end: its position in the stream, truth, the pending pose."""
    estimators: dict[str, Any]
    """Each estimator's ``state_dict()``, by name."""


class Engine:
    """The front-end and a set of estimators, fed one validated event at a time.

    Args:
        estimators: Estimators with distinct names; each sees every step in the same calls.
        frontend: How events become steps (keyframing, first-observation-only).
        records: Time the estimators and return a :class:`StepRecord` for each complete step; False for a
            caller that only queries (:meth:`push` and :meth:`close` then return None).
    """

    def __init__(
        self, estimators: Sequence[Estimator], frontend: FrontEndConfig | None = None, records: bool = True
    ) -> None:
        names = [e.name for e in estimators]
        if len(set(names)) != len(names):
            raise ValueError(f"estimator names repeat: {', '.join(names)}")
        self.estimators = list(estimators)
        self.frontend = FrontEnd(frontend)
        self.state = EngineState()
        self.records = records
        self._latest: dict[str, Snapshot] = {}

    @property
    def steps(self) -> int:
        """Complete steps so far."""
        return self.state.steps

    @property
    def observations(self) -> int:
        """Observations in complete steps so far."""
        return self.state.observations

    def push(self, event: Event | Scan) -> list[StepRecord]:
        """Consume one validated event (or a scan of the library API).

        Returns:
            The steps it completed, in index order, each with every estimator's snapshot: usually none or one (an
            odometry event completes the previous pose); more when it splits an increment at sightings between
            ticks or releases held lines. Empty without ``records``.
        """
        return self._drain(self.frontend.push(event))

    def flush(self, until: float = math.inf) -> list[StepRecord]:
        """Give on every line the front-end's reorder buffer holds (or those older than ``until``); the steps that
        completed (as :meth:`push`)."""
        return self._drain(self.frontend.flush(until))

    def _drain(self, completed: Step | None) -> list[StepRecord]:
        """Complete this step and every other the front-end has complete, in index order."""
        records = []
        while completed is not None:
            record = self._complete(completed)
            if record is not None:
                records.append(record)
            completed = self.frontend.next_complete()
        return records

    def sync(self) -> Mapping[str, Snapshot]:
        """Bring every estimator up to the newest event; their current snapshots by name ({} before any pose).

        The mapping is the engine's own until the step completes: read it, do not change it.
        """
        pending = self.frontend.pending
        if pending is None:
            return {}
        pending.sealed = True
        step = pending.freeze()
        self._deliver(step)
        latest = self._latest
        if len(latest) != len(self.estimators):  # loaded from a checkpoint taken after this very query
            for estimator in self.estimators:
                if estimator.name not in latest:
                    latest[estimator.name] = estimator.snapshot(step)
        return latest

    def close(self) -> StepRecord | None:
        """End of stream: complete the newest step (None if there was no pose)."""
        last = self.frontend.close()
        return None if last is None else self._complete(last)

    def _deliver(self, step: Step) -> None:
        """Give the estimators whatever of this (newest) step they have not seen."""
        k = len(step.landmarks)
        if self.state.given >= 0 and k == self.state.given and len(step.fixes) == self.state.given_fixes:
            return
        given, latest = self.state.given, self._latest
        for estimator in self.estimators:
            if not self.records:
                latest[estimator.name] = estimator.step(step) if given < 0 else estimator.extend(step, given)
                continue
            started = time.perf_counter()
            latest[estimator.name] = estimator.step(step) if given < 0 else estimator.extend(step, given)
            elapsed = time.perf_counter() - started
            self.state.seconds[estimator.name] = self.state.seconds.get(estimator.name, 0.0) + elapsed
        self.state.given, self.state.given_fixes = k, len(step.fixes)

    def _another_robot(self) -> None:
        """A second robot begins: the estimators that take one robot at a time leave."""
        single = [e.name for e in self.estimators if not getattr(e, "several_robots", False)]
        if not single:
            return
        if len(single) == len(self.estimators) or not self.records:
            raise OnlineSlamError(f"several robots: the {', '.join(single)} takes one robot at a time")
        self.estimators = [e for e in self.estimators if e.name not in single]
        self.state.left += single

    def _complete(self, step: Step) -> StepRecord | None:
        if step.prior is not None and step.index > 0:
            self._another_robot()
        self._deliver(step)
        self.state.steps += 1
        self.state.observations += len(step.landmarks)
        self.state.times.append(step.t)
        self.state.robots.append(step.robot)
        if not self.records:
            self.state.given, self.state.given_fixes, self._latest = -1, 0, {}
            return None
        for estimator in self.estimators:  # after a checkpoint was loaded mid-step, nothing new to deliver
            if estimator.name not in self._latest:
                self._latest[estimator.name] = estimator.snapshot(step)
                self.state.seconds.setdefault(estimator.name, 0.0)
        record = StepRecord(step, self._latest, self.state.seconds)
        self.state.given, self.state.given_fixes, self._latest, self.state.seconds = -1, 0, {}, {}
        return record

    # -- checkpoints -------------------------------------------------------------------------------
    def checkpoint(self) -> EngineCheckpoint:
        """The whole state: the engine's, the front-end's and every estimator's (sharing their arrays)."""
        return EngineCheckpoint(self.state, self.frontend, {e.name: e.state_dict() for e in self.estimators})

    def restore(self, saved: EngineCheckpoint) -> None:
        """Continue from a :meth:`checkpoint` of an engine built with the same estimators and configuration."""
        self.estimators = [e for e in self.estimators if e.name not in saved.state.left]
        if sorted(saved.estimators) != sorted(e.name for e in self.estimators):
            raise ValueError("the checkpoint holds other estimators")
        self.state, self.frontend, self._latest = saved.state, saved.frontend, {}
        for estimator in self.estimators:
            estimator.load_state(saved.estimators[estimator.name])
