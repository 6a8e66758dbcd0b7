"""A map's landmark priors as factors: K blocks of c residual rows each, either one per landmark (c = 2, the
map's landmarks independent) or one over all of them (K = 1, c = 2Q: the map's joint covariance, whose shared
error no per-landmark prior can hold). The Jacobian is the constant square-root information."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from online_slam.factors.graph import FactorGraph

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def jacobian(graph: FactorGraph) -> Array:
    """Each block's Jacobian on its landmarks (the square-root information), shape (K, c, c)."""
    return graph.lp_joint[None] if len(graph.lp_joint) else graph.lp_sqrt_info


def columns(graph: FactorGraph, landmark_column: Index) -> Index:
    """Each block's columns (its landmarks' x, y in order), shape (K, c), from each landmark's first column."""
    first = landmark_column[graph.lp_landmark][:, None] + np.arange(2)
    return first.reshape(1, -1) if len(graph.lp_joint) else first


def residuals(graph: FactorGraph, landmarks: Array) -> Array:
    """Whitened residuals, shape (K, c) (row order: landmark by landmark, x then y, in either form)."""
    e = landmarks[graph.lp_landmark] - graph.lp_mean
    if len(graph.lp_joint):
        return (graph.lp_joint @ e.reshape(-1))[None]
    return np.einsum("kij,kj->ki", graph.lp_sqrt_info, e)


def entries(graph: FactorGraph, first_row: int, landmark_column: Index) -> tuple[Index, Index]:
    """(row, column) of every Jacobian entry, in :func:`jacobian`'s order, the first block's first row given."""
    cols = columns(graph, landmark_column)
    k, c = cols.shape
    rows = first_row + c * np.arange(k, dtype=np.int64)[:, None, None] + np.arange(c)[None, :, None]
    return np.broadcast_to(rows, (k, c, c)).reshape(-1), np.broadcast_to(cols[:, None, :], (k, c, c)).reshape(-1)
