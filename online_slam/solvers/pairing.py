"""Pairing sightings with landmarks again over a whole run: annealed expectation-maximization, then the majority.

An online estimator pairs each scan once, at the estimate it had then; a wrong pairing pulls the estimate that the
next pairings are made at, and the run settles where its own pairings agree with it (on MRCLAM's clusters of tubes
0.17-0.30 m apart, robot 5's pairing ends at a truncated cost of 425 where a pairing near the barcodes' costs 390).
:func:`repair` treats the landmark of each sighting as hidden: each sighting weighs every nearby landmark by its
likelihood (and an outlier class at the rejection bound), the weighted least-squares problem is solved, and the
weights computed again (EM), the sightings' noise first inflated by a temperature that falls to 1 (deterministic
annealing: Ueda & Nakano 1998), which lets the estimate leave the basin its own pairings dug. Then each sighting
goes to the landmark that takes the majority of its weight, if one does (one landmark per scan), the others staying
weighed; solved again until the pairing holds. Then the map itself is mended
(:mod:`~online_slam.solvers.landmark_moves`): landmarks stacked on one spot are placed apart again, landmarks are born
where sightings that lost their scan's landmark gather, and landmarks near each other that no scans pick together are
merged, each followed by the hard rounds. The result replaces the estimate only if it has the lower objective
(:func:`objective`): annealing may also end in a worse basin. Why: benchmarks/RESULTS.md, "Pairing again at the end"
and "Landmarks born, merged and unstacked".
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from scipy.special import logsumexp, softmax

from online_slam.factors.graph import FactorGraph, evaluate, sighting_chi2
from online_slam.models.observation import landmark_from_sighting
from online_slam.solvers.config import SolverConfig
from online_slam.solvers.landmark_moves import births, distinct, merged_away, reseeded, stacked_groups
from online_slam.solvers.least_squares import solve

Array = NDArray[np.float64]
Index = NDArray[np.int64]

TEMPERATURES = (16.0, 8.0, 4.0, 2.0, 1.0)
"""The sightings' noise is inflated by these factors (in variance), in turn; the last is the model's own."""
EM_ROUNDS = 3
"""Weighted solves at each temperature."""
MAJORITY = 0.5
"""A sighting is paired only with a landmark that takes more than this share of its weight (outlier class
included)."""
NEAREST = 4
"""Landmarks a sighting is weighed against: those nearest the world point it gives."""
WEIGHT_FLOOR = 1e-3
"""Weights below this are left out of the solve."""
HARD_ROUNDS = 10
"""Most majority pairings solved in turn before the pairing holds."""
BIRTH_ROUNDS = 3
"""Rounds of births (:func:`~online_slam.solvers.landmark_moves.births`), each followed by the hard rounds."""


@dataclass(frozen=True)
class Sightings:
    """The sightings to pair (k of them), each once."""

    pose: Index
    """Observing pose of each, shape (k,)."""
    z: Array
    """Measurements, shape (k, 2)."""
    sqrt_info: Array
    """Square-root information, shape (k, 2, 2)."""
    model: NDArray[np.int8]
    """Model tags, shape (k,)."""


@dataclass(frozen=True)
class Pairing:
    """The run solved with its sightings paired again."""

    poses: Array
    """Poses, shape (n, 3)."""
    landmarks: Array
    """The landmarks, shape (M, 2)."""
    index: Index
    """Each sighting's landmark where one takes the majority of its weight (one per scan), else -1, shape (k,)."""
    likeliest: Index
    """Each sighting's likeliest landmark (``index`` where it has one; -1: an outlier), shape (k,)."""
    origin: Index
    """Each landmark's row in the landmarks given (-1: one the pairing added), shape (M',); rows missing from it
    were merged into another."""


def _points(s: Sightings, poses: Array, rows: Index | slice = slice(None)) -> Array:
    """Where sightings ``rows`` put their landmarks, (j, 2)."""
    return landmark_from_sighting(poses[s.pose[rows]], s.z[rows], s.model[rows])


def _candidates(s: Sightings, poses: Array, landmarks: Array) -> tuple[Index, Array]:
    """The nearest landmarks to each sighting's world point (k, c) and their chi-squares (k, c)."""
    c = min(NEAREST, len(landmarks))
    points = _points(s, poses)
    near = cKDTree(landmarks).query(points, k=c)[1].reshape(len(points), c).astype(np.int64)
    k = np.repeat(np.arange(len(points)), c)
    d2 = sighting_chi2(poses[s.pose[k]], landmarks[near.reshape(-1)], s.z[k], s.sqrt_info[k], s.model[k])
    return near, d2.reshape(len(points), c)


def _terms(d2: Array, bound: float) -> Array:
    """Each candidate's log-likelihood and the outlier class's (at ``bound``), normalizers dropped, (k, c + 1)."""
    return -0.5 * np.concatenate([d2, np.full((len(d2), 1), bound)], axis=1)


def _weights(d2: Array, bound: float, temperature: float) -> Array:
    """Each candidate's share of a sighting's weight, the outlier class taking the rest, (k, c)."""
    return softmax(_terms(d2, bound) / temperature, axis=1)[:, :-1]


def objective(base: FactorGraph, s: Sightings, poses: Array, landmarks: Array, bound: float) -> float:
    """What the pairing minimizes: the other factors' half squared residuals, minus each sighting's log-likelihood
    under its nearest landmarks and the outlier class (the mixture, the sightings' own normalizers dropped)."""
    log_likelihood = logsumexp(_terms(_candidates(s, poses, landmarks)[1], bound), axis=1)
    r = evaluate(dataclasses.replace(base, n_landmarks=len(landmarks)), poses, landmarks)
    return 0.5 * float(r @ r) - float(log_likelihood.sum())


def _paired(s: Sightings, poses: Array, landmarks: Array, bound: float) -> tuple[Index, Index, Array, Index]:
    """The majority pairing at an estimate (one landmark per scan), each sighting's likeliest landmark, the weights
    (k, c) and their candidates (k, c)."""
    everyone = np.arange(len(s.z))
    near, d2 = _candidates(s, poses, landmarks)
    w = _weights(d2, bound, 1.0)
    best = np.argmax(w, axis=1)
    pick = near[everyone, best]
    pick[w[everyone, best] <= MAJORITY] = -1
    order = np.lexsort((-w[everyone, best], pick, s.pose))  # one landmark per scan: the surest sighting keeps it
    first = np.ones(len(order), dtype=bool)
    first[1:] = ~((np.diff(s.pose[order]) == 0) & (np.diff(pick[order]) == 0) & (pick[order][1:] >= 0))
    pick[order[~first]] = -1
    likeliest = np.where(w[everyone, best] > WEIGHT_FLOOR, near[everyone, best], -1)
    return pick, np.where(pick >= 0, pick, likeliest), w, near


def _solve(
    base: FactorGraph, s: Sightings, rows: Index, landmark: Index, scale: Array, poses: Array, landmarks: Array,
    solver: SolverConfig,
) -> tuple[Array, Array]:  # fmt: skip
    """Least squares with sighting ``rows`` on ``landmark`` (information times ``scale``); a landmark no row sees
    stays where it is."""
    kept, landmark = np.unique(landmark, return_inverse=True)
    graph = dataclasses.replace(
        base,
        n_landmarks=len(kept),
        obs_pose=s.pose[rows],
        obs_landmark=landmark.astype(np.int64),
        obs_z=s.z[rows],
        obs_sqrt_info=s.sqrt_info[rows] * np.sqrt(scale)[:, None, None],
        obs_model=s.model[rows],
    )
    result = solve(graph, poses, landmarks[kept], solver)
    landmarks = landmarks.copy()
    landmarks[kept] = result.landmarks
    return result.poses, landmarks


def _scale(s: Sightings, poses: Array, landmarks: Array, pick: Index) -> float:
    """How far the paired sightings' points (``pick``: :func:`_paired`'s) lie from their landmarks, as a standard
    deviation per axis, m: their median distance over ``sqrt(2 ln 2)`` (a Rayleigh's median). Their covariances
    would not do: a stream may widen them for what they share in time, not for how far apart one scan's sightings
    lie."""
    rows = np.flatnonzero(pick >= 0)
    if not len(rows):
        return 0.0
    miss = np.hypot(*(_points(s, poses, rows) - landmarks[pick[rows]]).T)
    return float(np.median(miss)) / np.sqrt(2.0 * np.log(2.0))


def _unstacked(
    s: Sightings, poses: Array, landmarks: Array, w: Array, near: Index, scale: float
) -> tuple[Array, NDArray[np.bool_]] | None:
    """The landmarks with each stacked group placed again by k-means of its sightings' points, as many as one
    scan's sightings there say (:func:`~online_slam.solvers.landmark_moves.distinct`), and which to keep (the
    group's others are merged away); None if none is stacked. ``w``, ``near``: :func:`_paired`'s."""
    groups = stacked_groups(landmarks, scale)
    if not groups:
        return None
    best = near[np.arange(len(near)), np.argmax(w, axis=1)]
    landmarks, keep = landmarks.copy(), np.ones(len(landmarks), dtype=bool)
    for group in groups:
        rows = np.flatnonzero(np.isin(best, group))
        k = distinct(s.pose[rows], len(group)) if len(rows) else len(group)
        if len(rows) >= k:
            landmarks[group[:k]] = reseeded(_points(s, poses, rows), k)
            keep[group[k:]] = False
    return landmarks, keep


def _hard(
    base: FactorGraph, s: Sightings, poses: Array, landmarks: Array, bound: float, solver: SolverConfig
) -> tuple[Array, Array]:
    """The majority pairing solved in turn until it holds (the others weighed)."""
    index = np.full(len(s.z), -2, dtype=np.int64)
    for _ in range(HARD_ROUNDS):
        pick, _, w, near = _paired(s, poses, landmarks, bound)
        if np.array_equal(pick, index):
            break
        index = pick
        sure = np.flatnonzero(index >= 0)
        k, c = np.nonzero((w > WEIGHT_FLOOR) & (index < 0)[:, None])  # the others as weighed
        rows, landmark = np.r_[sure, k], np.r_[index[sure], near[k, c]]
        poses, landmarks = _solve(base, s, rows, landmark, np.r_[np.ones(len(sure)), w[k, c]], poses, landmarks, solver)
    return poses, landmarks


def repair(
    base: FactorGraph, s: Sightings, poses: Array, landmarks: Array, bound: float, solver: SolverConfig
) -> Pairing:
    """Pair every sighting again, from an estimate (see the module's docstring).

    Args:
        base: The run's other factors (odometry, priors, robot sightings, fixes): its observations are replaced.
        s: Every sighting of the run, once each.
        poses: The estimate's poses (n, 3); ``landmarks`` its landmarks (M, 2).
        bound: A sighting's chi-square at which the outlier class is as likely as a landmark (the rejection bound).
        solver: The least-squares settings.

    Returns:
        The poses and landmarks solved with the majority pairing (the others weighed), or the estimate given where
        that has the lower :func:`objective`; the pairing at them.
    """
    none = np.full(len(s.z), -1, dtype=np.int64)
    if len(s.z) == 0 or len(landmarks) == 0:
        return Pairing(poses, landmarks, none, none, np.arange(len(landmarks)))
    start = objective(base, s, poses, landmarks, bound)
    before = poses, landmarks
    for temperature in TEMPERATURES:
        for _ in range(EM_ROUNDS):
            near, d2 = _candidates(s, poses, landmarks)
            w = _weights(d2, bound, temperature)
            k, c = np.nonzero(w > WEIGHT_FLOOR)
            poses, landmarks = _solve(base, s, k, near[k, c], w[k, c] / temperature, poses, landmarks, solver)
    poses, landmarks = _hard(base, s, poses, landmarks, bound, solver)
    origin = np.arange(len(landmarks))
    pick, _, w, near = _paired(s, poses, landmarks, bound)
    scale = _scale(s, poses, landmarks, pick)
    if scale > 0:  # 0 (nothing paired): no moves
        if (unstacked := _unstacked(s, poses, landmarks, w, near, scale)) is not None:
            placed, keep = unstacked
            poses, landmarks = _hard(base, s, poses, placed[keep], bound, solver)
            origin = origin[keep]
            pick, _, w, _ = _paired(s, poses, landmarks, bound)
        for _ in range(BIRTH_ROUNDS):
            losers = np.flatnonzero((w.max(axis=1) > MAJORITY) & (pick < 0))  # lost to a surer sighting of the scan
            born = births(_points(s, poses, losers), s.pose[losers], landmarks, scale)
            if not len(born):
                break
            poses, landmarks = _hard(base, s, poses, np.vstack([landmarks, born]), bound, solver)
            origin = np.r_[origin, np.full(len(born), -1)]
            pick, _, w, _ = _paired(s, poses, landmarks, bound)
        if len(drop := merged_away(landmarks, pick, s.pose, scale)):
            keep = np.ones(len(landmarks), dtype=bool)
            keep[drop] = False
            poses, landmarks = _hard(base, s, poses, landmarks[keep], bound, solver)
            origin = origin[keep]
    if objective(base, s, poses, landmarks, bound) > start:  # annealing may end in a worse basin: keep the start
        (poses, landmarks), origin = before, np.arange(len(before[1]))
    pick, likeliest, _, _ = _paired(s, poses, landmarks, bound)
    return Pairing(poses, landmarks, pick, likeliest, origin)
