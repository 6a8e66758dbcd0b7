"""The one protocol every estimator follows, and the immutable records they return."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from online_slam.frontend.steps import Step
from online_slam.sources.events import LandmarkId, RobotId

Array = NDArray[np.float64]

RobotPose = tuple[int, float, Array, Array]
"""A robot's newest pose in an estimator: its step index, its time, ``[x, y, theta]`` (3,), its covariance (3, 3)."""


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
    landmark_joint: Array | None = None
    """Final joint covariance of the landmarks, shape (2M, 2M) (rows ``[x0, y0, x1, ...]``), where the estimator
    has it (a saved map keeps it: :class:`~online_slam.sources.landmark_map.LandmarkMap`)."""


@runtime_checkable
class Estimator(Protocol):
    """Consumes steps one at a time; ``finish`` closes the stream and returns the final estimate.

    ``step`` takes a new pose (with its odometry and the sightings known so far); ``extend`` takes further
    sightings of that newest pose. Results depend only on what was given, in which calls: the engine
    (:class:`~online_slam.engine.Engine`) gives each complete step in one ``step`` call unless a query asked for
    the newest pose earlier.

    The engine reads ``several_robots`` with ``getattr``, False where it is missing: an estimator of one's own
    without it runs, and leaves the engine when a second robot begins.
    """

    name: str
    """The estimator's name, unique among the estimators of one engine (e.g. ``ekf``, ``smoother W=20 K=1``)."""
    online: bool
    """True when step snapshots are real-time estimates (online figures are computed from them)."""
    several_robots: bool
    """True when it takes several robots' steps in one stream (one index over all robots' poses)."""

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


@runtime_checkable
class SlamEstimator(Estimator, Protocol):
    """An estimator that :class:`~online_slam.slam.Slam` runs (the EKF, the sliding-window smoother): an
    :class:`Estimator` that also gives its whole current state at any query, without changing it (N poses so far,
    M landmarks)."""

    def landmark_marginals(self) -> Array:
        """The current 2x2 marginal covariance of every landmark, shape (M, 2, 2), in the order of a snapshot's
        ``landmark_ids`` taken now (NaN where the estimator's system is singular)."""
        ...

    def trajectory_parts(self) -> tuple[Array, Array]:
        """The current estimate of every pose so far in two parts, shapes (N0, 3) and (N - N0, 3): the poses that no
        longer change (a read-only view of the estimator's own array) and those that still may (a copy); with
        several robots, (0, 3) and every pose in step order. Their concatenation is :meth:`trajectory`."""
        ...

    def robot_poses(self) -> dict[RobotId | None, RobotPose]:
        """Each robot's newest pose by robot (None: the stream's one unnamed robot): its step index, its time, its
        estimate ``[x, y, theta]`` (3,) and its covariance (3, 3), as copies."""
        ...
