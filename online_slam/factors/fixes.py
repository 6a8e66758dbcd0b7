"""Absolute fixes as prior rows of a factor graph (:mod:`online_slam.models.fix` has their residual).

A fix's square-root information has a zero row (a position fix measures no heading, a heading fix no position),
a start prior's is full rank: that tells them apart where a marginal prior must not count a fix twice.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from online_slam.factors.graph import FactorGraph

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def with_fixes(graph: FactorGraph, pose: Index, mean: Array, offset: Array, W: Array) -> FactorGraph:
    """The graph with fix rows appended to its priors.

    Args:
        graph: Any factor graph.
        pose: The graph pose of each fix, shape (f,).
        mean: Fixed values ``[x, y, theta]``, shape (f, 3).
        offset: Fixed points in the robot frame, shape (f, 2).
        W: Square-root information, shape (f, 3, 3) (zero rows for what a fix does not measure).
    """
    if not len(pose):
        return graph
    offsets = graph.prior_offset if len(graph.prior_offset) else np.zeros((len(graph.prior_pose), 2))
    return dataclasses.replace(
        graph,
        prior_pose=np.r_[graph.prior_pose, np.asarray(pose, dtype=np.int64)],
        prior_mean=np.concatenate([graph.prior_mean, mean]),
        prior_sqrt_info=np.concatenate([graph.prior_sqrt_info, W]),
        prior_offset=np.concatenate([offsets, offset]),
    )


def fix_rows(graph: FactorGraph) -> NDArray[np.bool_]:
    """Which of the graph's priors are fixes (a zero row in their square-root information), shape (P,)."""
    if not len(graph.prior_pose):
        return np.zeros(0, dtype=bool)
    return ~np.all(np.any(graph.prior_sqrt_info != 0.0, axis=2), axis=1)
