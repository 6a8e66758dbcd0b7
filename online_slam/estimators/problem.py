"""Accumulates steps into the arrays of a factor graph, with odometry-composed initial values."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from online_slam.factors.graph import FactorGraph
from online_slam.frontend.steps import Step
from online_slam.geometry.se2 import compose
from online_slam.models.range_bearing import landmark_from_observation
from online_slam.sources.events import LandmarkId

Array = NDArray[np.float64]


class ProblemLog:
    """Every factor seen so far, plus initial values: poses by composed odometry, landmarks by first sight.

    Attributes:
        poses: Initial pose values in step order.
        landmark_ids: Landmark ids in order of first observation.
    """

    def __init__(self) -> None:
        self.poses: list[Array] = []
        self.times: list[float] = []
        self.landmark_ids: tuple[LandmarkId, ...] = ()
        self._landmark_index: dict[LandmarkId, int] = {}
        self._landmarks: list[Array] = []
        self.prior: tuple[Array, Array | None] | None = None
        self._odo_delta: list[Array] = []
        self._odo_cov: list[Array] = []
        self._obs_pose: list[Array] = []
        self._obs_landmark: list[Array] = []
        self._obs_z: list[Array] = []
        self._obs_cov: list[Array] = []

    @property
    def landmarks(self) -> Array:
        """Initial landmark values, shape (M, 2)."""
        return np.array(self._landmarks).reshape(-1, 2)

    def landmark_indices(self, ids: tuple[LandmarkId, ...]) -> NDArray[np.int64]:
        """Indices of known landmarks (-1 for unknown ids)."""
        return np.array([self._landmark_index.get(i, -1) for i in ids], dtype=np.int64)

    def add(self, step: Step) -> Array:
        """Record a step; return its initial pose value, shape (3,)."""
        if step.index != len(self.poses):
            raise ValueError(f"steps must arrive in order: expected {len(self.poses)}, got {step.index}")
        if step.odometry is None:
            assert step.prior is not None
            pose = np.array(step.prior, dtype=float)
            self.prior = (pose, step.prior_cov)
        else:
            pose = compose(self.poses[-1], step.odometry)
            self._odo_delta.append(step.odometry)
            self._odo_cov.append(step.odometry_cov)
        self.poses.append(pose)
        self.times.append(step.t)
        if step.landmarks:
            new = [j for j, lid in enumerate(step.landmarks) if lid not in self._landmark_index]
            ids = list(self.landmark_ids)
            for j in new:
                lid = step.landmarks[j]
                if lid in self._landmark_index:  # the same new landmark twice in one step
                    continue
                self._landmark_index[lid] = len(ids)
                ids.append(lid)
                self._landmarks.append(landmark_from_observation(pose, step.z[j]))
            self.landmark_ids = tuple(ids)
            self._obs_pose.append(np.full(len(step.landmarks), step.index))
            self._obs_landmark.append(self.landmark_indices(step.landmarks))
            self._obs_z.append(step.z)
            self._obs_cov.append(step.z_cov)
        return pose

    def graph(self) -> FactorGraph:
        """All factors recorded so far as one graph (start pose fixed, or a prior on it)."""
        n = len(self.poses)
        fixed: list[int] = []
        prior_args: dict[str, object] = {}
        if self.prior is not None:
            mean, cov = self.prior
            if cov is None:
                fixed = [0]
            else:
                prior_args = {"prior_pose": [0], "prior_mean": mean[None], "prior_cov": cov[None]}
        cat = np.concatenate
        return FactorGraph.build(
            n,
            len(self.landmark_ids),
            fixed_poses=fixed,
            **prior_args,  # type: ignore[arg-type]
            odo_from=np.arange(n - 1),
            odo_to=np.arange(1, n),
            odo_delta=np.array(self._odo_delta).reshape(-1, 3),
            odo_cov=np.array(self._odo_cov).reshape(-1, 3, 3),
            obs_pose=cat(self._obs_pose) if self._obs_pose else [],
            obs_landmark=cat(self._obs_landmark) if self._obs_landmark else [],
            obs_z=cat(self._obs_z) if self._obs_z else np.zeros((0, 2)),
            obs_cov=cat(self._obs_cov) if self._obs_cov else np.zeros((0, 2, 2)),
        )
