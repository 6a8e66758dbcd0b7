"""The smoother's marginal prior: fold-in of the oldest pose's factors, release of landmarks, re-anchoring.

The prior is a Gaussian ``d ~ N(mu, Sigma)`` on ``d = x - x_lin`` (heading wrapped) over the oldest window pose
and every landmark it has touched, kept in covariance form: folding a factor in is an exact linear-Gaussian
update (the next pose and new landmarks are appended through their factor, the other observations update it
like a Kalman filter), and eliminating a pose is dropping its rows — the same result as a Schur complement of
the information matrix, at O(n^2) per factor. Its quadratic is never relinearized: it is re-centred (exactly) at
the current estimate before new factors are folded in, and those are linearized there; with
``linearization="invariant"`` (the default) its covariance is also carried there (:func:`carry`).

A window solve sees only the prior's marginal on its pose and the landmarks the window observes
(:func:`reduced`); the others are recovered from their conditional mean afterwards.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as la
from numpy.typing import NDArray
from scipy.stats import chi2

from online_slam.estimators.kalman import apply_update, stacked_jacobian
from online_slam.estimators.linearization import heading_column, transport
from online_slam.estimators.smoother.config import GLOBAL_FALSE_ALARM
from online_slam.estimators.smoother.relinearize import prior_covariance, prior_marginal
from online_slam.factors.graph import FactorGraph, robot_sighting_residual_with_jacobians, sqrt_information
from online_slam.factors.robust import RobustLoss
from online_slam.geometry.angles import wrap
from online_slam.models.fix import fix_residual_with_jacobians
from online_slam.models.motion import odometry_residual_with_jacobians
from online_slam.models.observation import (
    POSITION,
    RANGE_BEARING,
    SIGHTING,
    centred,
    predict_with_jacobians,
    wrap_bearings,
)
from online_slam.models.position import range_bearing_from_position
from online_slam.solvers.least_squares import QuadraticPrior

Array = NDArray[np.float64]
Index = NDArray[np.int64]
Sightings = tuple[Index, Array, Array, Array, NDArray[np.int8]]
"""A pose's sightings: landmark indices (k,), z (k, 2), covariances (k, 2, 2), square-root information (k, 2, 2),
model tags (k,)."""
RobotFold = tuple[Index, Index, Array, Array, Array]
"""Robot sightings between poses the prior holds or fixed poses: (first row of the sighting pose (k,), of the seen
pose (k,), -1 for a fixed pose; z (k, 2); square-root information (k, 2, 2); the fixed poses' values (k, 2, 3),
read where the row is -1)."""
Appended = tuple[Array, Array, Array, Array]
"""A whitened factor that appends a variable: (residual r0, Jacobian on the old pose, on the new variable, the
new variable's linearization point)."""


@dataclass(eq=False)
class Prior:
    """The marginal prior ``d ~ N(mu, Sigma)``, ``d = x - x_lin``, over ``[landmarks..., others..., pose]``.

    The pose comes last, so that its rows and columns are the ones the next pose reuses; ``others`` are the other
    robots' oldest window poses (several robots; none with one).
    """

    pose: int
    """Index of the pose it holds (the oldest window pose)."""
    landmarks: Index
    """Indices of the landmarks it holds, in its order, shape (L,)."""
    x_lin: Array
    """Linearization point of ``[landmarks..., pose]``, shape (2 L + 3,)."""
    mu: Array
    """Mean of d, shape (2 L + 3,)."""
    Sigma: Array
    """Covariance of d, contiguous (n, n), so that Kalman updates run in place
    (:func:`~online_slam.estimators.kalman.downdate`)."""
    others: Index = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """Indices of the other poses it holds (other robots' oldest window poses), in its order, shape (R,)."""

    @property
    def poses(self) -> Index:
        """Every pose it holds, in its order: ``others``, then ``pose``."""
        return np.r_[self.others, self.pose].astype(np.int64)


@dataclass(frozen=True)
class PriorSplit:
    """The prior's state split into the part a window solve sees and the passive landmarks."""

    order: Index
    """State rows of the active landmarks, then of the pose."""
    passive: Index
    """State rows of the passive landmarks."""
    is_active: NDArray[np.bool_]
    """Which of the prior's landmarks are active, shape (L,)."""
    information: Array
    """``Sigma_aa^-1``, the information of the active part, shape (len(order), len(order))."""


def initial_prior(
    start: tuple[int, Array, Array | None], pose: Array, landmark_map: tuple[Array, Array, Array] | None = None
) -> Prior:
    """The prior before any marginalization: the start pose, fixed (Sigma = 0) or with its prior; with a map that
    has a joint covariance, every map landmark too (independent of the start: the map's frame is the start's).

    Args:
        start: (start pose index, its prior mean, its prior covariance or None when fixed).
        pose: The start pose's current estimate, shape (3,).
        landmark_map: (the map landmarks' current estimates (M, 2), the map's positions (M, 2), its joint
            covariance (2M, 2M)), landmarks 0..M-1; None: no landmark.
    """
    index, mean, cov = start
    x_lin = pose.copy()
    mu = mean - x_lin
    mu[2] = wrap(mu[2])
    Sigma = np.zeros((3, 3))
    if cov is not None:
        Sigma[:] = cov
    if landmark_map is None:
        return Prior(index, np.zeros(0, dtype=np.int64), x_lin, mu, Sigma)
    estimates, xy, joint = landmark_map
    n = len(joint)
    both = np.zeros((n + 3, n + 3))
    both[:n, :n], both[n:, n:] = joint, Sigma
    lin = estimates.reshape(-1)
    return Prior(index, np.arange(len(xy), dtype=np.int64), np.r_[lin, x_lin], np.r_[xy.reshape(-1) - lin, mu], both)


def resized(Sigma: Array, size: int, keep: int) -> Array:
    """Sigma itself when the size does not change, else a new contiguous size x size array whose top-left
    ``keep`` x ``keep`` block holds Sigma's (the rest uninitialized)."""
    if len(Sigma) == size:
        return Sigma
    grown = np.empty((size, size))
    grown[:keep, :keep] = Sigma[:keep, :keep]
    return grown


def fuse_repeats(
    indices: Index, z: Array, z_cov: Array, model: NDArray[Any]
) -> tuple[Index, Array, Array, NDArray[Any]]:
    """Merge repeated observations of one landmark from one pose into a single equivalent observation.

    Both measure the same ``h(pose, landmark)``, so their two quadratics sum to one with information
    ``R1^-1 + R2^-1`` centred on the information-weighted mean (bearings averaged relative to the first).
    Repeats of both models are first all expressed as range-bearing (position sightings converted to first
    order, :func:`~online_slam.models.position.range_bearing_from_position`).
    """
    if len(np.unique(indices)) == len(indices):
        return indices, z, z_cov, model
    structured = model.dtype == SIGHTING
    keep_i, keep_z, keep_c, keep_m = [], [], [], []
    for j in dict.fromkeys(indices.tolist()):
        rows = np.flatnonzero(indices == j)
        zs, covs, tag = z[rows], z_cov[rows], model[rows]
        if structured and not np.all(tag["mount"] == tag["mount"][:1]):  # several sensors: all at the centre
            zs, covs = centred(zs, covs, tag)
            tag = np.zeros(len(rows), dtype=SIGHTING)
            tag["tag"] = POSITION
        if structured:  # one sensor: fused in its frame
            mount, tag = tag[:1].copy(), tag["tag"]
        if len(np.unique(tag)) > 1:
            xy = tag == POSITION
            zs, covs, tag = zs.copy(), covs.copy(), np.full(len(rows), RANGE_BEARING, dtype=np.int8)
            zs[xy], covs[xy] = range_bearing_from_position(zs[xy], covs[xy])
        info = np.linalg.inv(covs)
        offsets = wrap_bearings(zs - zs[0], tag)
        cov = np.linalg.inv(info.sum(axis=0))
        mean = wrap_bearings((zs[0] + cov @ np.einsum("kij,kj->i", info, offsets))[None], tag[:1])[0]
        keep_i.append(j)
        keep_z.append(mean)
        keep_c.append(0.5 * (cov + cov.T))
        if structured:
            mount["tag"] = tag[0]
            keep_m.append(mount[0])
        else:
            keep_m.append(tag[0])
    kept = np.array(keep_m, dtype=SIGHTING if structured else np.int8)
    return np.array(keep_i, dtype=np.int64), np.array(keep_z), np.array(keep_c), kept


def carry(Sigma: Array, x_from: Array, x_to: Array) -> None:
    """Carry a one-pose prior's covariance (over ``[landmarks..., pose]``) from ``x_from`` to ``x_to`` in place.

    As the invariant EKF after an update (:func:`~online_slam.estimators.linearization.transport`): the error is
    read on SE_{1+L}(2) (the pose's heading; its position and every landmark's as translations), whose
    unobservable directions do not depend on the estimate, and mapped back to our coordinates at ``x_to``:
    ``Sigma <- T Sigma T^T``, ``T = I + c e_theta^T``, ``c = J (point_to - point_from)`` per position. A turn about
    the origin at ``x_from`` (``[J l..., J p, 1]``) becomes the same turn at ``x_to``.

    Args:
        Sigma: Covariance of ``[landmarks..., pose]``, contiguous, shape (2 L + 3, 2 L + 3).
        x_from: The linearization point it was built at, shape (2 L + 3,).
        x_to: The new linearization point, shape (2 L + 3,).
    """
    n = len(x_to)
    column = np.zeros(n)
    column[: n - 1] = heading_column(x_to[: n - 1].reshape(-1, 2), x_from[: n - 1].reshape(-1, 2)).reshape(-1)
    transport(Sigma, column, heading=n - 1)


CARRY_TURN = 1e-3
"""A window solve that turns the prior's pose by more than this (rad) carries the prior there (:func:`carried`)."""


def carried(prior: Prior, landmarks: Array, pose: Array) -> Prior | None:
    """A one-pose prior re-centred at the current estimate of its variables (``landmarks`` (M, 2), its ``pose``
    (3,)), its covariance carried there (:func:`carry`); None when its pose turned by at most :data:`CARRY_TURN`.

    A solve that turns the prior's pose reads the covariance, built at the old heading, at the new one: the tight
    relative directions then constrain the turn itself and the newest pose's covariance collapses (MRCLAM robot
    4's second half: a 0.16 rad turn took it from 0.73 m to 0.10 m at 1.1 m error). The invariant smoother reads
    a solve's information with this prior; its mean stays where it is.
    """
    if len(prior.others):
        return None
    current, shift = _recentring(prior, landmarks, pose)
    if abs(shift[-1]) <= CARRY_TURN:
        return None
    Sigma = prior.Sigma.copy()
    carry(Sigma, prior.x_lin, current)
    return Prior(prior.pose, prior.landmarks, current, prior.mu - shift, Sigma, prior.others)


def _recentring(prior: Prior, landmarks: Array, pose: Array) -> tuple[Array, Array]:
    """The current estimate of the prior's variables (``landmarks`` (M, 2), the poses it holds (3 R + 3,)) and its
    shift from the prior's linearization point, headings wrapped; each of shape (2 L + 3 R + 3,)."""
    current = np.r_[landmarks[prior.landmarks].reshape(-1), pose]
    shift = current - prior.x_lin
    headings = slice(2 * len(prior.landmarks) + 2, None, 3)
    shift[headings] = wrap(shift[headings])
    return current, shift


def split(prior: Prior, active: Index) -> PriorSplit:
    """The prior's state split by the landmarks a window solve sees (``active``, sorted)."""
    n = len(prior.mu)
    is_active = np.isin(prior.landmarks, active)
    order = np.r_[(2 * np.flatnonzero(is_active)[:, None] + np.arange(2)).reshape(-1), np.arange(2 * len(is_active), n)]
    passive = (2 * np.flatnonzero(~is_active)[:, None] + np.arange(2)).reshape(-1)
    S_aa = prior.Sigma[np.ix_(order, order)]
    try:
        A = la.cho_solve(la.cho_factor(S_aa), np.eye(len(order)))
    except la.LinAlgError:  # rank-deficient: the information of the directions it has
        A = np.linalg.pinv(S_aa, hermitian=True)
    return PriorSplit(order, passive, is_active, 0.5 * (A + A.T))


def reduced(
    prior: Prior, active: Index, pose_columns: Index, landmark_column: Index
) -> tuple[QuadraticPrior, Callable[[Array, Array], tuple[Index, Array]] | None]:
    """The prior's marginal on its poses and the active landmarks, and a function recovering the others.

    Args:
        prior: The marginal prior.
        active: The landmarks the window observes (sorted), shape (A,).
        pose_columns: The column of each prior pose (:attr:`Prior.poses`) in the window system, shape (R + 1,).
        landmark_column: Each active landmark's column in the window system, shape (A,).

    Returns:
        (the quadratic on those columns; None when every landmark of the prior is active, else a function of the
        solved prior poses (R + 1, 3) and active landmarks (A, 2) giving the passive landmarks' indices and
        conditional means (k, 2)).
    """
    s = split(prior, active)
    A = s.information
    mu_a = prior.mu[s.order]
    local = np.searchsorted(active, prior.landmarks[s.is_active])
    columns = np.r_[
        (landmark_column[local][:, None] + np.arange(2)).reshape(-1),
        (pose_columns[:, None] + np.arange(3)).reshape(-1),
    ]
    angle = np.zeros(len(s.order), dtype=bool)
    angle[len(s.order) - 3 * len(pose_columns) + 2 :: 3] = True
    quadratic = QuadraticPrior(columns, prior.x_lin[s.order], angle, A, -A @ mu_a)
    if len(s.passive) == 0:
        return quadratic, None
    passive_ids = prior.landmarks[~s.is_active]

    def recover(prior_poses: Array, active_landmarks: Array) -> tuple[Index, Array]:
        """Passive landmarks at their conditional mean given the solved active part (matrix-vector only)."""
        d_a = np.r_[active_landmarks[local].reshape(-1), prior_poses.reshape(-1)] - prior.x_lin[s.order]
        d_a[angle] = wrap(d_a[angle])
        d_p = prior.mu[s.passive] + prior.Sigma[np.ix_(s.passive, s.order)] @ (A @ (d_a - mu_a))
        return passive_ids, (prior.x_lin[s.passive] + d_p).reshape(-1, 2)

    return quadratic, recover


def marginalize(
    prior: Prior,
    pose: Array,
    landmarks: Array,
    sightings: Sightings | None,
    odometry: tuple[Array, Array],
    next_pose: tuple[int, Array],
    loss: RobustLoss | None,
    linearization: str = "standard",
    robots: RobotFold | None = None,
    fixes: tuple[Array, Array, Array] | None = None,
) -> Prior:
    """Fold the prior pose o's factors into the prior ``[landmarks..., others..., o]``, then eliminate o.

    First o's observations of landmarks the prior holds update it jointly (a Kalman update). Then every
    variable that o's remaining factors determine — landmarks seen for the first time, and the next pose
    n1 through the odometry — is appended from its factor, ``d_new = M d_o - J_new^-1 (r0 + v)`` with
    ``M = -J_new^-1 J_o``; their noises are independent, so one growth of Sigma serves them all and drops o
    on the way: ``[landmarks..., new landmarks..., n1]``. The prior's covariance is updated in place (the
    prior owns it); the result reuses its buffer when the size holds.

    Args:
        prior: The prior on o (``prior.pose``).
        pose: The current estimate of every pose it holds (:attr:`Prior.poses`, o last), shape (3 R + 3,).
        landmarks: Every landmark's current estimate, shape (M, 2).
        sightings: o's sightings to fold in (judged outliers left out), or None.
        odometry: (delta, square-root information) of the odometry from o to n1.
        next_pose: (n1, its current estimate (3,)).
        loss: The robust loss on sightings (IRLS weights at the linearization point).
        linearization: ``standard``: re-centre the prior at the current estimate first and linearize there;
            ``invariant``: the same, its covariance carried there (:func:`carry`; one pose held, else exactly
            re-centred); ``fej``: linearize at the prior's first estimates.
        robots: o's robot sightings of (or by) the other poses the prior holds, or None.
        fixes: o's absolute fixes (mean (f, 3), offset (f, 2), square-root information (f, 3, 3)), or None: they
            update o like the sightings (and leave the window with o, so they are counted once).
    """
    x_lin, mu, Sigma = prior.x_lin, prior.mu, prior.Sigma
    n = len(mu)
    if linearization != "fej":
        current, shift = _recentring(prior, landmarks, pose)
        if linearization == "invariant" and not len(prior.others):
            carry(Sigma, x_lin, current)
        x_lin, mu = current, mu - shift
    lin_o = x_lin[n - 3 :]
    held = list(prior.landmarks)
    appended: list[Appended] = []
    if sightings is not None:
        mu, held, appended = _fold_sightings(Sigma, x_lin, mu, held, sightings, landmarks, loss)
    if robots is not None:
        mu = _fold_robots(Sigma, x_lin, mu, robots, loss)
    if fixes is not None:
        mu = _fold_fixes(Sigma, x_lin, mu, fixes)
    delta, W = odometry
    index, value = next_pose
    e, J_a, J_b = odometry_residual_with_jacobians(lin_o, value, delta)
    appended.append((W @ e, W @ J_a, W @ J_b, value))
    grown = _grown(index, np.array(held, dtype=np.int64), x_lin, mu, Sigma, appended)
    return grown if not len(prior.others) else _landmarks_first(grown, len(prior.landmarks), prior.others)


def _fold_robots(Sigma: Array, x_lin: Array, mu: Array, robots: RobotFold, loss: RobustLoss | None) -> Array:
    """Update the prior with robot sightings between poses it holds (Sigma in place); the updated mean."""
    rows_a, rows_b, z, W, fixed = robots
    pose_a = np.where(rows_a[:, None] >= 0, x_lin[np.maximum(rows_a, 0)[:, None] + np.arange(3)], fixed[:, 0])
    pose_b = np.where(rows_b[:, None] >= 0, x_lin[np.maximum(rows_b, 0)[:, None] + np.arange(3)], fixed[:, 1])
    e, J_a, J_b = robot_sighting_residual_with_jacobians(pose_a, pose_b, z)
    r0 = np.einsum("kij,kj->ki", W, e)
    if loss is not None:
        W = W * np.sqrt(loss.weight(np.sum(r0 * r0, axis=1)))[:, None, None]
        r0 = np.einsum("kij,kj->ki", W, e)
    cols = np.unique(np.r_[rows_a, rows_b])
    cols = cols[cols >= 0]
    where = {int(c): 3 * k for k, c in enumerate(cols)}
    J_s = np.zeros((2 * len(z), 3 * len(cols)))
    for k, (a, b) in enumerate(zip(rows_a.tolist(), rows_b.tolist())):
        for row, J in ((a, J_a[k]), (b, J_b[k])):
            if row >= 0:
                J_s[2 * k : 2 * k + 2, where[row] : where[row] + 3] = W[k] @ J
    cols = (cols[:, None] + np.arange(3)).reshape(-1)
    PHt = Sigma[:, cols] @ J_s.T
    S = J_s @ PHt[cols] + np.eye(len(J_s))  # whitened factors: unit noise
    with contextlib.suppress(np.linalg.LinAlgError):
        dmu, _, _ = apply_update(Sigma, PHt, S, -(r0.reshape(-1) + J_s @ mu[cols]), exactly_symmetric=False)
        mu = mu + dmu
    return mu


def _fold_fixes(Sigma: Array, x_lin: Array, mu: Array, fixes: tuple[Array, Array, Array]) -> Array:
    """Update the prior with absolute fixes of its last pose (Sigma in place); the updated mean."""
    mean, offset, W = fixes
    n = len(mu)
    cols = np.arange(n - 3, n)
    e, J = fix_residual_with_jacobians(x_lin[n - 3 :], offset, mean)
    J_s, r0 = (W @ J).reshape(-1, 3), np.einsum("kij,kj->ki", W, e).reshape(-1)
    rows = np.any(J_s != 0.0, axis=1)  # a fix's zero rows measure nothing
    J_s, r0 = J_s[rows], r0[rows]
    PHt = Sigma[:, cols] @ J_s.T
    S = J_s @ PHt[cols] + np.eye(len(J_s))  # whitened factors: unit noise
    with contextlib.suppress(np.linalg.LinAlgError):
        dmu, _, _ = apply_update(Sigma, PHt, S, -(r0 + J_s @ mu[cols]), exactly_symmetric=False)
        mu = mu + dmu
    return mu


def _landmarks_first(prior: Prior, old: int, others: Index) -> Prior:
    """The grown prior ``[old landmarks..., others..., new landmarks..., pose]`` reordered to
    ``[landmarks..., others..., pose]``."""
    n, new = len(prior.mu), 2 * (len(prior.landmarks) - old)
    if not new:
        return replace(prior, others=others)
    o = 2 * old + 3 * len(others)
    order = np.r_[np.arange(2 * old), np.arange(o, o + new), np.arange(2 * old, o), np.arange(n - 3, n)]
    Sigma = np.ascontiguousarray(prior.Sigma[np.ix_(order, order)])
    return Prior(prior.pose, prior.landmarks, prior.x_lin[order], prior.mu[order], Sigma, others)


def _fold_sightings(
    Sigma: Array,
    x_lin: Array,
    mu: Array,
    held: list[int],
    sightings: Sightings,
    landmarks: Array,
    loss: RobustLoss | None,
) -> tuple[Array, list[int], list[Appended]]:
    """Update the prior with the sightings of the landmarks it holds (``held``, in its order; Sigma in place).

    Returns:
        (the updated mean, ``held`` with the landmarks seen for the first time appended, the factors that
        append them).
    """
    n = len(mu)
    lin_o = x_lin[n - 3 :]
    held = list(held)
    slot = {int(j): k for k, j in enumerate(held)}
    indices, z, z_cov, model = fuse_repeats(*sightings[:3], sightings[4])
    is_held = np.array([int(j) in slot for j in indices], dtype=bool)
    first = ~is_held  # first sight (repeats are fused): appends the landmark
    for j in indices[first]:
        slot[int(j)] = len(held)
        held.append(int(j))
    lin_l = np.array(
        [landmarks[j] if first[k] else x_lin[2 * slot[int(j)] : 2 * slot[int(j)] + 2] for k, j in enumerate(indices)]
    )
    z_hat, J_p, J_l = predict_with_jacobians(lin_o, lin_l, model)
    e = wrap_bearings(z_hat - z, model)
    W = sightings[3] if z_cov is sightings[2] else sqrt_information(z_cov)  # stored unless repeats were fused
    r0 = np.einsum("kij,kj->ki", W, e)
    if loss is not None:
        W = W * np.sqrt(loss.weight(np.sum(r0 * r0, axis=1)))[:, None, None]
        r0 = np.einsum("kij,kj->ki", W, e)
    Jp, Jl = W @ J_p, W @ J_l
    update = np.flatnonzero(is_held)
    if len(update):
        cols = np.r_[
            (2 * np.array([slot[int(indices[k])] for k in update])[:, None] + np.arange(2)).reshape(-1),
            np.arange(n - 3, n),
        ]
        J_s = stacked_jacobian(Jp[update], Jl[update], pose_first=False)
        PHt = Sigma[:, cols] @ J_s.T
        S = J_s @ PHt[cols] + np.eye(len(J_s))  # whitened factors: unit noise
        # in place: the prior owns its covariance (untouched if S is not positive definite in floating point)
        with contextlib.suppress(np.linalg.LinAlgError):
            innovation = -(r0[update].reshape(-1) + J_s @ mu[cols])
            dmu, _, _ = apply_update(Sigma, PHt, S, innovation, exactly_symmetric=False)
            mu = mu + dmu
    return mu, held, [(r0[k], Jp[k], Jl[k], lin_l[k]) for k in np.flatnonzero(first)]


def _grown(index: int, landmarks: Index, x_lin: Array, mu: Array, Sigma: Array, appended: list[Appended]) -> Prior:
    """The prior with the appended variables (the last one the new pose ``index``) and the old pose dropped."""
    n = len(mu)
    inv = [np.linalg.inv(a[2]) for a in appended]
    M = np.vstack([-i @ a[1] for i, a in zip(inv, appended)])  # (q, 3)
    offset = np.concatenate([-i @ a[0] for i, a in zip(inv, appended)])
    noise = la.block_diag(*[i @ i.T for i in inv])
    keep = n - 3
    q = len(M)
    cross = M @ Sigma[:keep, keep:].T  # (q, keep): read o's rows before they are overwritten
    block = M @ Sigma[keep:, keep:] @ M.T + noise
    grown = resized(Sigma, keep + q, keep)  # o's rows and columns are reused when the size holds
    grown[keep:, :keep] = cross
    grown[:keep, keep:] = cross.T
    grown[keep:, keep:] = 0.5 * (block + block.T)
    mu = np.r_[mu[:keep], M @ mu[keep:] + offset]
    x_lin = np.r_[x_lin[:keep], np.concatenate([a[3] for a in appended])]
    return Prior(index, landmarks, x_lin, mu, grown)


def fold_map(prior: Prior, rows: Index, xy: Array, cov: Array) -> None:
    """Fold a map's priors on landmarks the prior holds (rows: their landmark indices, just come in with their
    sightings) into it, in place: a Kalman update with ``H`` selecting them, ``z = xy`` (k, 2), ``R = cov``
    (k, 2, 2). From then on the prior carries them; the window's graph no longer adds them."""
    where = {int(j): i for i, j in enumerate(prior.landmarks)}
    columns = np.array([2 * where[int(j)] + c for j in rows for c in range(2)], dtype=np.int64)
    k = len(rows)
    S = prior.Sigma[np.ix_(columns, columns)].copy()
    S.reshape(k, 2, k, 2)[np.arange(k), :, np.arange(k), :] += cov
    y = (xy - (prior.x_lin[columns] + prior.mu[columns]).reshape(-1, 2)).reshape(-1)
    dx, _, _ = apply_update(prior.Sigma, prior.Sigma[:, columns].copy(), S, y)
    prior.mu += dx


def release(prior: Prior, stale: list[int]) -> tuple[Prior, int]:
    """The prior with landmarks ``stale`` marginalized out (in covariance form: their rows and columns dropped),
    and how many it held."""
    slots = np.flatnonzero(np.isin(prior.landmarks, stale))
    drop = (2 * slots[:, None] + np.arange(2)).reshape(-1)
    keep = np.setdiff1d(np.arange(len(prior.mu)), drop)
    Sigma = np.ascontiguousarray(prior.Sigma[np.ix_(keep, keep)])
    landmarks = np.delete(prior.landmarks, slots)
    return Prior(prior.pose, landmarks, prior.x_lin[keep], prior.mu[keep], Sigma, prior.others), len(slots)


def reanchored(
    prior: Prior,
    past: FactorGraph,
    values: Array,
    landmarks: Array,
    loss: RobustLoss | None,
    information_max: int,
    carried: bool = False,
) -> Prior | None:
    """The prior moved to revised values of the history (see :mod:`~online_slam.estimators.smoother.relinearize`).

    Its linearization point becomes the revised values of its variables and its mean the one the history's
    factors give there; its covariance is relinearized too while it holds at most ``information_max``
    landmarks.

    Args:
        prior: The prior on the oldest window pose (``prior.pose``).
        past: The history's factors (:func:`~online_slam.estimators.smoother.relinearize.history_graph`).
        values: Revised values of poses ``0..prior.pose``, shape (prior.pose + 1, 3).
        landmarks: Revised values of every landmark, shape (M, 2).
        loss: The robust loss on sightings.
        information_max: Most landmarks the prior may hold for its covariance to be relinearized.
        carried: A covariance that is not relinearized is carried to the new point (:func:`carry`; one pose
            held), as the invariant option does.

    Returns:
        The re-anchored prior, or None when the history's pull on the prior's variables, in its own metric,
        exceeds the chi-square bound (an inlier-consistent history gives a chi-square value; a larger one means
        the solve did not reconcile it: a poor minimum).
    """
    relinearized = len(prior.landmarks) <= information_max
    kept = None if not len(prior.others) else prior.poses
    g_k, H_k = prior_marginal(past, values, landmarks, prior.landmarks, loss, relinearized, kept)
    x_lin = np.r_[landmarks[prior.landmarks].reshape(-1), values[-1] if kept is None else values[kept].reshape(-1)]
    Sigma = prior.Sigma if H_k is None else prior_covariance(H_k, prior.Sigma)
    if H_k is None and carried and kept is None:
        Sigma = Sigma.copy()  # the window's prior keeps its own until the revision is taken
        carry(Sigma, prior.x_lin, x_lin)
    if float(g_k @ Sigma @ g_k) > chi2.isf(GLOBAL_FALSE_ALARM, len(g_k)):
        return None
    return Prior(prior.pose, prior.landmarks, x_lin, -(Sigma @ g_k), Sigma, prior.others)
