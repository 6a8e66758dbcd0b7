"""Covariance recovery for the smoother: the newest pose's, association's joint covariance, landmark marginals.

Association asks for the joint covariance of the newest pose and candidate landmarks at every scan. Usually it
is read from the last solve's factored information (:class:`Solved`), carried through the newest odometry
(:func:`propagated_covariance`): this saves linearizing and factoring the window per scan. Otherwise the
window and the reduced prior are linearized at the current estimate (:func:`window_covariance`). Landmarks only
the prior holds are, given the prior's part that the window sees, independent of the rest: their covariance is
the prior's conditional plus that part's uncertainty carried through the regression.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
from numpy.typing import NDArray

from online_slam.estimators.smoother.prior import Prior, PriorSplit, split
from online_slam.estimators.smoother.window import Linearized, Window
from online_slam.factors.graph import SparseLayout
from online_slam.geometry.se2 import compose_with_jacobians

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def locate(ids: Index, wanted: Index) -> tuple[Index, NDArray[np.bool_]]:
    """Where each of ``wanted`` (k,) is in ``ids`` (distinct, any order), and whether it is there; shapes (k,)."""
    if not len(ids):
        return np.zeros(len(wanted), dtype=np.int64), np.zeros(len(wanted), dtype=bool)
    order = np.argsort(ids, kind="stable")
    where = order[np.minimum(np.searchsorted(ids, wanted, sorter=order), len(ids) - 1)]
    return where, ids[where] == wanted


@dataclass(frozen=True, eq=False)
class Solved:
    """The last window solve's factored information, for association covariances until the state moves."""

    window: Index
    """The window poses it solved, shape (P,)."""
    pose_column: Index
    """Column of each window pose in its system (-1: fixed), shape (P,)."""
    active: Index
    """The landmarks it solved (sorted), shape (A,)."""
    landmark_column: Index
    """Column of each active landmark, shape (A,)."""
    factor: Array
    """``scipy.linalg.cho_factor`` of its information (upper triangle), shape (n, n)."""
    exact: bool = True
    """False once judged outliers it holds were dropped from a marginalized pose: its information then holds
    sightings the state no longer does (robust-weighted: near enough for the noise adaptation's statistics,
    not for association, which linearizes the window then)."""

    def columns(self, landmarks: Index) -> Index:
        """The columns of these solved landmarks (k,), shape (2k,)."""
        return (self.landmark_column[locate(self.active, landmarks)[0]][:, None] + np.arange(2)).reshape(-1)


def factored(
    information: Array | None, window: list[int], sparse: SparseLayout, active: Index
) -> tuple[Array, Solved | None] | None:
    """The newest pose's covariance from a window solve's information, and that information factored.

    Args:
        information: The solve's information at its solution (dense or sparse), or None.
        window: The window poses it solved, oldest first.
        sparse: Its layout.
        active: The landmarks it solved (sorted).

    Returns:
        None when the newest pose was fixed or there is no information (the pose covariance stays); else
        (the newest pose's covariance (3, 3), the factored information), NaN and None where it is singular.
    """
    newest = sparse.pose_column[len(window) - 1]
    if newest < 0 or information is None:
        return None
    H = information
    H = H.toarray() if hasattr(H, "toarray") else H
    unit = np.zeros((H.shape[0], 3))
    unit[newest + np.arange(3), np.arange(3)] = 1.0
    try:
        factor, _ = la.cho_factor(H, lower=False)
        cov = la.cho_solve((factor, False), unit)[newest : newest + 3]
    except (la.LinAlgError, ValueError):  # singular, or not finite
        return np.full((3, 3), np.nan), None
    solved = Solved(
        np.array(window, dtype=np.int64),
        sparse.pose_column[: len(window)].copy(),
        active,
        sparse.landmark_column[: len(active)].copy(),
        factor,
    )
    return 0.5 * (cov + cov.T), solved


def pose_marginals(solved: Solved, poses: list[int]) -> dict[int, Array]:
    """The marginal covariance (3, 3) of each of these window poses from a solve's factored information (poses it
    held fixed, or did not solve, left out)."""
    position = {int(g): k for k, g in enumerate(solved.window.tolist())}
    wanted = [(g, int(solved.pose_column[position[g]])) for g in poses if g in position]
    wanted = [(g, c) for g, c in wanted if c >= 0]
    if not wanted:
        return {}
    unit = np.zeros((solved.factor.shape[0], 3 * len(wanted)))
    for k, (_, c) in enumerate(wanted):
        unit[c + np.arange(3), 3 * k + np.arange(3)] = 1.0
    cov = la.cho_solve((solved.factor, False), unit)
    out = {}
    for k, (g, c) in enumerate(wanted):
        block = cov[c : c + 3, 3 * k : 3 * k + 3]
        out[g] = 0.5 * (block + block.T)
    return out


UNKNOWN_VARIANCE = 1e6
"""Every variance of the joint covariance :func:`window_covariance` gives when it has no information to read (a
window not yet linearizable, a map's landmark without its covariance): gates pass everything, and noise adaptation
reads nothing from it (:func:`is_unknown`)."""


def is_unknown(joint: Array) -> bool:
    """Whether ``joint`` is the covariance :func:`window_covariance` gives when it knows nothing."""
    return bool(np.array_equal(joint, np.eye(len(joint)) * UNKNOWN_VARIANCE))


def window_covariance(
    linearized: Linearized,
    prior: Prior | None,
    indices: Index,
    unheld: Callable[[Index], Array | None] | None = None,
) -> Array:
    """Joint covariance of the newest pose and landmarks ``indices`` (c,) from a linearized window, shape
    (3 + 2c, 3 + 2c).

    Landmarks the window observes read the inverse information; landmarks only the prior holds are its
    conditional given the part the window shares, propagated; landmarks neither holds (a map's, not seen yet)
    their own covariance, independent of the rest (``unheld`` gives it for some landmarks, or None). A landmark
    nothing constrains (cannot happen with a consistent state) gives a large diagonal.
    """
    c = len(indices)
    active, sparse, quadratic, H = linearized.active, linearized.layout, linearized.quadratic, linearized.information
    rows = 3 + 2 * c
    fallback = np.eye(rows) * UNKNOWN_VARIANCE
    if H is None:
        return fallback
    n = len(H)
    L = np.zeros((rows, n))
    N = np.zeros((rows, rows))
    newest = sparse.pose_column[linearized.poses - 1]
    if newest >= 0:
        L[np.arange(3), newest + np.arange(3)] = 1.0
    position, is_active = locate(active, indices)
    for k in np.flatnonzero(is_active):
        column = sparse.landmark_column[position[k]]
        L[3 + 2 * k + np.arange(2), column + np.arange(2)] = 1.0
    passive_k = np.flatnonzero(~is_active)
    slots, held = np.zeros(len(passive_k), dtype=np.int64), np.zeros(len(passive_k), dtype=bool)
    if len(passive_k) and prior is not None and quadratic is not None:
        slots, held = locate(prior.landmarks, indices[passive_k])
    if not held.all():  # a map's landmarks not seen yet: their own prior, independent of the window's variables
        block = None if unheld is None else unheld(indices[passive_k[~held]])
        if block is None:
            return fallback
        free_rows = (3 + 2 * passive_k[~held][:, None] + np.arange(2)).reshape(-1)
        N[np.ix_(free_rows, free_rows)] = block
        passive_k, slots = passive_k[held], slots[held]
    if len(passive_k):
        assert prior is not None and quadratic is not None  # held: the prior holds them
        s = split(prior, active)
        state_rows = (2 * slots[:, None] + np.arange(2)).reshape(-1)
        S_pa = prior.Sigma[np.ix_(state_rows, s.order)]
        B = S_pa @ s.information
        out_rows = (3 + 2 * passive_k[:, None] + np.arange(2)).reshape(-1)
        L[np.ix_(out_rows, quadratic.columns)] = B
        N[np.ix_(out_rows, out_rows)] = prior.Sigma[np.ix_(state_rows, state_rows)] - B @ S_pa.T
    try:
        X = la.cho_solve(la.cho_factor(H), L.T)
    except (la.LinAlgError, ValueError):
        return fallback
    joint = L @ X + N
    return 0.5 * (joint + joint.T)


def propagated_covariance(
    solved: Solved | None, window: Window, prior: Prior | None, indices: Index, exact: bool = True
) -> Array | None:
    """The joint covariance of :func:`window_covariance` from the last solve's factored information, or None if
    it does not apply.

    It applies while nothing moved since that solve but the newest pose's odometry: the newest pose is then
    the solved one composed with it, and its joint covariance with the landmarks is the solved one carried
    through the composition's Jacobians. Marginalizing old poses since does not change the remaining
    variables' marginal (exact for the linearized system with a re-centred marginalization, ``standard`` and
    ``invariant``; with ``linearization="fej"`` up to the prior's older linearization points). A landmark only the prior
    holds is, given the prior's part that the solve saw (its pose and solved landmarks), independent of the
    rest: its covariance is the prior's conditional plus that part's solved covariance carried through the
    regression. None when the state moved otherwise (the owner drops ``solved`` then: a sighting was added, a
    global solve handed over, a landmark released), and, when ``exact``, after judged outliers were dropped from a
    marginalized pose (:attr:`Solved.exact`).
    """
    applies, carry = _carry(solved, window)
    if solved is None or not applies or (exact and not solved.exact):
        return None
    s, c = solved, len(indices)
    _, is_solved = locate(s.active, indices)
    passive = np.flatnonzero(~is_solved)
    # The joint is R^T H^-1 R (+ the prior's conditional), R mapping it onto the solved system's columns.
    R = np.zeros((len(s.factor), 3 + 2 * c))
    R[s.pose_column[-1] + np.arange(3), np.arange(3)] = 1.0
    known = 3 + (2 * np.flatnonzero(is_solved)[:, None] + np.arange(2)).reshape(-1)
    R[s.columns(indices[is_solved]), known] = 1.0
    conditional = None
    if len(passive):
        regression = _passive_regression(s, prior, indices[passive])
        if regression is None:
            return None
        a_columns, B, S_cond = regression
        out = 3 + (2 * passive[:, None] + np.arange(2)).reshape(-1)
        R[np.ix_(a_columns, out)] = B.T
        conditional = (out, S_cond)
    P = R.T @ la.cho_solve((s.factor, False), R)
    if conditional is not None:
        P[np.ix_(conditional[0], conditional[0])] += conditional[1]
    if carry is not None:
        F, noise = carry
        P[:3] = F @ P[:3]
        P[:, :3] = P[:, :3] @ F.T
        P[:3, :3] += noise
    return 0.5 * (P + P.T)


def _carry(solved: Solved | None, window: Window) -> tuple[bool, tuple[Array, Array] | None]:
    """Whether the last solve still applies, and how its newest pose reaches the current one: None (it is the
    same) or (F, noise) through the newest odometry."""
    if solved is None:
        return False, None
    newest = window.indices[-1]
    if newest == solved.window[-1] and not window.unsolved:
        return True, None
    if len(window.indices) > 1 and window.indices[-2] == solved.window[-1] and window.unsolved == {newest}:
        if (
            newest in window.observations
            or newest not in window.odometry  # another robot's start: no increment from the solved pose
            or window.previous.get(newest, solved.window[-1]) != solved.window[-1]
        ):
            return False, None
        delta, Q, _ = window.odometry[newest]
        _, F, G = compose_with_jacobians(window.poses[solved.window[-1]], delta)
        return True, (F, G @ Q @ G.T)
    return False, None


def _passive_regression(s: Solved, prior: Prior | None, wanted: Index) -> tuple[Index, Array, Array] | None:
    """The regression ``d_p = B d_a + noise`` of landmarks only the prior holds (``wanted``, (k,)) on the prior's
    part the solve saw: (that part's columns in the solved system (q,), B (2k, q), the conditional covariance
    (2k, 2k)), or None when it does not apply."""
    if prior is None or not len(prior.landmarks):
        return None
    prior_poses, solved = locate(s.window, prior.poses)
    if not solved.all() or (s.pose_column[prior_poses] < 0).any():  # a prior pose not solved, or fixed
        return None
    slot, held = locate(prior.landmarks, wanted)
    if not held.all():  # not in the prior either (inconsistent state)
        return None
    is_held = np.isin(prior.landmarks, s.active)
    n = len(prior.mu)
    order = np.r_[(2 * np.flatnonzero(is_held)[:, None] + np.arange(2)).reshape(-1), np.arange(2 * len(is_held), n)]
    rows = (2 * slot[:, None] + np.arange(2)).reshape(-1)
    S_pa = prior.Sigma[np.ix_(rows, order)]
    try:
        B = la.cho_solve(la.cho_factor(prior.Sigma[np.ix_(order, order)]), S_pa.T).T  # (2k, q)
    except (la.LinAlgError, ValueError):
        return None
    a_columns = np.r_[
        s.columns(prior.landmarks[is_held]), (s.pose_column[prior_poses][:, None] + np.arange(3)).reshape(-1)
    ]
    return a_columns, B, prior.Sigma[np.ix_(rows, rows)] - B @ S_pa.T


@dataclass(frozen=True)
class Passive:
    """The landmarks only the prior holds, as a regression on the part of it the window sees (``d_a``):
    ``d_p = mu_p + B (d_a - mu_a) + noise``."""

    split: PriorSplit
    """The prior's state split (active part, passive landmarks)."""
    S_pa: Array
    """The prior's covariance of the passive landmarks with the active part, shape (2P, q)."""
    B: Array
    """The regression, ``S_pa Sigma_aa^-1``, shape (2P, q)."""
    C_a: Array
    """The window's covariance of the active part now, shape (q, q)."""


def _inverse(linearized: Linearized, prior: Prior | None) -> tuple[Array | None, Passive | None]:
    """(The inverse of the window's information, None when it has no free variable or is singular; the passive
    landmarks' regression, None when there are none)."""
    H, quadratic = linearized.information, linearized.quadratic
    if H is None:  # no free variable
        return None, None
    try:
        C = la.cho_solve(la.cho_factor(H), np.eye(len(H)))
    except (la.LinAlgError, ValueError):  # singular, or not finite
        return None, None
    if prior is None or quadratic is None:
        return C, None
    s = split(prior, linearized.active)
    if len(s.passive) == 0:
        return C, None
    S_pa = prior.Sigma[np.ix_(s.passive, s.order)]
    return C, Passive(s, S_pa, S_pa @ s.information, C[np.ix_(quadratic.columns, quadratic.columns)])


def landmark_marginals(linearized: Linearized, prior: Prior | None, count: int) -> Array:
    """2x2 marginal covariance of every landmark (``count``) from a linearized window, shape (M, 2, 2).

    Landmarks a window pose observes read their block of the inverse information; passive landmarks add the
    prior's conditional covariance to the propagated uncertainty of the part they are conditioned on. NaN
    where the system is singular.
    """
    out = np.full((count, 2, 2), np.nan)
    active, sparse = linearized.active, linearized.layout
    C, passive = _inverse(linearized, prior)
    if C is None:
        return out
    cols = sparse.landmark_column[np.arange(len(active))][:, None] + np.arange(2)  # (A, 2)
    out[active] = C[cols[:, :, None], cols[:, None, :]]
    if passive is None or prior is None:
        return out
    s, B = passive.split, passive.B
    q = len(s.order)
    B3, S3 = B.reshape(-1, 2, q), passive.S_pa.reshape(-1, 2, q)
    pairs = s.passive.reshape(-1, 2)
    S_pp = prior.Sigma[pairs[:, :, None], pairs[:, None, :]]
    conditional = S_pp - np.einsum("piq,pjq->pij", B3, S3)
    propagated = np.einsum("piq,qr,pjr->pij", B3, passive.C_a, B3)
    blocks = conditional + propagated
    out[prior.landmarks[~s.is_active]] = 0.5 * (blocks + blocks.transpose(0, 2, 1))
    return out


def landmark_joint(linearized: Linearized, prior: Prior | None, count: int) -> Array:
    """Joint covariance of every landmark (``count``) from a linearized window, shape (2M, 2M), rows ``[x0, y0,
    x1, ...]``: as :func:`landmark_marginals`, with the cross terms. Given the part of the prior the window sees
    (``d_a``), a passive landmark is ``d_p = mu_p + B (d_a - mu_a) + noise``, so ``cov(d_p, v) = B cov(d_a, v)``
    for any window variable ``v`` and ``cov(d_p) = S_pp - B S_ap + B C_a B^T``. NaN where the system is singular,
    and for a landmark neither observed nor held by the prior."""
    out = np.full((2 * count, 2 * count), np.nan)
    active, sparse, quadratic = linearized.active, linearized.layout, linearized.quadratic
    C, passive = _inverse(linearized, prior)
    if C is None:
        return out
    columns = (sparse.landmark_column[np.arange(len(active))][:, None] + np.arange(2)).reshape(-1)
    rows = (2 * active[:, None] + np.arange(2)).reshape(-1)
    out[np.ix_(rows, rows)] = C[np.ix_(columns, columns)]
    if passive is None or prior is None or quadratic is None:
        return out
    s, B = passive.split, passive.B
    p_rows = (2 * prior.landmarks[~s.is_active][:, None] + np.arange(2)).reshape(-1)
    cross = B @ C[np.ix_(quadratic.columns, columns)]
    out[np.ix_(p_rows, rows)] = cross
    out[np.ix_(rows, p_rows)] = cross.T
    pp = prior.Sigma[np.ix_(s.passive, s.passive)] - B @ passive.S_pa.T + B @ passive.C_a @ B.T
    out[np.ix_(p_rows, p_rows)] = 0.5 * (pp + pp.T)
    return out
