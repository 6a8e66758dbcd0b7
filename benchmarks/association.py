"""Time per scan of the association methods (nearest neighbour, JCBB) against the size of the scan and the map.

Each case draws a map of M landmarks uniformly in a square around the robot, a belief with the EKF-like
uncertainty of a robot that has driven a while (pose sigma 0.3 m / 0.05 rad, landmark sigma 0.2 m, correlated
through a random factor), and a scan of the k nearest landmarks seen with range/bearing noise. Reported: the
median wall time per scan over several scans, and the share of sightings paired with their true landmark.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from online_slam.frontend.association import Belief, associate
from online_slam.models.range_bearing import range_bearing

Index = NDArray[np.int64]

NOISE = np.array([0.05, np.deg2rad(0.5)])
"""Range and bearing sigmas of the simulated sightings."""


@dataclass(frozen=True)
class AssociationTiming:
    """One case: method, scan size, map size."""

    method: str
    """``nn`` or ``jcbb``."""
    sightings: int
    """Sightings per scan (k)."""
    landmarks: int
    """Landmarks in the belief (M)."""
    median_ms: float
    """Median time per scan."""
    accuracy: float
    """Share of sightings paired with their true landmark."""


def _case(
    rng: np.random.Generator, landmarks: int, sightings: int
) -> tuple[Belief, np.ndarray, np.ndarray, np.ndarray]:
    side = 4.0 * np.sqrt(landmarks)  # ~16 m^2 per landmark
    truth = rng.uniform(-side / 2, side / 2, (landmarks, 2))
    pose = np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)])
    n = 3 + 2 * landmarks
    A = rng.normal(size=(n, 6)) * 0.05
    cov = A @ A.T
    cov[np.diag_indices(3)] += np.array([0.3, 0.3, 0.05]) ** 2
    cov[np.arange(3, n), np.arange(3, n)] += 0.2**2
    estimate = rng.multivariate_normal(np.r_[pose, truth.reshape(-1)], cov)
    belief = Belief(estimate[:3], estimate[3:].reshape(-1, 2), cov)
    seen = np.argsort(np.linalg.norm(truth, axis=1))[:sightings]
    z = range_bearing(pose[None, :], truth[seen]) + rng.normal(0, NOISE, (sightings, 2))
    R = np.broadcast_to(np.diag(NOISE**2), (sightings, 2, 2)).copy()
    return belief, z, R, seen


def time_association(
    sightings: tuple[int, ...] = (5, 10, 15), landmarks: tuple[int, ...] = (50, 200), scans: int = 20, seed: int = 3
) -> list[AssociationTiming]:
    """Time both methods on the same random scans for every (k, M)."""
    rows = []
    for m in landmarks:
        for k in sightings:
            rng = np.random.default_rng(seed)
            cases = [_case(rng, m, k) for _ in range(scans)]
            for method in ("nn", "jcbb"):
                times, right = [], 0
                for belief, z, R, seen in cases:
                    started = time.perf_counter()
                    result = associate(method, belief, z, R)
                    times.append(time.perf_counter() - started)
                    right += int(np.sum(result.landmark == seen))
                rows.append(AssociationTiming(method, k, m, 1e3 * float(np.median(times)), right / (k * scans)))
    return rows
