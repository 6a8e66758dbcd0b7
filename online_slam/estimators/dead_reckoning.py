"""Dead reckoning: compose odometry from the start pose; landmarks placed from their first observation."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate, Snapshot
from online_slam.frontend.steps import Step

Array = NDArray[np.float64]


class DeadReckoning:
    """The odometry-only baseline, following the estimator protocol."""

    name = "odometry"
    online = True

    def __init__(self) -> None:
        self.log = ProblemLog(keep_factors=False)

    def step(self, step: Step) -> Snapshot:
        """Compose the step's increment onto the previous pose."""
        pose = self.log.add(step)
        return Snapshot(self.name, step.index, step.t, pose, None, self.log.landmark_ids, self.log.landmarks)

    def extend(self, step: Step, start: int) -> Snapshot:
        """More sightings of the newest pose: place new landmarks; the pose does not move."""
        self.log.extend(step, start)
        return self.snapshot(step)

    def snapshot(self, step: Step) -> Snapshot:
        """The newest pose's value and the landmarks placed so far."""
        pose = self.log.poses[-1]
        return Snapshot(self.name, step.index, step.t, pose, None, self.log.landmark_ids, self.log.landmarks)

    def trajectory(self) -> Array:
        """The composed trajectory so far, shape (N, 3)."""
        return np.array(self.log.poses).reshape(-1, 3)

    def state_dict(self) -> dict[str, Any]:
        """Everything recorded (numbers and arrays only)."""
        return self.log.state_dict()

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict`."""
        self.log.load_state(state)

    def finish(self) -> Estimate:
        """The composed trajectory."""
        return Estimate(self.name, np.array(self.log.poses), self.log.landmark_ids, self.log.landmarks)
