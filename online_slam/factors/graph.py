"""A factor graph over poses ``[x, y, theta]`` and landmarks ``[x, y]``, stored as arrays.

Three factor kinds, all whitened by the square-root information ``W`` (``W^T W = cov^-1``):

- prior on a pose: ``W (p - mean)`` (angle wrapped), or with ``prior_offset`` an absolute fix of a point of the
  robot frame and the heading, ``W (fixed(p, offset) - mean)`` (:mod:`online_slam.models.fix`; its ``W`` may have
  zero rows: a position fix, a heading fix);
- odometry between poses a and b: ``W (between(a, b) - delta)`` (angle wrapped) — the article's model;
- observation of landmark l from pose p: ``W (h(p, l) - z)``, with ``h`` the sighting's own model
  (:mod:`online_slam.models.observation`: range-bearing, bearing wrapped, or the landmark's position in the
  robot frame), tagged per observation in ``obs_model``;
- range-bearing sighting of a robot: pose b's position seen from pose a, ``W (h(a, b_xy) - z)`` (bearing wrapped;
  one robot's pose sighted from another's). Its rows follow the observations;
- prior on a landmark (a map's, ``--map``): ``W (l - mean)``. Its rows come last; the robust loss never applies.

The state vector holds the free poses then the landmarks; fixed poses have no columns.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import cast

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from online_slam.factors import landmark_prior
from online_slam.factors.information import sqrt_information as sqrt_information
from online_slam.factors.robust import RobustLoss
from online_slam.geometry.angles import wrap
from online_slam.models.fix import fix_residual_with_jacobians
from online_slam.models.motion import odometry_residual_with_jacobians
from online_slam.models.observation import RANGE_BEARING, predict, predict_with_jacobians, tags, wrap_bearings
from online_slam.models.range_bearing import robot_sighting_residual_with_jacobians

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def _index(values: ArrayLike) -> Index:
    return np.asarray(values, dtype=np.int64).reshape(-1)


@dataclass(frozen=True)
class FactorGraph:
    """All factors of a problem as arrays (P priors, K odometry factors, L observations)."""

    n_poses: int
    """Number of pose variables."""
    n_landmarks: int
    """Number of landmark variables."""
    fixed_poses: Index
    """Indices of poses held constant, shape (F,)."""
    prior_pose: Index
    """Pose index of each prior, shape (P,)."""
    prior_mean: Array
    """Prior means, shape (P, 3)."""
    prior_sqrt_info: Array
    """Prior square-root information, shape (P, 3, 3)."""
    odo_from: Index
    """Earlier pose of each odometry factor, shape (K,)."""
    odo_to: Index
    """Later pose of each odometry factor, shape (K,)."""
    odo_delta: Array
    """Measured increments, shape (K, 3)."""
    odo_sqrt_info: Array
    """Square-root information of the increments, shape (K, 3, 3)."""
    obs_pose: Index
    """Observing pose of each observation, shape (L,)."""
    obs_landmark: Index
    """Observed landmark of each observation, shape (L,)."""
    obs_z: Array
    """Measured ``[range, bearing]`` or ``[dx, dy]`` (see ``obs_model``), shape (L, 2)."""
    obs_sqrt_info: Array
    """Square-root information of the observations, shape (L, 2, 2)."""
    obs_model: NDArray[np.int8]
    """Model tag of each observation (:mod:`online_slam.models.observation`), shape (L,)."""
    rob_from: Index = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """Sighting pose of each robot sighting, shape (R,)."""
    rob_to: Index = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """Sighted pose (another robot's) of each robot sighting, shape (R,)."""
    rob_z: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """Measured ``[range, bearing]`` to the sighted pose's position, shape (R, 2)."""
    rob_sqrt_info: Array = field(default_factory=lambda: np.zeros((0, 2, 2)))
    """Square-root information of the robot sightings, shape (R, 2, 2)."""
    lp_landmark: Index = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """Landmark of each landmark prior (a map's), shape (Q,)."""
    lp_mean: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """Prior means, shape (Q, 2)."""
    lp_sqrt_info: Array = field(default_factory=lambda: np.zeros((0, 2, 2)))
    """Prior square-root information, shape (Q, 2, 2)."""
    lp_joint: Array = field(default_factory=lambda: np.zeros((0, 0)))
    """Or their joint square-root information, shape (2Q, 2Q) over ``[x0, y0, x1, ...]`` of ``lp_landmark``, which
    replaces ``lp_sqrt_info`` when not empty (:mod:`~online_slam.factors.landmark_prior`)."""
    prior_offset: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """The robot-frame point each prior fixes (absolute fixes), shape (P, 2); empty: every prior is on the pose."""

    @staticmethod
    def build(
        n_poses: int,
        n_landmarks: int,
        *,
        fixed_poses: ArrayLike = (),
        prior_pose: ArrayLike = (),
        prior_mean: ArrayLike = (),
        prior_cov: ArrayLike = (),
        odo_from: ArrayLike = (),
        odo_to: ArrayLike = (),
        odo_delta: ArrayLike = (),
        odo_cov: ArrayLike = (),
        obs_pose: ArrayLike = (),
        obs_landmark: ArrayLike = (),
        obs_z: ArrayLike = (),
        obs_cov: ArrayLike = (),
        obs_model: ArrayLike = RANGE_BEARING,
        rob_from: ArrayLike = (),
        rob_to: ArrayLike = (),
        rob_z: ArrayLike = (),
        rob_cov: ArrayLike = (),
    ) -> FactorGraph:
        """Build a graph from covariances (computes the square-root information once); ``obs_model`` tags every
        observation with one model, or each with its own (L,)."""
        prior_cov = np.asarray(prior_cov, dtype=float).reshape(-1, 3, 3)
        odo_cov = np.asarray(odo_cov, dtype=float).reshape(-1, 3, 3)
        obs_cov = np.asarray(obs_cov, dtype=float).reshape(-1, 2, 2)
        obs_pose = _index(obs_pose)
        rob_cov = np.asarray(rob_cov, dtype=float).reshape(-1, 2, 2)
        return FactorGraph(
            n_poses=int(n_poses),
            n_landmarks=int(n_landmarks),
            fixed_poses=_index(fixed_poses),
            prior_pose=_index(prior_pose),
            prior_mean=np.asarray(prior_mean, dtype=float).reshape(-1, 3),
            prior_sqrt_info=sqrt_information(prior_cov) if len(prior_cov) else prior_cov,
            odo_from=_index(odo_from),
            odo_to=_index(odo_to),
            odo_delta=np.asarray(odo_delta, dtype=float).reshape(-1, 3),
            odo_sqrt_info=sqrt_information(odo_cov) if len(odo_cov) else odo_cov,
            obs_pose=obs_pose,
            obs_landmark=_index(obs_landmark),
            obs_z=np.asarray(obs_z, dtype=float).reshape(-1, 2),
            obs_sqrt_info=sqrt_information(obs_cov) if len(obs_cov) else obs_cov,
            obs_model=tags(obs_model, len(obs_pose)),
            rob_from=_index(rob_from),
            rob_to=_index(rob_to),
            rob_z=np.asarray(rob_z, dtype=float).reshape(-1, 2),
            rob_sqrt_info=sqrt_information(rob_cov) if len(rob_cov) else rob_cov,
        )

    @property
    def n_residuals(self) -> int:
        """Number of scalar residuals."""
        pairs = len(self.obs_pose) + len(self.rob_from) + len(self.lp_landmark)
        return 3 * len(self.prior_pose) + 3 * len(self.odo_from) + 2 * pairs


@dataclass(frozen=True)
class SparseLayout:
    """Where each Jacobian entry goes; computed once per graph, reused every iteration."""

    pose_column: Index
    """First column of each pose, -1 for a fixed pose, shape (n_poses,)."""
    landmark_column: Index
    """First column of each landmark, shape (n_landmarks,)."""
    n_columns: int
    """Number of free scalar variables."""
    rows: Index
    """Row of each kept Jacobian entry."""
    cols: Index
    """Column of each kept Jacobian entry."""
    keep: NDArray[np.bool_]
    """Which entries of the full (fixed columns included) data vector are kept."""


def _block_indices(first_row: Index, m: int, first_col: Index, c: int) -> tuple[Index, Index]:
    rows = first_row[:, None, None] + np.arange(m)[None, :, None] + np.zeros((1, 1, c), dtype=np.int64)
    cols = first_col[:, None, None] + np.arange(c)[None, None, :] + np.zeros((1, m, 1), dtype=np.int64)
    return rows.reshape(-1), np.where(np.repeat(first_col, m * c) < 0, -1, cols.reshape(-1))


def layout(graph: FactorGraph, entries: bool = True) -> SparseLayout:
    """Compute the sparse layout of a graph's Jacobian.

    Args:
        graph: The factor graph.
        entries: Also work out the (row, column) of every Jacobian entry (the sparse path needs them; the
            dense assembler only needs the columns).

    Returns:
        The layout: columns of every variable and, with ``entries``, where each Jacobian entry goes.
    """
    free = np.ones(graph.n_poses, dtype=bool)
    free[graph.fixed_poses] = False
    pose_column = np.where(free, 3 * (np.cumsum(free) - 1), -1).astype(np.int64)
    n_pose_cols = 3 * int(free.sum())
    landmark_column = n_pose_cols + 2 * np.arange(graph.n_landmarks, dtype=np.int64)
    n_columns = n_pose_cols + 2 * graph.n_landmarks
    if not entries:
        none = np.zeros(0, dtype=np.int64)
        return SparseLayout(pose_column, landmark_column, n_columns, none, none, np.zeros(0, dtype=bool))
    P, K, L = len(graph.prior_pose), len(graph.odo_from), len(graph.obs_pose)
    prior_rows = 3 * np.arange(P, dtype=np.int64)
    odo_rows = 3 * P + 3 * np.arange(K, dtype=np.int64)
    obs_rows = 3 * P + 3 * K + 2 * np.arange(L, dtype=np.int64)
    parts = [
        _block_indices(prior_rows, 3, pose_column[graph.prior_pose], 3),
        _block_indices(odo_rows, 3, pose_column[graph.odo_from], 3),
        _block_indices(odo_rows, 3, pose_column[graph.odo_to], 3),
        _block_indices(obs_rows, 2, pose_column[graph.obs_pose], 3),
        _block_indices(obs_rows, 2, landmark_column[graph.obs_landmark], 2),
    ]
    if len(graph.rob_from):
        rob_rows = 3 * P + 3 * K + 2 * L + 2 * np.arange(len(graph.rob_from), dtype=np.int64)
        parts += [
            _block_indices(rob_rows, 2, pose_column[graph.rob_from], 3),
            _block_indices(rob_rows, 2, pose_column[graph.rob_to], 3),
        ]
    if len(graph.lp_landmark):
        parts.append(landmark_prior.entries(graph, graph.n_residuals - 2 * len(graph.lp_landmark), landmark_column))
    rows = np.concatenate([p[0] for p in parts])
    cols = np.concatenate([p[1] for p in parts])
    keep = cols >= 0
    return SparseLayout(
        pose_column=pose_column,
        landmark_column=landmark_column,
        n_columns=n_columns,
        rows=rows[keep],
        cols=cols[keep],
        keep=keep,
    )


@dataclass(frozen=True)
class JacobianPoint:
    """Values some variables' Jacobians are evaluated at instead of their current values (First-Estimates
    Jacobians: a marginal prior's variables keep the linearization point the prior was built at, so that the
    window's factors and the prior see one linearization of each variable). Residuals stay at the current values.
    """

    pose_rows: Index
    """Graph pose indices whose Jacobians are taken at ``pose_values``, shape (a,)."""
    pose_values: Array
    """Their linearization points, shape (a, 3)."""
    landmark_rows: Index
    """Graph landmark indices whose Jacobians are taken at ``landmark_values``, shape (b,)."""
    landmark_values: Array
    """Their linearization points, shape (b, 2)."""

    def apply(self, poses: Array, landmarks: Array) -> tuple[Array, Array]:
        """Copies of (poses (P, 3), landmarks (M, 2)) with the fixed rows set to their linearization points."""
        poses, landmarks = poses.copy(), landmarks.copy()
        poses[self.pose_rows] = self.pose_values
        landmarks[self.landmark_rows] = self.landmark_values
        return poses, landmarks


def _whiten(W: Array, e: Array) -> Array:
    return np.einsum("kij,kj->ki", W, e)


def _errors(
    graph: FactorGraph, poses: Array, landmarks: Array, at: tuple[Array, Array] | None = None
) -> tuple[Array, Array, Array, Array, Array, Array, Array, Array]:
    """Unwhitened errors of every factor (angles wrapped) and the Jacobians of odometry and observations.

    ``at``: the (poses, landmarks) the Jacobians are evaluated at (:meth:`JacobianPoint.apply`); the errors stay
    at the given values.

    Returns:
        (e_prior (P, 3), W d e_prior/dpose (P, 3, 3), e_odo (K, 3), d e_odo/da and /db (K, 3, 3), e_obs (L, 2),
        d e_obs/dpose (L, 2, 3), d e_obs/dlandmark (L, 2, 2)).
    """
    if len(graph.prior_offset):
        e_prior, J = fix_residual_with_jacobians(poses[graph.prior_pose], graph.prior_offset, graph.prior_mean)
        if at is not None:
            J = fix_residual_with_jacobians(at[0][graph.prior_pose], graph.prior_offset, graph.prior_mean)[1]
        WJ_prior = graph.prior_sqrt_info @ J
    else:
        e_prior, WJ_prior = poses[graph.prior_pose] - graph.prior_mean, graph.prior_sqrt_info
        e_prior[:, 2] = wrap(e_prior[:, 2])
    e_odo, J_a, J_b = odometry_residual_with_jacobians(poses[graph.odo_from], poses[graph.odo_to], graph.odo_delta)
    if at is None:
        z, J_p, J_l = predict_with_jacobians(poses[graph.obs_pose], landmarks[graph.obs_landmark], graph.obs_model)
    else:
        z = predict(poses[graph.obs_pose], landmarks[graph.obs_landmark], graph.obs_model)
        p, l = at
        _, J_a, J_b = odometry_residual_with_jacobians(p[graph.odo_from], p[graph.odo_to], graph.odo_delta)
        _, J_p, J_l = predict_with_jacobians(p[graph.obs_pose], l[graph.obs_landmark], graph.obs_model)
    e_obs = wrap_bearings(z - graph.obs_z, graph.obs_model)
    return e_prior, WJ_prior, e_odo, J_a, J_b, e_obs, J_p, J_l


def _robot_rows(
    graph: FactorGraph, poses: Array, loss: RobustLoss | None, at: Array | None = None
) -> tuple[Array, Array, Array, float]:
    """Whitened robot-sighting residuals and Jacobians (IRLS-weighted under ``loss``) and their cost.

    ``at``: the poses the Jacobians are evaluated at (default: ``poses``).

    Returns:
        (r (R, 2), W de/da (R, 2, 3), W de/db (R, 2, 3), cost as :func:`cost` counts it).
    """
    e, J_a, J_b = robot_sighting_residual_with_jacobians(poses[graph.rob_from], poses[graph.rob_to], graph.rob_z)
    if at is not None:
        _, J_a, J_b = robot_sighting_residual_with_jacobians(at[graph.rob_from], at[graph.rob_to], graph.rob_z)
    W = graph.rob_sqrt_info
    r = _whiten(W, e)
    s = np.sum(r * r, axis=1)
    if loss is None or not len(s) or s.max() <= loss.quadratic_within:
        return r, W @ J_a, W @ J_b, 0.5 * float(np.sum(s))
    sqrt_w = np.sqrt(loss.weight(s))
    W = W * sqrt_w[:, None, None]
    return r * sqrt_w[:, None], W @ J_a, W @ J_b, 0.5 * float(np.sum(loss.rho(s)))


def evaluate(graph: FactorGraph, poses: Array, landmarks: Array) -> Array:
    """Whitened residuals.

    Args:
        graph: The factor graph.
        poses: Pose values, shape (n_poses, 3).
        landmarks: Landmark values, shape (n_landmarks, 2).

    Returns:
        Residual vector, shape (n_residuals,), ordered priors, odometry, observations.
    """
    e_prior, _, e_odo, _, _, e_obs, _, _ = _errors(graph, poses, landmarks)
    parts = [
        _whiten(graph.prior_sqrt_info, e_prior).reshape(-1),
        _whiten(graph.odo_sqrt_info, e_odo).reshape(-1),
        _whiten(graph.obs_sqrt_info, e_obs).reshape(-1),
    ]
    if len(graph.rob_from):
        parts.append(_robot_rows(graph, poses, None)[0].reshape(-1))
    if len(graph.lp_landmark):
        parts.append(landmark_prior.residuals(graph, landmarks).reshape(-1))
    return np.concatenate(parts)


def sighting_chi2(poses: Array, landmarks: Array, z: Array, sqrt_info: Array, model: ArrayLike) -> Array:
    """Squared whitened norm of k sightings' residuals (chi-square, 2 dof, when the model is right).

    Args:
        poses: Observing poses, shape (k, 3). landmarks: Observed landmarks, shape (k, 2).
        z: Observations, shape (k, 2). sqrt_info: Their square-root information, (k, 2, 2).
        model: Their model tags, shape (k,) (or one tag for all).

    Returns:
        Shape (k,).
    """
    e = wrap_bearings(predict(poses, landmarks, model) - z, model)
    w = _whiten(sqrt_info, e)
    return np.sum(w * w, axis=1)


def observation_chi2(graph: FactorGraph, poses: Array, landmarks: Array) -> Array:
    """Squared whitened norm of each observation's residual in a graph, shape (n_obs,)."""
    return sighting_chi2(
        poses[graph.obs_pose], landmarks[graph.obs_landmark], graph.obs_z, graph.obs_sqrt_info, graph.obs_model
    )


def robot_sighting_chi2(graph: FactorGraph, poses: Array) -> Array:
    """Squared whitened norm of each robot sighting's residual in a graph, shape (R,)."""
    r = _robot_rows(graph, poses, None)[0]
    return np.sum(r * r, axis=1)


def subgraph(
    graph: FactorGraph,
    n_poses: int,
    fixed_poses: Index,
    prior: NDArray[np.bool_],
    odo: NDArray[np.bool_],
    obs: NDArray[np.bool_],
    rob: NDArray[np.bool_] | None = None,
) -> FactorGraph:
    """The factors the masks select (priors, odometry, sightings, robot sightings: none when ``rob`` is None), over
    ``n_poses`` poses with ``fixed_poses`` held constant and every landmark."""
    rob = np.zeros(len(graph.rob_from), dtype=bool) if rob is None else rob
    return FactorGraph(
        n_poses=n_poses,
        n_landmarks=graph.n_landmarks,
        fixed_poses=fixed_poses,
        prior_pose=graph.prior_pose[prior],
        prior_mean=graph.prior_mean[prior],
        prior_sqrt_info=graph.prior_sqrt_info[prior],
        prior_offset=graph.prior_offset[prior] if len(graph.prior_offset) else graph.prior_offset,
        odo_from=graph.odo_from[odo],
        odo_to=graph.odo_to[odo],
        odo_delta=graph.odo_delta[odo],
        odo_sqrt_info=graph.odo_sqrt_info[odo],
        obs_pose=graph.obs_pose[obs],
        obs_landmark=graph.obs_landmark[obs],
        obs_z=graph.obs_z[obs],
        obs_sqrt_info=graph.obs_sqrt_info[obs],
        obs_model=graph.obs_model[obs],
        rob_from=graph.rob_from[rob],
        rob_to=graph.rob_to[rob],
        rob_z=graph.rob_z[rob],
        rob_sqrt_info=graph.rob_sqrt_info[rob],
        lp_landmark=graph.lp_landmark,
        lp_mean=graph.lp_mean,
        lp_sqrt_info=graph.lp_sqrt_info,
        lp_joint=graph.lp_joint,
    )


def without_robot_sightings(graph: FactorGraph, drop: NDArray[np.bool_]) -> FactorGraph:
    """The same graph with the robot sightings flagged in ``drop`` (R,) switched off (zero information)."""
    W = graph.rob_sqrt_info.copy()
    W[drop] = 0.0
    return dataclasses.replace(graph, rob_sqrt_info=W)


def without_observations(graph: FactorGraph, drop: NDArray[np.bool_]) -> FactorGraph:
    """The same graph with the observations flagged in ``drop`` (n_obs,) switched off (zero information)."""
    W = graph.obs_sqrt_info.copy()
    W[drop] = 0.0
    return dataclasses.replace(graph, obs_sqrt_info=W)


def cost(graph: FactorGraph, r: Array, loss: RobustLoss | None = None) -> float:
    """``0.5 * |r|^2``, with the observations' part through the robust loss when one is given.

    Args:
        graph: The factor graph.
        r: Whitened residuals from :func:`evaluate`, shape (n_residuals,).
        loss: Robust loss on observations, or None.
    """
    if loss is None:
        return 0.5 * float(r @ r)
    split = 3 * len(graph.prior_pose) + 3 * len(graph.odo_from)
    end = len(r) - 2 * len(graph.lp_landmark)  # landmark priors: least squares
    s = np.sum(r[split:end].reshape(-1, 2) ** 2, axis=1)
    if not len(s) or s.max() <= loss.quadratic_within:
        return 0.5 * float(r @ r)
    quadratic = float(r[:split] @ r[:split]) + float(r[end:] @ r[end:])
    return 0.5 * quadratic + 0.5 * float(np.sum(loss.rho(s)))


def linearize(
    graph: FactorGraph,
    sparse: SparseLayout,
    poses: Array,
    landmarks: Array,
    loss: RobustLoss | None = None,
    at: JacobianPoint | None = None,
) -> tuple[Array, sp.csr_matrix]:
    """Whitened residuals and their Jacobian with respect to the free variables.

    Args:
        graph: The factor graph.
        sparse: Its layout (from :func:`layout`).
        poses: Pose values, shape (n_poses, 3).
        landmarks: Landmark values, shape (n_landmarks, 2).
        loss: Robust loss on observations: their rows are scaled by ``sqrt(rho'(s))`` (IRLS).
        at: Where some variables' Jacobians are evaluated (default: the given values).

    Returns:
        (r, J): residuals, shape (n_residuals,), and the Jacobian, sparse (n_residuals, n_columns).
    """
    point = None if at is None else at.apply(poses, landmarks)
    e_prior, WJ_prior, e_odo, J_a, J_b, e_obs, J_p, J_l = _errors(graph, poses, landmarks, point)
    W_odo, W_obs = graph.odo_sqrt_info, graph.obs_sqrt_info
    if loss is not None and len(e_obs):
        s = np.sum(_whiten(W_obs, e_obs) ** 2, axis=1)
        W_obs = W_obs * np.sqrt(loss.weight(s))[:, None, None]
    r_parts = [
        _whiten(graph.prior_sqrt_info, e_prior).reshape(-1),
        _whiten(W_odo, e_odo).reshape(-1),
        _whiten(W_obs, e_obs).reshape(-1),
    ]
    data_parts = [
        WJ_prior.reshape(-1),
        (W_odo @ J_a).reshape(-1),
        (W_odo @ J_b).reshape(-1),
        (W_obs @ J_p).reshape(-1),
        (W_obs @ J_l).reshape(-1),
    ]
    if len(graph.rob_from):
        r_rob, WJ_from, WJ_to, _ = _robot_rows(graph, poses, loss, None if point is None else point[0])
        r_parts.append(r_rob.reshape(-1))
        data_parts += [WJ_from.reshape(-1), WJ_to.reshape(-1)]
    if len(graph.lp_landmark):
        r_parts.append(landmark_prior.residuals(graph, landmarks).reshape(-1))
        data_parts.append(landmark_prior.jacobian(graph).reshape(-1))
    r = np.concatenate(r_parts)
    data = np.concatenate(data_parts)[sparse.keep]
    J = sp.csr_matrix((data, (sparse.rows, sparse.cols)), shape=(graph.n_residuals, sparse.n_columns))
    return r, J


class DenseAssembler:
    """Dense Gauss-Newton normal equations ``H = J^T J``, ``g = J^T r`` and the cost, assembled block by block.

    For small problems (a smoother's window) this avoids building the sparse Jacobian: each factor's whitened
    Jacobian blocks are multiplied out and scattered into H with one ``bincount``. Where each block lands is
    worked out once, at construction, and reused for every linearization of the same graph.

    Args:
        graph: The factor graph.
        sparse: Its layout (from :func:`layout`).
    """

    def __init__(self, graph: FactorGraph, sparse: SparseLayout) -> None:
        self.graph, self.n = graph, sparse.n_columns
        n = self.n

        def columns(*blocks: tuple[Index, int]) -> Index:
            """Each factor's columns, its blocks side by side, shape (K, sum of widths); -1 where fixed."""
            parts = [np.where(first[:, None] >= 0, first[:, None] + np.arange(width), -1) for first, width in blocks]
            return np.concatenate(parts, axis=1)

        self._columns = {
            "prior": columns((sparse.pose_column[graph.prior_pose], 3)),
            "odometry": columns((sparse.pose_column[graph.odo_from], 3), (sparse.pose_column[graph.odo_to], 3)),
            "observation": columns(
                (sparse.pose_column[graph.obs_pose], 3), (sparse.landmark_column[graph.obs_landmark], 2)
            ),
        }
        if len(graph.rob_from):
            self._columns["robot"] = columns(
                (sparse.pose_column[graph.rob_from], 3), (sparse.pose_column[graph.rob_to], 3)
            )
        if len(graph.lp_landmark):
            self._columns["landmark prior"] = landmark_prior.columns(graph, sparse.landmark_column)
        h_index, g_index = [], []
        # Which entries of each kind's (K, c, c) block products and (K, c) gradients land (None: all of them).
        self._keep: dict[str, tuple[NDArray[np.bool_] | None, NDArray[np.bool_] | None]] = {}
        for kind, cols in self._columns.items():
            ok = cols >= 0
            ok_h = (ok[:, :, None] & ok[:, None, :]).ravel()
            ok_g = ok.ravel()
            h_index.append((cols[:, :, None] * n + cols[:, None, :]).ravel()[ok_h])
            g_index.append(cols.ravel()[ok_g])
            self._keep[kind] = (None if ok_h.all() else ok_h, None if ok_g.all() else ok_g)
        self._h_index = np.concatenate(h_index)
        self._g_index = np.concatenate(g_index)

    def __call__(
        self, poses: Array, landmarks: Array, loss: RobustLoss | None = None, at: JacobianPoint | None = None
    ) -> tuple[Array, Array, float]:
        """(H (n, n), g (n,), cost) at the given values; cost as :func:`cost`.

        Args:
            poses: Pose values, shape (n_poses, 3).
            landmarks: Landmark values, shape (n_landmarks, 2).
            loss: Robust loss on observations (IRLS weights), or None.
            at: Where some variables' Jacobians are evaluated (default: the given values).
        """
        graph, n = self.graph, self.n
        point = None if at is None else at.apply(poses, landmarks)
        e_prior, WJ_prior, e_odo, J_a, J_b, e_obs, J_p, J_l = _errors(graph, poses, landmarks, point)
        W_odo, W_obs = graph.odo_sqrt_info, graph.obs_sqrt_info
        r_prior, r_odo, r_obs = _whiten(graph.prior_sqrt_info, e_prior), _whiten(W_odo, e_odo), _whiten(W_obs, e_obs)
        total = 0.5 * float(np.sum(r_prior**2) + np.sum(r_odo**2))
        s = np.sum(r_obs**2, axis=1)
        if loss is not None and len(e_obs) and s.max() > loss.quadratic_within:
            total += 0.5 * float(np.sum(loss.rho(s)))
            sqrt_w = np.sqrt(loss.weight(s))
            W_obs, r_obs = W_obs * sqrt_w[:, None, None], r_obs * sqrt_w[:, None]
        else:  # least squares (or a loss that is exactly least squares at every residual here)
            total += 0.5 * float(np.sum(s))
        factors = {
            "prior": (r_prior, WJ_prior),
            "odometry": (r_odo, W_odo @ np.concatenate([J_a, J_b], axis=2)),
            "observation": (r_obs, W_obs @ np.concatenate([J_p, J_l], axis=2)),
        }
        if len(graph.rob_from):
            r_rob, WJ_from, WJ_to, rob_cost = _robot_rows(graph, poses, loss, None if point is None else point[0])
            factors["robot"] = (r_rob, np.concatenate([WJ_from, WJ_to], axis=2))
            total += rob_cost
        if len(graph.lp_landmark):
            r_lp = landmark_prior.residuals(graph, landmarks)
            factors["landmark prior"] = (r_lp, landmark_prior.jacobian(graph))
            total += 0.5 * float(np.sum(r_lp**2))
        h_value, g_value = [], []
        for kind, (r, J) in factors.items():
            keep_h, keep_g = self._keep[kind]
            h = np.einsum("kmi,kmj->kij", J, J).ravel()
            g = np.einsum("kmi,km->ki", J, r).ravel()
            h_value.append(h if keep_h is None else h[keep_h])
            g_value.append(g if keep_g is None else g[keep_g])
        # Casts: bincount with weights sums them in float64 (numpy's stubs give it integers).
        H = cast(Array, np.bincount(self._h_index, np.concatenate(h_value), minlength=n * n)).reshape(n, n)
        g = cast(Array, np.bincount(self._g_index, np.concatenate(g_value), minlength=n))
        return H, g, total
