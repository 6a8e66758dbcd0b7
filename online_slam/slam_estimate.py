"""What ``Slam.estimate`` gives: the newest pose, its covariance, the trajectory with its times, the map, and
each robot's part (arrays read-only, captured at query time)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.protocol import Snapshot
from online_slam.sources.events import LandmarkId, RobotId

Array = NDArray[np.float64]

NewestPose = tuple[int, float, Array, Array]
"""A robot's newest pose in an estimator: its step index, its time, ``[x, y, theta]`` (3,), its covariance
(3, 3). An estimator of several robots gives them by robot from ``robot_poses()``."""


@dataclass(frozen=True)
class RobotEstimate:
    """One robot's part of a :class:`SlamEstimate` (arrays read-only)."""

    index: int
    """Index of the robot's newest pose (one index over all robots' poses, in the order they began)."""
    t: float
    """Its time, seconds."""
    pose: Array
    """Its estimate ``[x, y, theta]``, shape (3,)."""
    pose_cov: Array
    """Its covariance, shape (3, 3)."""
    steps: NDArray[np.int64]
    """Indices of the robot's poses in :attr:`SlamEstimate.trajectory`, shape (N_r,)."""
    trajectory: Array
    """Current estimate of each of the robot's poses, shape (N_r, 3); the last row is ``pose``."""


@dataclass(frozen=True)
class SlamEstimate:
    """The estimate after every event added so far. Arrays are read-only; everything is read from data captured
    at query time, and ``trajectory``, ``landmarks`` and ``landmark_covs`` are assembled on first access.

    Before any event there is no pose yet: the estimate is empty, with ``index`` -1, ``t``, ``pose`` and
    ``pose_cov`` NaN, a (0, 3) ``trajectory`` and no landmarks."""

    snapshot: Snapshot
    """The estimator's snapshot after the newest event (its arrays belong to this estimate alone)."""
    landmark_cov_array: Array | None
    """Landmark 2x2 marginal covariances, shape (M, 2, 2), or None when not asked for."""
    trajectory_parts: tuple[Array, Array]
    """Poses that no longer change (a read-only view) and the poses that still may, as of the query."""
    robot_poses: Mapping[RobotId, NewestPose] = field(default_factory=dict)
    """Each named robot's newest pose at the query (empty when the events name no robot)."""
    step_robots: list[RobotId] = field(default_factory=list)
    """The robot of every pose begun by the query, in index order (only appended to afterwards)."""
    trajectory_times: Array = field(default_factory=lambda: _read_only(np.zeros(0)))
    """Time of each row of ``trajectory``, seconds, shape (N,) (with keyframing, the kept poses' times)."""

    @property
    def t(self) -> float:
        """Time of ``pose``, seconds (NaN before any pose): the newest pose's, or the time it was predicted to (the
        query's ``at``, or the newest odometry not yet in a pose)."""
        return self.snapshot.t

    @property
    def index(self) -> int:
        """Index of the newest pose (0 is the start; -1 before any pose)."""
        return self.snapshot.index

    @cached_property
    def pose(self) -> Array:
        """Newest pose ``[x, y, theta]``, shape (3,) (NaN before any pose), predicted to ``t``."""
        return _locked(self.snapshot.pose)

    @cached_property
    def pose_cov(self) -> Array:
        """Its covariance, shape (3, 3) (NaN where the estimator has none)."""
        cov = self.snapshot.pose_cov
        return _locked(cov) if cov is not None else _read_only(np.full((3, 3), np.nan))

    @property
    def landmark_ids(self) -> tuple[LandmarkId, ...]:
        """Landmark ids in the order of ``landmark_array``, length M."""
        return self.snapshot.landmark_ids

    @cached_property
    def landmark_array(self) -> Array:
        """Landmark positions, shape (M, 2)."""
        return _locked(self.snapshot.landmarks)

    @cached_property
    def trajectory(self) -> Array:
        """Current estimate of every pose so far, shape (N, 3), N = index + 1 (with several robots, all robots'
        poses in index order: see ``robots``)."""
        return _read_only(np.concatenate(self.trajectory_parts))

    @cached_property
    def robots(self) -> Mapping[RobotId, RobotEstimate]:
        """Robot id -> its newest pose, covariance and trajectory, for every named robot the estimator has a pose
        of (in the order they started); empty when the events name no robot."""
        robots = np.array(self.step_robots[: len(self.trajectory)], dtype=object)
        out = {}
        for robot, (index, t, pose, cov) in self.robot_poses.items():
            steps = _read_only_index(np.flatnonzero(robots == robot))
            out[robot] = RobotEstimate(index, t, _locked(pose), _locked(cov), steps, _locked(self.trajectory[steps]))
        return MappingProxyType(out)

    @cached_property
    def landmarks(self) -> Mapping[LandmarkId, Array]:
        """Landmark id -> position ``[x, y]``, shape (2,)."""
        return MappingProxyType(dict(zip(self.landmark_ids, self.landmark_array)))

    @cached_property
    def landmark_covs(self) -> Mapping[LandmarkId, Array] | None:
        """Landmark id -> 2x2 marginal covariance, or None when not asked for."""
        if self.landmark_cov_array is None:
            return None
        return MappingProxyType(dict(zip(self.landmark_ids, self.landmark_cov_array)))


def _read_only(array: Array) -> Array:
    array = np.array(array, dtype=float)
    array.flags.writeable = False
    return array


def _read_only_index(array: NDArray[np.int64]) -> NDArray[np.int64]:
    array.flags.writeable = False
    return array


def _locked(array: Array) -> Array:
    """Make an array that only this estimate refers to (a snapshot's copy) read-only, without copying it."""
    array.flags.writeable = False
    return array


def empty_estimate(estimator: str, landmark_covs: bool) -> SlamEstimate:
    """The estimate before any pose: index -1, NaN time and pose, nothing else."""
    nothing = _read_only(np.zeros((0, 3)))
    snapshot = Snapshot(estimator, -1, math.nan, np.full(3, math.nan), None, (), np.zeros((0, 2)))
    covs = _read_only(np.zeros((0, 2, 2))) if landmark_covs else None
    return SlamEstimate(snapshot, covs, (nothing, nothing))
