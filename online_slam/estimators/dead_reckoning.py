"""Dead reckoning: compose odometry from the start pose; landmarks placed from their first observation."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.problem import LoggedEstimator, ProblemLog
from online_slam.estimators.protocol import Estimate

Array = NDArray[np.float64]


class DeadReckoning(LoggedEstimator):
    """The odometry-only baseline, following the estimator protocol."""

    name = "odometry"
    online = True

    def __init__(self) -> None:
        self.log = ProblemLog(keep_factors=False)

    def finish(self) -> Estimate:
        """The composed trajectory."""
        return Estimate(self.name, np.array(self.log.poses), self.log.landmark_ids, self.log.landmarks)
