"""The ideal EKF: every Jacobian at the true state (a reference for simulated worlds, never an estimator of data).

Huang, Mourikis & Roumeliotis (IJRR 29(5), 2010) use it as the yardstick of consistency: linearized at the truth,
the filter's Jacobians keep SLAM's unobservable directions unobserved and carry no linearization error, so its
NEES is what the model's noise alone gives. Its estimate and innovations are the EKF's own (``f`` and ``h`` at the
estimate); only ``F``, ``G``, ``H`` and a new landmark's ``d l / d robot`` are taken at the true poses and
landmarks. It needs the truth of every pose and every sighted landmark, so it runs beside the estimators in
``compare --runs N --peer ideal`` (one robot), fed the truth the simulator wrote.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.ekf import EkfSlam
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.ekf_robots import landmark_columns
from online_slam.estimators.kalman import stacked_jacobian
from online_slam.estimators.linearization import heading_column
from online_slam.estimators.protocol import Snapshot
from online_slam.frontend.pose import GroundTruth
from online_slam.frontend.steps import Step
from online_slam.geometry.se2 import compose_with_jacobians
from online_slam.models.observation import (
    RANGE_BEARING,
    landmark_from_sighting_with_jacobians,
    predict_with_jacobians,
    wrap_bearings,
)

Array = NDArray[np.float64]


class IdealEkf(EkfSlam):
    """The EKF with its Jacobians at the truth (additive updates, as the textbook EKF); one robot."""

    name = "ideal ekf"

    def __init__(self, truth: GroundTruth, config: EkfConfig | None = None) -> None:
        """Args: truth: every pose's and every sighted landmark's truth; config: the EKF's other settings (its
        ``linearization`` is replaced)."""
        super().__init__(replace(config or EkfConfig(), linearization="standard"))
        self.truth = truth
        self._at: int | None = None  # the step being consumed
        self._before: int | None = None  # the step before it (the increment's start)
        self._placing: Any = None  # the landmark being placed

    def _true_pose(self, index: int | None) -> Array:
        if index is None or index not in self.truth.poses:
            raise OnlineSlamError(f"ideal EKF: no true pose for step {index}")
        return np.asarray(self.truth.poses[index], dtype=float)

    def _true_landmark(self, landmark: Any) -> Array:
        if landmark not in self.truth.landmarks:
            raise OnlineSlamError(f"ideal EKF: no true position for landmark {landmark}")
        return np.asarray(self.truth.landmarks[landmark], dtype=float)

    def _step(self, step: Step) -> Snapshot:
        if step.odometry is None and step.index > 0:
            raise OnlineSlamError("ideal EKF: takes one robot")
        self._before, self._at = self._at, step.index
        return super()._step(step)

    def _motion(self, u: Array) -> tuple[Array, Array, Array]:
        """The pose moved by u at the estimate; ``F`` and ``G`` at the true poses: ``F[:2, 2] = J (p_k+1 - p_k)``."""
        before, after = self._true_pose(self._before), self._true_pose(self._at)
        _, F, G = compose_with_jacobians(before, u)
        F[:2, 2] = heading_column(after[:2], before[:2])
        return compose_with_jacobians(self.x[:3, 0], u)[0], F, G

    def add_landmark(self, landmark: Any, z: Array, R: Array, model: int = RANGE_BEARING) -> None:
        """The EKF's placement, its Jacobians at the true pose and landmark."""
        self._placing = landmark
        super().add_landmark(landmark, z, R, model)

    def reanchor_landmark(self, index: int, z: Array, R: Array, model: int = RANGE_BEARING) -> None:
        """The EKF's restart of a landmark, its Jacobians at the true pose and landmark."""
        self._placing = self.landmark_ids[index]
        super().reanchor_landmark(index, z, R, model)

    def _placed(self, z: Array, model: int) -> tuple[Array, Array, Array]:
        """The landmark placed at the estimate; ``d l / d z`` at the true pose, ``d l / d robot = [I, J (l - p)]``
        at the true landmark and pose."""
        position, _, _ = landmark_from_sighting_with_jacobians(self.x[:3, 0], z, model)
        pose = self._true_pose(self._at)
        _, G_r, G_z = landmark_from_sighting_with_jacobians(pose, z, model)
        G_r[:, 2] = heading_column(self._true_landmark(self._placing), pose[:2])
        return position, G_r, G_z

    def _innovation(
        self, indices: NDArray[np.int64], z: Array, model: NDArray[np.int8]
    ) -> tuple[Array, Array, NDArray[np.int64]]:
        """Innovations at the estimate, Jacobians at the true pose and landmarks."""
        landmarks = self.x[self._offset :, 0].reshape(-1, 2)[indices]
        z_hat, _, _ = predict_with_jacobians(self.x[:3, 0], landmarks, model)
        true = np.array([self._true_landmark(self.landmark_ids[j]) for j in indices]).reshape(-1, 2)
        _, J_p, J_l = predict_with_jacobians(self._true_pose(self._at), true, model)
        y = wrap_bearings(z - z_hat, model)
        columns = np.r_[np.arange(3), landmark_columns(indices, self._offset)]
        return y, stacked_jacobian(J_p, J_l), columns
