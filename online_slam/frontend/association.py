"""Data association for sightings without landmark ids: nearest neighbour and joint compatibility (JCBB).

Pure math over a Gaussian belief of the robot pose and the landmarks: state ``s = [pose (3), l_1 .. l_M (2 each)]``
with covariance ``P`` (the EKF's own; a smoother can give pose and landmark marginals, cross terms zero). A
sighting ``z_i`` (range-bearing, or a position in the robot frame: each with its own model ``h``, tagged per
sighting; noise ``R_i``) and a landmark ``j`` give the innovation ``nu_ij = z_i - h(pose, l_j)`` (a bearing
wrapped) with Jacobian ``H_ij`` (``dh/dpose`` at the pose's columns, ``dh/dl`` at
``l_j``'s) and covariance ``S_ij = H_ij P H_ij^T + R_i`` — the measurement noise is part of it (PythonRobotics'
EKF-SLAM builds it from the state block alone, with a fixed threshold of 2.0).

- Individual compatibility: ``nu^T S^-1 nu <= chi2.isf(1 - p, 2)``.
- Nearest neighbour: compatible pairs by increasing distance, each sighting and each landmark used at most once.
- JCBB (Neira & Tardos, 2001): branch and bound over the sightings of one scan for the hypothesis with the most
  pairings whose *joint* innovation ``nu_H`` passes ``nu_H^T S_H^-1 nu_H <= chi2.isf(1 - p, 2 |H|)`` with
  ``S_H = H_H P H_H^T + blockdiag(R)`` (ties: the smaller joint distance). Sightings paired with nothing are
  candidates for new landmarks. The search is exponential in the worst case; it runs per scan, over
  individually compatible pairs only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg.lapack import dtrtrs
from scipy.stats import chi2

from online_slam.models.observation import (
    RANGE_BEARING,
    as_models,
    landmark_from_sighting_with_jacobians,
    predict_with_jacobians,
    wrap_bearings,
)

Array = NDArray[np.float64]
Index = NDArray[np.int64]

METHODS = ("nn", "jcbb")
"""Association methods for sightings without ids."""


@dataclass(frozen=True)
class Belief:
    """What an estimator believes, as association needs it (M landmarks)."""

    pose: Array
    """Robot pose ``[x, y, theta]``, shape (3,)."""
    landmarks: Array
    """Landmark positions, shape (M, 2)."""
    covariance: Array
    """Covariance of ``[pose, l_1 .. l_M]``, shape (3 + 2M, 3 + 2M)."""


@dataclass(frozen=True)
class Association:
    """One scan's pairing."""

    landmark: Index
    """Landmark index (into the belief's landmarks) of each sighting, -1 for none, shape (k,)."""
    joint_distance: float
    """Joint squared Mahalanobis distance of the pairings (0 with none)."""
    distances: Array
    """Individual squared Mahalanobis distance of every (sighting, landmark) pair, shape (k, M)."""


@dataclass(frozen=True)
class Predictions:
    """Every landmark's predicted sighting under each model a scan uses (T models), and each sighting's model."""

    row: Index
    """Each sighting's model: its row in the tables, shape (k,)."""
    z_hat: Array
    """Predicted sightings, shape (T, M, 2)."""
    J_p: Array
    """Their Jacobians with respect to the pose, shape (T, M, 2, 3)."""
    J_l: Array
    """Their Jacobians with respect to the landmark, shape (T, M, 2, 2)."""


def predictions(belief: Belief, model: ArrayLike, k: int) -> Predictions:
    """The belief's predictions for k sightings with model tags ``model`` ((k,), or one for all)."""
    tags = as_models(model, k)
    present, row = np.unique(tags, return_inverse=True)
    tables = [predict_with_jacobians(belief.pose[None, :], belief.landmarks, m) for m in present]
    z_hat, J_p, J_l = (np.stack(parts) for parts in zip(*tables))
    return Predictions(row.reshape(k).astype(np.int64), z_hat, J_p, J_l)


def _innovations(belief: Belief, z: Array, model: ArrayLike) -> tuple[Array, Predictions]:
    """nu (k, M, 2), and the predictions (with Jacobians) at the belief."""
    p = predictions(belief, model, len(z))
    nu = wrap_bearings(z[:, None, :] - p.z_hat[p.row], np.asarray(model)[..., None])
    return nu, p


def individual_distances(belief: Belief, z: Array, R: Array, model: ArrayLike = RANGE_BEARING) -> Array:
    """Squared Mahalanobis distance of every (sighting, landmark) pair, shape (k, M).

    Args:
        belief: Pose, landmarks and their joint covariance.
        z: Sightings, shape (k, 2).
        R: Their noise covariances, shape (k, 2, 2).
        model: Their model tags (k,), or one tag for all (default range-bearing).
    """
    return individual_log_likelihoods(belief, z, R, model)[0]


def _projected(P: Array, J_p: Array, J_l: Array) -> Array:
    """``H P H^T`` of every landmark's sighting (M, 2, 2), H its Jacobians (M, 2, 3) and (M, 2, 2)."""
    M = len(J_p)
    cols = 3 + 2 * np.arange(M)
    P_pp = P[:3, :3]
    P_pl = np.stack([P[:3, c : c + 2] for c in cols])  # (M, 3, 2)
    P_ll = np.stack([P[c : c + 2, c : c + 2] for c in cols])  # (M, 2, 2)
    return (
        J_p @ P_pp @ np.swapaxes(J_p, 1, 2)
        + J_p @ P_pl @ np.swapaxes(J_l, 1, 2)
        + J_l @ np.swapaxes(P_pl, 1, 2) @ np.swapaxes(J_p, 1, 2)
        + J_l @ P_ll @ np.swapaxes(J_l, 1, 2)
    )


def individual_log_likelihoods(
    belief: Belief, z: Array, R: Array, model: ArrayLike = RANGE_BEARING
) -> tuple[Array, Array]:
    """Squared Mahalanobis distances ``d2`` and log densities ``-d2 / 2 - log(2 pi sqrt(det S))`` of every
    (sighting, landmark) pair, shapes (k, M) each (densities per unit of the sighting's z: range x bearing, or
    area)."""
    k, M = len(z), len(belief.landmarks)
    if k == 0 or M == 0:
        return np.full((k, M), np.inf), np.full((k, M), -np.inf)
    nu, p = _innovations(belief, z, model)
    HPH = np.stack([_projected(belief.covariance, J_p, J_l) for J_p, J_l in zip(p.J_p, p.J_l)])  # (T, M, 2, 2)
    S = HPH[p.row] + R[:, None, :, :]  # (k, M, 2, 2)
    d2 = np.einsum("kmi,kmi->km", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    log_det = np.log(S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] * S[..., 1, 0])
    return d2, -0.5 * d2 - 0.5 * log_det - np.log(2.0 * np.pi)


def nearest_neighbour(
    belief: Belief, z: Array, R: Array, gate_probability: float = 0.99, model: ArrayLike = RANGE_BEARING
) -> Association:
    """Pair each sighting with its nearest individually compatible landmark, each landmark at most once.

    Pairs are taken by increasing distance (the globally nearest first), so a landmark goes to the sighting
    closest to it. ``model``: the sightings' model tags (k,), or one for all.
    """
    d2 = individual_distances(belief, z, R, model)
    gate = chi2.isf(1.0 - gate_probability, 2)
    out = np.full(len(z), -1, dtype=np.int64)
    used: set[int] = set()
    total = 0.0
    for flat in np.argsort(d2, axis=None, kind="stable"):
        i, j = np.unravel_index(flat, d2.shape)
        if d2[i, j] > gate:
            break
        if out[i] < 0 and int(j) not in used:
            out[i], total = j, total + float(d2[i, j])
            used.add(int(j))
    return Association(out, total, d2)


MAX_NODES = 20000
"""JCBB explores at most this many hypotheses per scan, then keeps the best found (bounds the worst case)."""


def jcbb(
    belief: Belief,
    z: Array,
    R: Array,
    gate_probability: float = 0.99,
    max_nodes: int = MAX_NODES,
    model: ArrayLike = RANGE_BEARING,
) -> Association:
    """Joint compatibility branch and bound: the largest jointly compatible pairing of one scan.

    The joint distance grows by one Schur complement per pairing added: the Cholesky factor of ``S_H`` is kept
    along the search and grown by one block row (a triangular solve, O(m^2) for m pairings, not a new 2m x 2m
    solve). ``S_H^-1`` updated by blocks instead lost all precision by 15 pairings (negative joint distances).

    Args:
        belief: Pose, landmarks and their joint covariance.
        z: The scan's sightings, shape (k, 2).
        R: Their noise covariances, shape (k, 2, 2).
        gate_probability: Probability that a true pairing passes the (individual and joint) chi-square tests.
        max_nodes: Hypotheses explored at most (the best found so far is kept when the budget runs out).
        model: The sightings' model tags (k,), or one for all (default range-bearing).

    Returns:
        The pairing (most pairings; among those, the smallest joint distance).
    """
    k = len(z)
    d2 = individual_distances(belief, z, R, model)
    limits = chi2.isf(1.0 - gate_probability, 2 * np.arange(1, k + 1))
    candidates = [[int(j) for j in np.argsort(row, kind="stable") if row[j] <= limits[0]] for row in d2]
    best: list = [[], np.inf]  # pairs, joint distance
    if not any(candidates):
        return Association(np.full(k, -1, dtype=np.int64), 0.0, d2)
    innovations, p = _innovations(belief, z, model)  # (k, M, 2)
    GPG, q_of = _pair_covariances(belief.covariance, p, candidates)
    nodes = [0]

    def search(i: int, pairs: list[tuple[int, int]], rows: Index, L: Array, y: Array, distance: float) -> None:
        """Extend the hypothesis ``pairs`` (its S_H = L L^T, ``y = L^-1 nu_H``, distance ``|y|^2``) at sighting i."""
        nodes[0] += 1
        if i == k:
            if len(pairs) > len(best[0]) or (len(pairs) == len(best[0]) and distance < best[1]):
                best[0], best[1] = list(pairs), distance
            return
        used = {p[1] for p in pairs}
        m = len(pairs)
        for j in candidates[i]:
            if j in used or nodes[0] >= max_nodes:
                continue
            b = 2 * q_of[i, j]
            s = GPG[b : b + 2, b : b + 2] + R[i]
            e = innovations[i, j]
            if m:
                w = dtrtrs(L, GPG[rows, b : b + 2], lower=1)[0]  # L^-1 cov(nu_H, nu_b) (LAPACK's: no wrapper)
                s = s - w.T @ w  # the Schur complement: the new innovation's covariance given the hypothesis'
                e = e - w.T @ y
            # 2 x 2 Cholesky factor of s; not positive definite (NaN included): no such pairing
            if not s[0, 0] > 0.0:
                continue
            l00 = math.sqrt(s[0, 0])
            l10 = s[1, 0] / l00
            d = s[1, 1] - l10 * l10
            if not (d > 0.0 and math.isfinite(d)):
                continue
            l11 = math.sqrt(d)
            y0 = e[0] / l00
            y1 = (e[1] - l10 * y0) / l11
            joint = distance + y0 * y0 + y1 * y1
            if joint > limits[m]:
                continue
            grown = np.zeros((2 * m + 2, 2 * m + 2))
            grown[: 2 * m, : 2 * m] = L
            if m:
                grown[2 * m :, : 2 * m] = w.T
            grown[2 * m, 2 * m], grown[2 * m + 1, 2 * m], grown[2 * m + 1, 2 * m + 1] = l00, l10, l11
            search(i + 1, [*pairs, (i, j)], np.append(rows, (b, b + 1)), grown, np.append(y, (y0, y1)), joint)
        remaining = len(pairs) + (k - i - 1)
        if remaining > len(best[0]) or (remaining == len(best[0]) and distance < best[1]):
            search(i + 1, pairs, rows, L, y, distance)  # leave sighting i unpaired, if that can still win

    search(0, [], np.zeros(0, dtype=np.int64), np.zeros((0, 0)), np.zeros(0), 0.0)
    out = np.full(k, -1, dtype=np.int64)
    for i, j in best[0]:
        out[i] = j
    return Association(out, float(best[1]) if best[0] else 0.0, d2)


def _pair_covariances(P: Array, p: Predictions, candidates: list[list[int]]) -> tuple[Array, Index]:
    """``G_a P G_b^T`` of every two candidate pairs at once: (2Q, 2Q), pair q's rows ``2q, 2q + 1``; and q of each
    (sighting, landmark) pair, shape (k, M) (-1: not a candidate). G: a pair's sighting Jacobian in the state,
    restricted to the pose's and the candidate landmarks' columns (the search reads slices, not solves)."""
    k, M = len(candidates), p.J_p.shape[1]
    pair_i = np.array([i for i, row in enumerate(candidates) for _ in row], dtype=np.int64)
    pair_j = np.array([j for row in candidates for j in row], dtype=np.int64)
    Q, model = len(pair_i), p.row[pair_i]
    q_of = np.full((k, M), -1, dtype=np.int64)
    q_of[pair_i, pair_j] = np.arange(Q)
    landmarks, slot = np.unique(pair_j, return_inverse=True)
    columns = np.concatenate([np.arange(3), (3 + 2 * landmarks[:, None] + np.arange(2)).ravel()])
    G = np.zeros((Q, 2, len(columns)))
    G[:, :, :3] = p.J_p[model, pair_j]
    placed = 3 + 2 * slot.reshape(-1)[:, None] + np.arange(2)  # (Q, 2): the landmark's columns in G
    G[np.arange(Q)[:, None, None], np.arange(2)[None, :, None], placed[:, None, :]] = p.J_l[model, pair_j]
    rows = G.reshape(2 * Q, len(columns))
    return rows @ P[np.ix_(columns, columns)] @ rows.T, q_of


def associate(
    method: str, belief: Belief, z: Array, R: Array, gate_probability: float = 0.99, model: ArrayLike = RANGE_BEARING
) -> Association:
    """``nn`` or ``jcbb`` on one scan (``model``: the sightings' model tags (k,), or one for all)."""
    if method == "nn":
        return nearest_neighbour(belief, z, R, gate_probability, model)
    if method == "jcbb":
        return jcbb(belief, z, R, gate_probability, model=model)
    raise ValueError(f"association method must be one of {', '.join(METHODS)}, not {method!r}")


def joint_log_likelihood(
    belief: Belief, z: Array, R: Array, landmark: Index, model: ArrayLike = RANGE_BEARING
) -> float:
    """Log density of a scan's paired sightings under one pairing (``landmark``: index per sighting, -1 for
    none), their innovations taken jointly: ``-(nu^T S^-1 nu + log det(2 pi S)) / 2`` with
    ``S = H P H^T + blockdiag(R)`` over the paired sightings (0 when none is paired)."""
    rows = np.flatnonzero(landmark >= 0)
    if len(rows) == 0:
        return 0.0
    tags = as_models(model, len(z))[rows]
    nu, p = _innovations(belief, z[rows], tags)
    cols = landmark[rows]
    m, n = len(rows), len(belief.covariance)
    H = np.zeros((2 * m, n))
    for a, (t, j) in enumerate(zip(p.row, cols)):
        H[2 * a : 2 * a + 2, :3] = p.J_p[t, j]
        H[2 * a : 2 * a + 2, 3 + 2 * j : 5 + 2 * j] = p.J_l[t, j]
    S = H @ belief.covariance @ H.T
    for a, i in enumerate(rows):
        S[2 * a : 2 * a + 2, 2 * a : 2 * a + 2] += R[i]
    e = nu[np.arange(m), cols].reshape(-1)
    sign, log_det = np.linalg.slogdet(S)
    if sign <= 0:
        return -np.inf
    return float(-0.5 * (e @ np.linalg.solve(S, e) + log_det + 2 * m * np.log(2.0 * np.pi)))


def rival_ratio(
    belief: Belief,
    z: Array,
    R: Array,
    pairing: Association,
    distinct: float,
    gate_probability: float = 0.99,
    model: ArrayLike = RANGE_BEARING,
    gate: float | None = None,
) -> float:
    """How likely the best rival of a scan's pairing is, relative to it (0: none).

    A rival pairs as many of the scan's sightings, jointly compatible, with none of the landmarks the sensor alone
    cannot tell apart from the pairing's own: landmarks whose distance from a sighting's paired landmark, against
    that sighting's world point covariance from its noise alone, is within ``distinct`` (a chi-square, 2 dof).
    Such a rival differs from the pairing by where it puts the robot, not by the sensor's noise: both pass the
    gates only because the pose is uncertain. ``gate``: the individual gate, if known (else from
    ``gate_probability``).
    """
    paired = np.flatnonzero(pairing.landmark >= 0)
    if len(paired) == 0:
        return 0.0
    gate = chi2.isf(1.0 - gate_probability, 2) if gate is None else gate
    passing: NDArray[np.bool_] = np.asarray((pairing.distances[paired] <= gate).any(axis=0))  # in some one's gate
    passing[pairing.landmark[paired]] = False
    if not passing.any():
        return 0.0
    L = belief.landmarks
    tags = as_models(model, len(z))[paired]
    J = landmark_from_sighting_with_jacobians(belief.pose[None, :], z[paired], tags)[2]
    points = J @ R[paired] @ np.swapaxes(J, 1, 2)  # (p, 2, 2): each sighting's world point, its noise alone
    d = L[None, :, :] - L[pairing.landmark[paired]][:, None, :]  # (p, M, 2)
    near = (np.einsum("pmi,pij,pmj->pm", d, np.linalg.inv(points), d) <= distinct).any(axis=0)
    others = np.flatnonzero(~near & passing)  # rival candidates: elsewhere, and passing the gate
    if len(others) == 0:
        return 0.0
    idx = np.r_[np.arange(3), (3 + 2 * others[:, None] + np.arange(2)).reshape(-1)]
    sub = Belief(belief.pose, L[others], belief.covariance[np.ix_(idx, idx)])
    rival = jcbb(sub, z, R, gate_probability, model=model)
    if int(np.sum(rival.landmark >= 0)) < len(paired):
        return 0.0
    own = joint_log_likelihood(belief, z, R, pairing.landmark, model)
    other = joint_log_likelihood(sub, z, R, rival.landmark, model)
    return float(np.exp(min(other - own, 700.0)))
