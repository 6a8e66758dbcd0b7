"""The engine: validated events in, one snapshot per estimator and step out — the one way in.

:class:`Engine` drives the front-end and any set of estimators together. ``replay``, ``compare``, the
benchmarks and the library class :class:`~online_slam.slam.Slam` all push events through it.

When a step is complete (the next odometry arrives, or the stream ends) every estimator gets it in one
``step`` call, exactly as a replay always did. A query (:meth:`Engine.sync`) may come earlier: then the newest
pose is shown to the estimators at once with the sightings it has so far, and later sightings of that pose
reach them through ``extend``. So an estimate never lags the sensors; and a replay, which queries only at
complete steps, gives the same numbers whether or not anyone queries it that way.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from online_slam.estimators.protocol import Estimator, Snapshot
from online_slam.frontend.steps import FrontEnd, FrontEndConfig, PendingStep, Step
from online_slam.sources.events import Event, Header


@dataclass(frozen=True)
class StepRecord:
    """A complete step and what every estimator made of it."""

    step: Step
    """The step (pose index, odometry, all of its observations)."""
    snapshots: dict[str, Snapshot]
    """Each estimator's estimate right after the step, by name."""
    seconds: dict[str, float]
    """Wall time each estimator spent on this step (all of its calls), by name."""


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
        self.steps = 0
        """Complete steps so far."""
        self.observations = 0
        """Observations in complete steps so far."""
        self.records = records
        self._given = -1  # observations of the pending step the estimators have (-1: not even its pose)
        self._latest: dict[str, Snapshot] = {}
        self._seconds: dict[str, float] = {}

    def push(self, event: Event) -> StepRecord | None:
        """Consume one validated event.

        Returns:
            The step it completed (an odometry event completes the previous pose), with every estimator's
            snapshot, or None.
        """
        completed = self.frontend.push(event)
        return None if completed is None else self._complete(completed)

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
        if self._given >= 0 and k == self._given:
            return
        given, latest = self._given, self._latest
        for estimator in self.estimators:
            if not self.records:
                latest[estimator.name] = estimator.step(step) if given < 0 else estimator.extend(step, given)
                continue
            started = time.perf_counter()
            latest[estimator.name] = estimator.step(step) if given < 0 else estimator.extend(step, given)
            elapsed = time.perf_counter() - started
            self._seconds[estimator.name] = self._seconds.get(estimator.name, 0.0) + elapsed
        self._given = k

    def _complete(self, step: Step) -> StepRecord | None:
        self._deliver(step)
        self.steps += 1
        self.observations += len(step.landmarks)
        if not self.records:
            self._given, self._latest = -1, {}
            return None
        for estimator in self.estimators:  # after a checkpoint was loaded mid-step, nothing new to deliver
            if estimator.name not in self._latest:
                self._latest[estimator.name] = estimator.snapshot(step)
                self._seconds.setdefault(estimator.name, 0.0)
        record = StepRecord(step, self._latest, self._seconds)
        self._given, self._latest, self._seconds = -1, {}, {}
        return record

    # -- checkpoints -------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """The front-end's position and every estimator's state (numbers, strings, lists, dicts, arrays)."""
        fe = self.frontend
        pending = fe.pending
        return {
            "steps": self.steps,
            "observations": self.observations,
            "given": self._given,
            "seconds": dict(self._seconds),
            "frontend": {
                "header": None if fe.header is None else {"name": fe.header.name, "meta": fe.header.meta},
                "truth_indices": np.array(list(fe.truth.poses), dtype=np.int64),
                "truth_poses": np.array(list(fe.truth.poses.values()), dtype=float).reshape(-1, 3),
                "truth_landmark_ids": list(fe.truth.landmarks),
                "truth_landmarks": np.array(list(fe.truth.landmarks.values()), dtype=float).reshape(-1, 2),
                "counts": dict(fe.counts),
                "sightings": fe.sightings,
                "outliers": {str(k): v for k, v in fe.truth.outliers.items()},
                "seen": list(fe._seen),
                "pending": None if pending is None else _pending_state(pending),
            },
            "estimators": {e.name: e.state_dict() for e in self.estimators},
        }

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict` into an engine built with the same estimators and configuration."""
        if sorted(state["estimators"]) != sorted(e.name for e in self.estimators):
            raise ValueError("the checkpoint holds other estimators")
        self.steps, self.observations = int(state["steps"]), int(state["observations"])
        self._given = int(state["given"])
        self._seconds = {str(k): float(v) for k, v in state["seconds"].items()}
        self._latest = {}
        fe, saved = self.frontend, state["frontend"]
        header = saved["header"]
        fe.header = None if header is None else Header(name=header["name"], meta=dict(header["meta"]))
        poses = np.array(saved["truth_poses"], dtype=float).reshape(-1, 3)
        fe.truth.poses = {int(i): p.copy() for i, p in zip(saved["truth_indices"], poses)}
        positions = np.array(saved["truth_landmarks"], dtype=float).reshape(-1, 2)
        fe.truth.landmarks = {lid: p.copy() for lid, p in zip(saved["truth_landmark_ids"], positions)}
        fe.counts = {str(k): int(v) for k, v in saved["counts"].items()}
        fe.sightings = int(saved["sightings"])
        fe.truth.outliers = {int(k): str(v) for k, v in saved["outliers"].items()}
        fe._seen = set(saved["seen"])
        fe.pending = None if saved["pending"] is None else _pending_from(saved["pending"])
        for estimator in self.estimators:
            estimator.load_state(state["estimators"][estimator.name])


def _pending_state(p: PendingStep) -> dict[str, Any]:
    return {
        "index": p.index,
        "t": p.t,
        "t_begin": p.t_begin,
        "odometry": p.odometry,
        "odometry_cov": p.odometry_cov,
        "prior": p.prior,
        "prior_cov": p.prior_cov,
        "merged": p.merged,
        "landmarks": list(p.landmarks),
        "z": np.array(p.z, dtype=float).reshape(-1, 2),
        "z_cov": p.z_covariances(),
        "sealed": p.sealed,
    }


def _pending_from(s: dict[str, Any]) -> PendingStep:
    def array(value: Any) -> np.ndarray | None:
        return None if value is None else np.array(value, dtype=float)

    return PendingStep(
        index=int(s["index"]),
        t=float(s["t"]),
        t_begin=float(s["t_begin"]),
        odometry=array(s["odometry"]),
        odometry_cov=array(s["odometry_cov"]),
        prior=array(s["prior"]),
        prior_cov=array(s["prior_cov"]),
        merged=int(s["merged"]),
        landmarks=list(s["landmarks"]),
        z=[(float(r), float(b)) for r, b in np.array(s["z"], dtype=float).reshape(-1, 2)],
        z_noise=[c.copy() for c in np.array(s["z_cov"], dtype=float).reshape(-1, 2, 2)],
        full_covariance=True,
        sealed=bool(s["sealed"]),
    )
