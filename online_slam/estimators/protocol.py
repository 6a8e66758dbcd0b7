"""The one protocol every estimator follows, and the immutable records they return."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from online_slam.frontend.steps import Step
from online_slam.sources.events import LandmarkId

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Snapshot:
    """What an estimator knows right after consuming one step (M landmarks known so far)."""

    estimator: str
    """Name of the estimator that produced it."""
    index: int
    """Index of the step just consumed (the newest pose)."""
    t: float
    """Time of that step, seconds."""
    pose: Array
    """Current estimate of the newest pose, shape (3,)."""
    pose_cov: Array | None
    """Its covariance, shape (3, 3), or None when the estimator has none."""
    landmark_ids: tuple[LandmarkId, ...]
    """Ids of the landmarks known so far, length M."""
    landmarks: Array
    """Their current estimates, shape (M, 2)."""
    landmark_covs: Array | None = None
    """Their 2x2 marginal covariances, shape (M, 2, 2), or None."""
    info: Mapping[str, Any] = field(default_factory=dict)
    """Estimator-specific figures for this step (e.g. NIS, gated observations, iterations)."""
    wall_s: float | None = None
    """Wall time the estimator spent on this step, seconds (set by the pipeline that timed it)."""


@dataclass(frozen=True)
class Estimate:
    """An estimator's final answer over the whole stream (N poses, M landmarks)."""

    estimator: str
    """Name of the estimator."""
    poses: Array
    """Final estimate of every pose, shape (N, 3)."""
    landmark_ids: tuple[LandmarkId, ...]
    """Landmark ids, length M."""
    landmarks: Array
    """Final landmark estimates, shape (M, 2)."""
    info: Mapping[str, Any] = field(default_factory=dict)
    """Solver report (iterations, convergence, costs...)."""
    landmark_covs: Array | None = None
    """Final 2x2 landmark marginal covariances, shape (M, 2, 2), where the estimator has them."""


@runtime_checkable
class Estimator(Protocol):
    """Consumes steps one at a time; ``finish`` closes the stream and returns the final estimate.

    ``step`` takes a new pose (with its odometry and the sightings known so far); ``extend`` takes further
    sightings of that newest pose. Results depend only on what was given, in which calls: the engine
    (:class:`~online_slam.engine.Engine`) gives each complete step in one ``step`` call unless a query asked for
    the newest pose earlier.
    """

    name: str
    online: bool
    """True when step snapshots are real-time estimates (online figures are computed from them)."""

    def step(self, step: Step) -> Snapshot:
        """Consume the next step (indices arrive in order 0, 1, 2, ...) and report the current estimate."""
        ...

    def extend(self, step: Step, start: int) -> Snapshot:
        """The newest step grew (same index, pose and odometry): its observations ``start:`` are new.

        The engine calls this when a query made it show a pose to the estimators before all of its sightings
        had arrived; the snapshot covers the whole step.
        """
        ...

    def snapshot(self, step: Step) -> Snapshot:
        """The current estimate, labelled as the newest step ``step`` (no state changes)."""
        ...

    def trajectory(self) -> Array:
        """Current estimate of every pose so far, shape (N, 3)."""
        ...

    def state_dict(self) -> Any:
        """The whole state as a tree (:func:`online_slam.checkpoint.to_tree` of its state dataclasses)."""
        ...

    def load_state(self, state: Any) -> None:
        """Restore a :meth:`state_dict` into an estimator built with the same configuration."""
        ...

    def finish(self) -> Estimate:
        """End of stream: return the final estimate."""
        ...
