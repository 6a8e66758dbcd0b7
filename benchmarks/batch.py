"""Batch solve time on a grid world: online-slam's sparse LM beside GTSAM's LM, same data, same run."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from online_slam import gtsam_peer
from online_slam.engine import Engine
from online_slam.estimators.batch import BatchEstimator
from online_slam.factors.graph import evaluate
from online_slam.solvers.least_squares import solve
from online_slam.sources.worlds import GridConfig, grid_world


@dataclass(frozen=True)
class Timing:
    """One solver's figures: best wall time over the repeats, iterations, final 0.5 * chi-square."""

    label: str
    """Who solved."""
    seconds: float
    """Best wall time of the solve alone, seconds."""
    iterations: int
    """Iterations of the timed run."""
    final_cost: float
    """Final cost, 0.5 * chi-square, evaluated by online-slam's own residuals."""


@dataclass(frozen=True)
class BatchBench:
    """Result of :func:`run_batch_bench`."""

    poses: int
    """Poses in the world."""
    landmarks: int
    """Landmarks in the world."""
    observations: int
    """Observations in the world."""
    ours: Timing
    """online-slam's sparse LM."""
    peer: Timing | None
    """GTSAM LM with native factors and default parameters, or None without gtsam."""


def run_batch_bench(config: GridConfig, repeats: int = 3) -> BatchBench:
    """Time both batch solvers from the same composed-odometry initial values.

    Args:
        config: The grid world to build.
        repeats: Each solver is timed this many times; the best time is kept.

    Returns:
        The figures.
    """
    batch = BatchEstimator()
    engine = Engine([batch])
    for event in grid_world(config):
        engine.push(event)
    engine.close()
    graph = batch.log.graph()
    poses0, landmarks0 = np.array(batch.log.poses), batch.log.landmarks

    def cost(poses: np.ndarray, landmarks: np.ndarray) -> float:
        r = evaluate(graph, poses, landmarks)
        return 0.5 * float(r @ r)

    best = np.inf
    for _ in range(repeats):
        started = time.perf_counter()
        result = solve(graph, poses0, landmarks0, batch.config.solver)
        best = min(best, time.perf_counter() - started)
    ours = Timing("online-slam LM", best, result.iterations, cost(result.poses, result.landmarks))
    peer = None
    if gtsam_peer.available():
        runs = [gtsam_peer.levenberg_marquardt(graph, poses0, landmarks0) for _ in range(repeats)]
        fastest = min(runs, key=lambda s: s.solve_s)
        peer = Timing("GTSAM LM (native factors)", fastest.solve_s, fastest.iterations,
                      cost(fastest.poses, fastest.landmarks))  # fmt: skip
    return BatchBench(graph.n_poses, graph.n_landmarks, len(graph.obs_pose), ours, peer)
