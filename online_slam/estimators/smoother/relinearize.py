"""Global relinearization for the sliding-window smoother: re-solve the whole history, re-anchor the prior.

The smoother's marginal prior freezes the linearization of every pose it has eliminated. A global
relinearization re-solves all factors ever seen (warm-started from the current estimate, a few Gauss-Newton /
Levenberg-Marquardt iterations), writes the revised poses back into the history, and moves the prior to the new
estimate: its linearization point becomes the revised values of the variables it holds, and its mean becomes the
one the history's factors give there,

    mu = -Sigma g',   g' = g_k - H_km H_mm^-1 g_m,

where ``g`` and ``H = J^T J`` are the gradient and Gauss-Newton matrix of the history's factors (odometry up to
the oldest window pose, the history poses' sightings, the start prior) at the revised values, ``m`` the history
poses and ``k`` the prior's variables (its landmarks, then the oldest window pose): ``g'`` is the gradient of the
history's cost with the history poses eliminated (a Schur complement, computed with one sparse solve of the
history poses' block — odometry chains make it banded). Where the prior is small, its information is
relinearized too (:func:`prior_marginal`): ``H' = H_kk - H_km H_mm^-1 H_mk`` at the revised values, the same
factorization with ``2 L + 3`` right-hand sides and a dense inverse; otherwise the prior keeps its covariance
``Sigma``, the same information linearized where each factor was folded in.

The whole-history solve itself (:func:`solve_all`) drops the sightings the smoother judged outliers when their
pose left the window (:func:`outlier_mask`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from online_slam.estimators.problem import ProblemLog, RobotSightings
from online_slam.factors.fixes import fix_rows
from online_slam.factors.graph import (
    FactorGraph,
    layout,
    linearize,
    subgraph,
    without_observations,
    without_robot_sightings,
)
from online_slam.factors.robust import RobustLoss
from online_slam.solvers.least_squares import SolverConfig, SolveResult, solve

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def history_graph(graph: FactorGraph, oldest: int) -> FactorGraph:
    """The factors of the poses before ``oldest`` (the oldest window pose): odometry up to it, their sightings,
    priors on them; over poses ``0..oldest`` and every landmark."""
    odo = graph.odo_to <= oldest
    obs = graph.obs_pose < oldest
    prior = graph.prior_pose < oldest
    return _map_seen(subgraph(graph, oldest + 1, graph.fixed_poses[graph.fixed_poses <= oldest], prior, odo, obs))


def _map_seen(past: FactorGraph) -> FactorGraph:
    """A history graph with the map's priors on the landmarks it saw only (the ones the marginal prior holds; with
    a joint map, all of them)."""
    if len(past.lp_joint):
        return past
    seen = np.isin(past.lp_landmark, past.obs_landmark)
    return replace(
        past, lp_landmark=past.lp_landmark[seen], lp_mean=past.lp_mean[seen], lp_sqrt_info=past.lp_sqrt_info[seen]
    )


def prior_marginal(
    history: FactorGraph,
    poses: Array,
    landmarks: Array,
    prior_landmarks: Index,
    loss: RobustLoss | None = None,
    information: bool = True,
    kept: Index | None = None,
) -> tuple[Array, Array | None]:
    """The history's cost with the history poses eliminated, as a quadratic over ``[prior landmarks..., oldest
    pose]`` (or ``[prior landmarks..., kept poses...]``): its gradient and (Gauss-Newton) information at the given
    values.

    Args:
        history: :func:`history_graph` (poses ``0..oldest``; the last one is the oldest window pose).
        poses: Values of poses ``0..oldest``, shape (oldest + 1, 3).
        landmarks: Values of every landmark, shape (M, 2).
        prior_landmarks: Landmark indices the prior holds, in its order, shape (L,).
        loss: The smoother's robust loss on sightings (IRLS weights at these values).
        information: Also compute ``H'`` (else None is returned in its place); landmarks the history sees that
            the prior does not hold are then eliminated with the poses (else held at their values).
        kept: The poses the prior holds, in its order, when they are not just the last one (several robots); every
            other free pose is eliminated.

    Returns:
        (g', shape (2 L + 3,); H', shape (2 L + 3, 2 L + 3), or None).
    """
    sparse = layout(history)
    r, J = linearize(history, sparse, poses, landmarks, loss)
    g = J.T @ r
    kept = np.array([history.n_poses - 1]) if kept is None else kept
    pose_cols = np.delete(sparse.pose_column, kept)
    m = (pose_cols[pose_cols >= 0][:, None] + np.arange(3)).reshape(-1)
    k = np.r_[
        (sparse.landmark_column[prior_landmarks][:, None] + np.arange(2)).reshape(-1),
        (sparse.pose_column[kept][:, None] + np.arange(3)).reshape(-1),
    ]
    if information:  # landmarks the history sees but the prior does not hold (released) are eliminated too
        others = np.setdiff1d(np.unique(history.obs_landmark), prior_landmarks)
        columns = sparse.landmark_column[others]
        m = np.r_[m, (columns[columns >= 0][:, None] + np.arange(2)).reshape(-1)].astype(np.int64)
    Jk = J[:, k].tocsc()
    H = (Jk.T @ Jk).toarray() if information else None
    if not len(m):
        return g[k], H
    Jm = J[:, m].tocsc()
    H_mm = (Jm.T @ Jm).tocsc() + sp.identity(len(m), format="csc") * 1e-12  # the start fixes the chain
    lu = spla.splu(H_mm)
    g_k = g[k] - Jk.T @ (Jm @ lu.solve(g[m]))
    if H is not None:
        H_mk = (Jm.T @ Jk).toarray()
        H = H - H_mk.T @ lu.solve(H_mk)
        H = 0.5 * (H + H.T)
    return g_k, H


def refine_recent(
    history: FactorGraph,
    first: int,
    poses: Array,
    landmarks: Array,
    solver: SolverConfig,
    loss: RobustLoss | None = None,
) -> tuple[Array, Array]:
    """Re-solve poses ``first..`` of a history graph with every earlier pose held fixed.

    Only the sightings of the landmarks those poses see take part (from every pose: the earlier ones pin the
    landmarks), so the problem is small. Used when a global solution handed over from the background is older
    than the poses that left the window since: they are brought to agree with it.

    Args:
        history: :func:`history_graph` over poses ``0..oldest``.
        first: The first pose to re-solve.
        poses: Values of poses ``0..oldest``, shape (oldest + 1, 3).
        landmarks: Values of every landmark, shape (M, 2).
        solver: Levenberg-Marquardt settings.
        loss: Robust loss on sightings.

    Returns:
        (poses, landmarks) with the re-solved values written in (copies).
    """
    poses, landmarks = poses.copy(), landmarks.copy()
    seen = np.unique(history.obs_landmark[history.obs_pose >= first])
    obs = np.isin(history.obs_landmark, seen)
    odo = history.odo_to >= first
    local = np.full(history.n_landmarks, -1, dtype=np.int64)
    local[seen] = np.arange(len(seen))
    prior = history.prior_pose >= first  # the fixes of the poses re-solved
    graph = FactorGraph(
        n_poses=history.n_poses,
        n_landmarks=len(seen),
        fixed_poses=np.arange(first, dtype=np.int64),
        prior_pose=history.prior_pose[prior],
        prior_mean=history.prior_mean[prior],
        prior_sqrt_info=history.prior_sqrt_info[prior],
        prior_offset=history.prior_offset[prior] if len(history.prior_offset) else history.prior_offset,
        odo_from=history.odo_from[odo],
        odo_to=history.odo_to[odo],
        odo_delta=history.odo_delta[odo],
        odo_sqrt_info=history.odo_sqrt_info[odo],
        obs_pose=history.obs_pose[obs],
        obs_landmark=local[history.obs_landmark[obs]],
        obs_z=history.obs_z[obs],
        obs_sqrt_info=history.obs_sqrt_info[obs],
        obs_model=history.obs_model[obs],
    )
    result = solve(graph, poses, landmarks[seen], solver, loss=loss)
    poses[first:] = result.poses[first:]
    landmarks[seen] = result.landmarks
    return poses, landmarks


def prior_covariance(information: Array, fallback: Array) -> Array:
    """The inverse of a relinearized prior information, or ``fallback`` where it is not positive definite
    (a direction the history no longer constrains at the new values)."""
    try:
        L = np.linalg.cholesky(information)
    except np.linalg.LinAlgError:
        return fallback
    inverse = np.linalg.inv(L)  # Sigma = L^-T L^-1
    Sigma = inverse.T @ inverse
    return 0.5 * (Sigma + Sigma.T)


def outlier_mask(graph: FactorGraph, decisions: list[tuple[int, NDArray[np.bool_]]]) -> NDArray[np.bool_]:
    """The graph's sightings judged outliers when their pose left the window (graph sightings in pose order).

    A decision applies where the graph holds exactly as many sightings of its pose as it judged.
    """
    drop = np.zeros(len(graph.obs_pose), dtype=bool)
    if not decisions:
        return drop
    poses = np.fromiter((g for g, _ in decisions), dtype=np.int64, count=len(decisions))
    sizes = np.fromiter((len(m) for _, m in decisions), dtype=np.int64, count=len(decisions))
    start = np.searchsorted(graph.obs_pose, poses)
    applies = np.searchsorted(graph.obs_pose, poses + 1) - start == sizes
    if not applies.any():
        return drop
    masks = np.concatenate([m for (_, m), ok in zip(decisions, applies.tolist()) if ok])
    sizes, start = sizes[applies], start[applies]
    # position of every judged sighting: its decision's start plus its rank within the decision
    offsets = np.repeat(start - (np.cumsum(sizes) - sizes), sizes)
    drop[np.arange(len(masks)) + offsets] = masks
    return drop


def inlier_graph(
    log: ProblemLog, decisions: list[tuple[int, NDArray[np.bool_]]], robot_rejected: Sequence[int] = ()
) -> FactorGraph:
    """Every factor of the log but the sightings (and robot sightings) judged outliers."""
    graph = log.graph()
    drop = outlier_mask(graph, decisions)
    graph = without_observations(graph, drop) if drop.any() else graph
    if len(robot_rejected):
        graph = without_robot_sightings(graph, robot_rows(log.seen, robot_rejected))
    return graph


def robot_rows(seen: RobotSightings, numbers: Sequence[int]) -> NDArray[np.bool_]:
    """Which robot sightings of a log's graph (its linked ones, in order) are among these sighting numbers."""
    return np.isin(np.flatnonzero(seen.linked()), np.asarray(numbers, dtype=np.int64))


def several_history_graph(graph: FactorGraph, left: Index, kept: Index, folded: NDArray[np.bool_]) -> FactorGraph:
    """The factors the prior folded in, several robots: odometry from the poses that left the window, their
    sightings, the start priors of those poses and of the prior's poses (``kept``), the robot sightings ``folded``
    (R,); over every pose, those neither left nor kept held fixed (no columns), the kept ones free."""
    gone = np.zeros(graph.n_poses, dtype=bool)
    gone[left] = True
    inside = gone.copy()
    inside[kept] = True
    odo, obs = gone[graph.odo_from], gone[graph.obs_pose]
    prior = np.where(fix_rows(graph), gone[graph.prior_pose], inside[graph.prior_pose])  # kept poses' fixes: window
    fixed = np.union1d(np.flatnonzero(~inside), graph.fixed_poses[gone[graph.fixed_poses]])
    return _map_seen(subgraph(graph, graph.n_poses, fixed.astype(np.int64), prior, odo, obs, folded))


def rejudged(
    graph: FactorGraph, decisions: list[tuple[int, NDArray[np.bool_]]], outliers: NDArray[np.bool_]
) -> list[tuple[int, NDArray[np.bool_]]]:
    """The decisions with each pose's mask replaced by ``outliers`` (one per sighting of the graph's first poses, in
    pose order) where the graph holds exactly as many sightings of the pose as it judged (see
    :func:`outlier_mask`); poses ``outliers`` does not reach keep theirs."""
    if not decisions:
        return []
    poses = np.fromiter((g for g, _ in decisions), dtype=np.int64, count=len(decisions))
    start = np.searchsorted(graph.obs_pose, poses)
    end = np.searchsorted(graph.obs_pose, poses + 1)
    return [
        (g, outliers[a:b].copy() if b - a == len(mask) and b <= len(outliers) else mask)
        for (g, mask), a, b in zip(decisions, start.tolist(), end.tolist())
    ]


def solve_all(
    log: ProblemLog,
    decisions: list[tuple[int, NDArray[np.bool_]]],
    poses: Array,
    landmarks: Array,
    solver: SolverConfig,
    loss: RobustLoss | None,
    robot_rejected: Sequence[int] = (),
) -> SolveResult:
    """Every factor of the log but the judged outliers, solved from the given values (pure: safe in a thread).

    Always by the sparse factorization (plain C, no threaded BLAS): the dense one's LAPACK runs on as many
    threads as the process allows at the moment, which the stepping thread changes (it limits BLAS to one thread
    per step), so a small problem solved in the background could differ in the last bits from run to run.
    """
    return solve(inlier_graph(log, decisions, robot_rejected), poses, landmarks, solver, loss=loss, dense=False)
