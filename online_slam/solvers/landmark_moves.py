"""Moves that change a map's landmarks while its sightings are paired again: unstack, birth, merge.

Annealed EM (:mod:`online_slam.solvers.pairing`) keeps the number of landmarks it starts from, and has fixed points
that its sightings alone do not leave: landmarks stacked on one spot share every sighting's weight evenly (none takes
a majority, so the hard rounds never part them); a landmark the online pairing never mapped lends its sightings to
its neighbours; a landmark mapped twice splits its sightings. What tells these apart is the scan: one scan sees a
landmark once, so two landmarks picked by sightings of one scan are two, and a sighting that lost its landmark to a
surer one of its scan saw another. Distances are in units of how far the paired sightings' points lie from their
landmarks (``scale``, a standard deviation per axis), so that no world's scale is built in. Pure functions of
arrays; why: benchmarks/RESULTS.md, "Landmarks born, merged and unstacked".
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

Array = NDArray[np.float64]
Index = NDArray[np.int64]

STACKED = 0.5
"""Landmarks nearer each other than this (in spreads) are stacked: their sightings cannot tell them apart."""
BIRTH_RADIUS = 1.0
"""Sightings that lost their landmark gather within this (in spreads) to give a landmark, which must lie at least
this far from every landmark."""
BIRTH_SCANS = 3
"""A landmark is born from sightings of at least this many scans; two landmarks picked together in fewer scans
than this, within :data:`MERGE_RADIUS`, are one."""
MERGE_RADIUS = 2.0
"""Landmarks this near each other (in spreads) are merged unless scans pick both."""
LLOYD_ROUNDS = 20
"""k-means rounds when stacked landmarks are placed again."""


def stacked_groups(landmarks: Array, scale: float) -> list[Index]:
    """Groups (each of 2 or more landmark indices) of landmarks chained nearer than :data:`STACKED` spreads."""
    pairs = np.array(sorted(cKDTree(landmarks).query_pairs(STACKED * scale)), dtype=np.int64).reshape(-1, 2)
    if not len(pairs):
        return []
    n = len(landmarks)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    counts = np.bincount(label)
    return [np.flatnonzero(label == g) for g in np.flatnonzero(counts > 1)]


def distinct(scans: Index, most: int) -> int:
    """How many landmarks sightings at one spot are of (1..``most``), from the scan of each (``scans`` (m,)): the
    largest ``k`` that at least :data:`BIRTH_SCANS` scans have ``k`` sightings there or more (one scan sees a
    landmark once)."""
    per_scan = np.unique(scans, return_counts=True)[1]
    k = 1
    while k < most and np.sum(per_scan >= k + 1) >= BIRTH_SCANS:
        k += 1
    return k


def reseeded(points: Array, k: int) -> Array:
    """``k`` places (k, 2) for the points (m, 2) of stacked landmarks' sightings: k-means, started from the point
    farthest from their median and then each point farthest from those chosen (deterministic)."""
    centre = np.median(points, axis=0)
    chosen = [int(np.argmax(np.hypot(*(points - centre).T)))]
    nearest = np.hypot(*(points - points[chosen[0]]).T)
    for _ in range(1, k):
        chosen.append(int(np.argmax(nearest)))
        nearest = np.minimum(nearest, np.hypot(*(points - points[chosen[-1]]).T))
    centres = points[chosen].copy()
    for _ in range(LLOYD_ROUNDS):
        label = np.argmin(((points[:, None, :] - centres[None]) ** 2).sum(axis=2), axis=1)
        moved = np.array([points[label == j].mean(axis=0) if (label == j).any() else centres[j] for j in range(k)])
        if np.allclose(moved, centres):
            break
        centres = moved
    return centres


def births(points: Array, scans: Index, landmarks: Array, scale: float) -> Array:
    """Where landmarks the map lacks stand (b, 2), from the points (j, 2) of sightings that lost their landmark to
    a surer sighting of their scan (``scans`` (j,)): the points at least :data:`BIRTH_RADIUS` spreads from every
    landmark, grouped greedily (the group within that radius of one point spanning the most scans first, then the
    rest), each group spanning :data:`BIRTH_SCANS` scans or more giving its median."""
    radius = BIRTH_RADIUS * scale
    if len(landmarks) and len(points):
        apart = cKDTree(landmarks).query(points)[0] > radius  # nearer a landmark: that landmark's own spread
        points, scans = points[apart], scans[apart]
    born: list[Array] = []
    while len(np.unique(scans)) >= BIRTH_SCANS:
        groups = cKDTree(points).query_ball_point(points, radius)
        counts = np.array([len(np.unique(scans[g])) for g in groups])
        best = int(np.argmax(counts))
        if counts[best] < BIRTH_SCANS:
            break
        place = np.median(points[groups[best]], axis=0)
        born.append(place)
        rest = np.hypot(*(points - place).T) > radius
        points, scans = points[rest], scans[rest]
    return np.array(born).reshape(-1, 2)


def merged_away(landmarks: Array, pick: Index, scan: Index, scale: float) -> Index:
    """Landmarks to drop (sorted indices): of each pair within :data:`MERGE_RADIUS` spreads that fewer than
    :data:`BIRTH_SCANS` scans pick both of (``pick`` (k,): each sighting's landmark or -1; ``scan`` (k,): its
    scan), the one fewer sightings pick, nearest pairs first, each landmark dropped once."""
    pairs = np.array(sorted(cKDTree(landmarks).query_pairs(MERGE_RADIUS * scale)), dtype=np.int64).reshape(-1, 2)
    if not len(pairs):
        return np.zeros(0, dtype=np.int64)
    used = pick >= 0
    picked = coo_matrix((np.ones(int(used.sum())), (scan[used], pick[used])), shape=(scan.max() + 1, len(landmarks)))
    picked = (picked.tocsr() > 0).astype(np.int64)  # scan x landmark: picked there
    together = np.asarray((picked.T @ picked)[pairs[:, 0], pairs[:, 1]]).ravel()  # scans picking both of a pair
    counts = np.bincount(pick[used], minlength=len(landmarks))
    order = np.argsort(np.hypot(*(landmarks[pairs[:, 0]] - landmarks[pairs[:, 1]]).T), kind="stable")
    dropped: set[int] = set()
    for (i, j), both in zip(pairs[order], together[order]):
        if i in dropped or j in dropped or both >= BIRTH_SCANS:
            continue
        dropped.add(int(j) if counts[j] < counts[i] or (counts[j] == counts[i] and j > i) else int(i))
    return np.array(sorted(dropped), dtype=np.int64)
