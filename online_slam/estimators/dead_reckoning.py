"""Dead reckoning: compose odometry from the start pose; landmarks placed from their first observation."""

from __future__ import annotations

import numpy as np

from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate, Snapshot
from online_slam.frontend.steps import Step


class DeadReckoning:
    """The odometry-only baseline, following the estimator protocol."""

    name = "odometry"
    online = True

    def __init__(self) -> None:
        self.log = ProblemLog()

    def step(self, step: Step) -> Snapshot:
        """Compose the step's increment onto the previous pose."""
        pose = self.log.add(step)
        return Snapshot(self.name, step.index, step.t, pose, None, self.log.landmark_ids, self.log.landmarks)

    def finish(self) -> Estimate:
        """The composed trajectory."""
        return Estimate(self.name, np.array(self.log.poses), self.log.landmark_ids, self.log.landmarks)
