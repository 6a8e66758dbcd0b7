"""The batch solver: every pose and landmark at once — the reference every online estimator is compared with."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

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
    initial: str = "odometry"
    """Initial values: ``odometry`` (composed odometry, landmarks from first sight) or the final estimate of
    another estimator of the same replay (``ekf``, ``smoother``); from composed odometry LM can end in a poor
    local minimum on long real runs."""


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

    def extend(self, step: Step, start: int) -> Snapshot:
        """More sightings of the newest pose: record them."""
        self.log.extend(step, start)
        return self.snapshot(step)

    def snapshot(self, step: Step) -> Snapshot:
        """The newest pose's value and the landmarks placed so far."""
        pose = self.log.poses[-1]
        return Snapshot(self.name, step.index, step.t, pose, None, self.log.landmark_ids, self.log.landmarks)

    def trajectory(self) -> NDArray[np.float64]:
        """The initial values it will start from (composed odometry), shape (N, 3)."""
        return np.array(self.log.poses).reshape(-1, 3)

    def state_dict(self) -> dict[str, Any]:
        """Everything recorded (numbers and arrays only)."""
        return self.log.state_dict()

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict`."""
        self.log.load_state(state)

    def finish(self, initial: Estimate | None = None) -> Estimate:
        """Solve the full problem, from composed odometry or from another estimate (same poses, same ids)."""
        started = time.perf_counter()
        graph = self.log.graph()
        poses, landmarks = np.array(self.log.poses).reshape(-1, 3), self.log.landmarks
        if initial is not None:
            if len(initial.poses) != len(poses):
                raise ValueError("initial estimate has a different number of poses")
            poses = initial.poses.copy()
            where = {lid: k for k, lid in enumerate(initial.landmark_ids)}
            for k, lid in enumerate(self.log.landmark_ids):
                if lid in where:
                    landmarks[k] = initial.landmarks[where[lid]]
        result = solve(graph, poses, landmarks, self.config.solver, loss=self.config.loss)
        info = {
            "iterations": result.iterations,
            "converged": result.converged,
            "initial_cost": result.initial_cost,
            "final_cost": result.final_cost,
            "message": result.message,
            "solve_s": time.perf_counter() - started,
            "initial": "odometry" if initial is None else initial.estimator,
        }
        return Estimate(self.name, result.poses, self.log.landmark_ids, result.landmarks, info)
