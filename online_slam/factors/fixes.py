"""Absolute fixes as prior rows of a factor graph (:mod:`online_slam.models.fix` has their residual).

A fix's square-root information has a zero row (a position fix measures no heading, a heading fix no position),
a start prior's is full rank: that tells them apart where a marginal prior must not count a fix twice.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from online_slam.factors.graph import FactorGraph
from online_slam.models.fix import FIX_FALSE_ALARM, fix_nis, fix_residual_with_jacobians

if TYPE_CHECKING:
    from online_slam.sources.events import Heading, Position

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


def fix_gate_ratio(graph: FactorGraph, poses: Array, widened: Array | None = None) -> Array:
    """Each prior's squared whitened residual at ``poses`` (n_poses, 3) over the fixes' gate
    (:data:`~online_slam.models.fix.FIX_FALSE_ALARM` at its degrees of freedom) for a fix, 0 for a start prior or a
    fix switched off, shape (P,); ``widened``: each fix's widening for correlation in time (in the graph's fix
    order), taken off (a fix is judged by its own covariance). At an estimate that used it, a good fix reads within
    its noise (below 1); a GPS jump far above."""
    out = np.zeros(len(graph.prior_pose))
    fixes = fix_rows(graph)
    W = graph.prior_sqrt_info[fixes]
    dof = np.count_nonzero(np.any(W != 0.0, axis=2), axis=1)
    if not np.any(dof):
        return out
    pose, offset, mean = poses[graph.prior_pose[fixes]], graph.prior_offset[fixes], graph.prior_mean[fixes]
    e = fix_residual_with_jacobians(pose, offset, mean)[0]  # its heading wrapped
    r = np.einsum("kij,kj->ki", W, e)
    chi2_values = np.sum(r * r, axis=1) * (1.0 if widened is None else widened)
    out[fixes] = np.where(dof > 0, chi2_values / chi2.isf(FIX_FALSE_ALARM, np.maximum(dof, 1)), 0.0)
    return out


def without_fixes(graph: FactorGraph, drop: NDArray[np.bool_]) -> FactorGraph:
    """The same graph with the priors flagged in ``drop`` (P,) switched off (zero information)."""
    W = graph.prior_sqrt_info.copy()
    W[drop] = 0.0
    return dataclasses.replace(graph, prior_sqrt_info=W)


def fix_gate(pose: ArrayLike, cov: ArrayLike, fixes: Sequence[Position | Heading]) -> tuple[NDArray[np.bool_], Array]:
    """Which fixes pass the gate against a pose estimate ``pose`` (3,) of covariance ``cov`` (3, 3), and their NIS
    (:func:`~online_slam.models.fix.fix_nis`), shapes (f,): passing is within the chi-square bound a good fix exceeds
    with probability :data:`FIX_FALSE_ALARM` at its degrees of freedom (41.4 for a position, 37.3 for a heading)."""
    nis, dof = fix_nis(pose, cov, fixes)
    return nis <= chi2.isf(FIX_FALSE_ALARM, dof), nis


def fix_report(used: int, rejected: int) -> dict[str, int]:
    """Fixes used and refused by the gate, for an estimate's info (nothing when none came)."""
    return {"fixes_used": used, "fixes_rejected": rejected} if used or rejected else {}
