"""The batch solver: every pose and landmark at once — the reference every online estimator is compared with."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate, Snapshot
from online_slam.factors.robust import RobustLoss
from online_slam.frontend.steps import Step
from online_slam.solvers.least_squares import SolverConfig, solve


@dataclass(frozen=True)
class BatchConfig:
    """Settings of the batch estimator."""

    solver: SolverConfig = field(default_factory=SolverConfig)
    """Settings of the sparse Levenberg-Marquardt solver."""
    loss: RobustLoss | None = None
    """Robust loss on observations (Huber or Cauchy), or None for plain least squares."""


class BatchEstimator:
    """Collects every step; solves the full problem once, at the end of the stream.

    Until then its snapshots report the initial values it will start from (composed odometry, landmarks from
    their first observation). It starts from those unless ``finish`` is given other initial values.
    """

    name = "batch"
    online = False

    def __init__(self, config: BatchConfig | None = None) -> None:
        self.config = config or BatchConfig()
        self.log = ProblemLog()

    def step(self, step: Step) -> Snapshot:
        """Record the step; report its initial value."""
        pose = self.log.add(step)
        return Snapshot(self.name, step.index, step.t, pose, None, self.log.landmark_ids, self.log.landmarks)

    def finish(self) -> Estimate:
        """Solve the full problem from the composed-odometry initial values."""
        started = time.perf_counter()
        graph = self.log.graph()
        result = solve(
            graph,
            np.array(self.log.poses).reshape(-1, 3),
            self.log.landmarks,
            self.config.solver,
            loss=self.config.loss,
        )
        info = {
            "iterations": result.iterations,
            "converged": result.converged,
            "initial_cost": result.initial_cost,
            "final_cost": result.final_cost,
            "message": result.message,
            "solve_s": time.perf_counter() - started,
        }
        return Estimate(self.name, result.poses, self.log.landmark_ids, result.landmarks, info)
