"""The EKF's tests on gated sightings: does one robot correction explain them (the filter drifted), and do a
landmark's recent gated sightings agree with each other (the landmark is stale)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from online_slam.factors.robust import outlier_threshold
from online_slam.geometry.angles import wrap
from online_slam.models.observation import predict_with_jacobians, wrap_bearings

Array = NDArray[np.float64]


def one_robot_correction_explains(
    pose: Array, landmarks: Array, P_ll: Array, z: Array, R: Array, model: NDArray[np.int8]
) -> bool:
    """Can one robot pose, the landmarks held where they are, explain these sightings (chi-square)?

    Gauss-Newton on the robot pose alone, each sighting weighted by its noise plus its landmark's uncertainty;
    the test is on the remaining residual (2k - 3 dof) at a 1e-3 false-alarm rate.

    Args:
        pose: The robot's estimate, shape (3,). landmarks: The sighted landmarks' estimates, shape (k, 2).
        P_ll: Their 2x2 marginal covariances, shape (k, 2, 2).
        z: The sightings, shape (k, 2). R: Their covariances, shape (k, 2, 2).
        model: Each sighting's model tag (:mod:`online_slam.models.observation`), shape (k,).
    """
    pose = pose.copy()
    chi2_value = np.inf
    for _ in range(6):
        z_hat, J_p, J_l = predict_with_jacobians(pose, landmarks, model)
        y = wrap_bearings(z - z_hat, model)
        C_inv = np.linalg.inv(R + J_l @ P_ll @ J_l.transpose(0, 2, 1))
        chi2_value = float(np.einsum("ki,kij,kj->", y, C_inv, y))
        A = np.einsum("kai,kab,kbj->ij", J_p, C_inv, J_p)
        b = np.einsum("kai,kab,kb->i", J_p, C_inv, y)
        try:
            step = np.linalg.solve(A, b)
        except np.linalg.LinAlgError:
            return False
        pose = pose + step
        pose[2] = wrap(pose[2])
    dof = 2 * len(landmarks) - 3
    return chi2_value <= outlier_threshold(1e-3, dof) if dof > 0 else True


def recent_agree(recent: dict[int, list[tuple[Array, Array]]], indices: NDArray[np.int64]) -> NDArray[np.bool_]:
    """For each sighting: do two thirds of its landmark's recent gated sightings agree with it (chi-square)?

    Args:
        recent: Recent gated sightings per landmark index, as (position (2,), its covariance (2, 2)); the
            newest of each is the sighting tested.
        indices: Landmark index of each sighting, shape (k,).
    """
    out = np.zeros(len(indices), dtype=bool)
    bound = outlier_threshold(1e-3)
    for i, j in enumerate(indices.tolist()):
        seen = recent.get(j, [])
        if len(seen) < 2:
            continue
        points = np.array([r[0] for r in seen])
        covs = np.array([r[1] for r in seen])
        d = points - points[-1]
        total = covs + covs[-1]
        chi2_values = np.einsum("ki,ki->k", d[:-1], np.linalg.solve(total[:-1], d[:-1, :, None])[..., 0])
        agree = int(np.sum(chi2_values <= bound))
        out[i] = agree >= max(1.0, 2.0 * len(chi2_values) / 3.0)
    return out
