"""Data association without ids: individual distances, nearest neighbour, JCBB (hand-made scans, a random one)."""

from __future__ import annotations

import numpy as np
import pytest

from online_slam.frontend.association import (
    Belief,
    associate,
    individual_distances,
    individual_log_likelihoods,
    jcbb,
    joint_log_likelihood,
    nearest_neighbour,
    rival_ratio,
)
from online_slam.geometry.angles import wrap
from online_slam.models.range_bearing import range_bearing, range_bearing_with_jacobians

R1 = np.diag([0.05**2, 0.01**2])


def belief(pose, landmarks, pose_var, landmark_var=1e-4) -> Belief:
    landmarks = np.asarray(landmarks, dtype=float)
    cov = np.zeros((3 + 2 * len(landmarks),) * 2)
    cov[:3, :3] = np.diag(pose_var)
    cov[3:, 3:] = landmark_var * np.eye(2 * len(landmarks))
    return Belief(np.asarray(pose, dtype=float), landmarks, cov)


def test_individual_distance_is_the_innovation_in_its_own_covariance(rng) -> None:
    landmarks = rng.uniform(-10, 10, (4, 2))
    A = rng.normal(size=(11, 11))
    b = Belief(np.array([0.3, -0.2, 0.4]), landmarks, A @ A.T * 0.01 + 1e-3 * np.eye(11))
    z = np.array([[5.0, 0.3], [8.0, -1.0]])
    R = np.stack([R1, 2 * R1])
    d2 = individual_distances(b, z, R)
    for i in range(2):
        for j in range(4):
            z_hat, J_p, J_l = range_bearing_with_jacobians(b.pose, landmarks[j])
            H = np.zeros((2, 11))
            H[:, :3], H[:, 3 + 2 * j : 5 + 2 * j] = J_p, J_l
            nu = z[i] - z_hat
            nu[1] = wrap(nu[1])
            assert d2[i, j] == pytest.approx(nu @ np.linalg.solve(H @ b.covariance @ H.T + R[i], nu), rel=1e-9)


def test_jcbb_is_right_where_nearest_neighbour_is_wrong() -> None:
    """Three landmarks in a row; the pose estimate is 1 m off along the row (and uncertain along it): each
    sighting looks like its neighbour's prediction. NN pairs by distance and is wrong; JCBB finds that one common
    pose error explains all three sightings."""
    landmarks = np.array([[5.0, -1.0], [5.0, 0.0], [5.0, 1.0]])
    true_pose = np.array([0.0, 1.0, 0.0])
    b = belief([0.0, 0.0, 0.0], landmarks, [0.01, 1.0, 1e-4])
    z = range_bearing(true_pose[None, :], landmarks)
    R = np.stack([R1] * 3)
    nn = nearest_neighbour(b, z, R)
    assert nn.landmark[1] == 0 and nn.landmark[2] == 1  # sightings of landmarks 1 and 2 given to 0 and 1
    joint = jcbb(b, z, R)
    assert list(joint.landmark) == [0, 1, 2]
    assert joint.joint_distance < 11.3  # chi-square 99% for 6 dof: 16.8; one common shift explains all


def test_clutter_pairs_with_nothing_and_true_sightings_with_their_landmarks(rng) -> None:
    landmarks = rng.uniform(-15, 15, (25, 2))
    pose = np.array([1.0, -2.0, 0.3])
    b = belief(pose, landmarks, [0.01, 0.01, 1e-4], landmark_var=0.01)
    visible = np.flatnonzero(np.linalg.norm(landmarks - pose[:2], axis=1) < 12)
    z = range_bearing(pose[None, :], landmarks[visible]) + rng.normal(0, [0.05, 0.01], (len(visible), 2))
    clutter = np.array([[7.3, 2.9]])  # a sighting of nothing: no landmark is near where it points
    assert np.min(np.linalg.norm(landmarks - (pose[:2] + 7.3 * np.array([np.cos(3.2), np.sin(3.2)])), axis=1)) > 2
    z = np.vstack([z, clutter])
    R = np.stack([R1] * len(z))
    for method in ("nn", "jcbb"):
        result = associate(method, b, z, R)
        assert list(result.landmark[:-1]) == list(visible), method
        assert result.landmark[-1] == -1, method


def test_no_landmarks_or_no_sightings() -> None:
    empty = Belief(np.zeros(3), np.zeros((0, 2)), 1e-2 * np.eye(3))
    assert list(jcbb(empty, np.array([[3.0, 0.1]]), R1[None]).landmark) == [-1]
    b = belief([0, 0, 0], [[1.0, 2.0]], [0.01, 0.01, 0.01])
    assert len(nearest_neighbour(b, np.zeros((0, 2)), np.zeros((0, 2, 2))).landmark) == 0
    with pytest.raises(ValueError):
        associate("greedy", b, np.zeros((0, 2)), np.zeros((0, 2, 2)))


def _joint_distance(belief: Belief, z: np.ndarray, R: np.ndarray, pairs: list[tuple[int, int]]) -> float:
    """nu_H^T S_H^-1 nu_H of a hypothesis (sighting, landmark) pairs."""
    if not pairs:
        return 0.0
    i = np.array([p[0] for p in pairs])
    j = np.array([p[1] for p in pairs])
    z_hat, J_p, J_l = range_bearing_with_jacobians(belief.pose[None, :], belief.landmarks[j])
    nu = z[i] - z_hat
    nu[:, 1] = wrap(nu[:, 1])
    n = len(belief.covariance)
    H = np.zeros((2 * len(pairs), n))
    for row, (Jp, Jl, lm) in enumerate(zip(J_p, J_l, j)):
        H[2 * row : 2 * row + 2, :3] = Jp
        H[2 * row : 2 * row + 2, 3 + 2 * lm : 5 + 2 * lm] = Jl
    S = H @ belief.covariance @ H.T
    for row, k in enumerate(i):
        S[2 * row : 2 * row + 2, 2 * row : 2 * row + 2] += R[k]
    v = nu.reshape(-1)
    return float(v @ np.linalg.solve(S, v))


@pytest.mark.parametrize("mapped, seen", [(12, 6), (20, 15)])
def test_jcbb_incremental_joint_distance_equals_the_explicit_one(rng, mapped: int, seen: int) -> None:
    """The Schur-complement updates along the search give the same joint distance as one 2m x 2m solve. With 15
    sightings a scan's S_H^-1 updated by blocks (as it once was) lost all precision: -12.8 against 56.7, wrong
    pairings; the Cholesky factor grown by block rows keeps it."""
    for _ in range(5):
        landmarks = rng.uniform(-10, 10, (mapped, 2))
        n = 3 + 2 * len(landmarks)
        A = rng.normal(size=(n, 6)) * 0.05
        cov = A @ A.T + np.diag(np.r_[[0.04, 0.04, 0.002], np.full(n - 3, 0.01)])
        b = Belief(np.array([0.2, -0.1, 0.05]), landmarks, cov)
        picked = rng.choice(len(landmarks), seen, replace=False)
        z = range_bearing(np.zeros(3)[None, :], landmarks[picked]) + rng.normal(0, [0.05, 0.01], (seen, 2))
        R = np.stack([R1] * seen)
        result = jcbb(b, z, R)
        pairs = [(i, int(j)) for i, j in enumerate(result.landmark) if j >= 0]
        assert len(pairs) >= 2 * seen // 3
        assert result.joint_distance == pytest.approx(_joint_distance(b, z, R, pairs), rel=1e-8)


def test_joint_log_likelihood_is_the_stacked_innovations_density(rng) -> None:
    landmarks = rng.uniform(-10, 10, (4, 2))
    A = rng.normal(size=(11, 11))
    b = Belief(np.array([0.3, -0.2, 0.4]), landmarks, A @ A.T * 0.01 + 1e-3 * np.eye(11))
    z = np.array([[5.0, 0.3], [8.0, -1.0], [3.0, 2.0]])
    R = np.stack([R1, 2 * R1, 3 * R1])
    single = individual_log_likelihoods(b, z, R)[1]
    for i in range(3):  # one sighting paired: its own density
        pairing = np.full(3, -1)
        pairing[i] = 2
        assert joint_log_likelihood(b, z, R, pairing) == pytest.approx(single[i, 2], rel=1e-9)
    pairing = np.array([1, -1, 3])
    H, nu = np.zeros((4, 11)), np.zeros(4)
    for a, (i, j) in enumerate(((0, 1), (2, 3))):
        z_hat, J_p, J_l = range_bearing_with_jacobians(b.pose, landmarks[j])
        H[2 * a : 2 * a + 2, :3], H[2 * a : 2 * a + 2, 3 + 2 * j : 5 + 2 * j] = J_p, J_l
        nu[2 * a : 2 * a + 2] = [z[i, 0] - z_hat[0], wrap(z[i, 1] - z_hat[1])]
    S = H @ b.covariance @ H.T
    S[:2, :2] += R[0]
    S[2:, 2:] += R[2]
    expected = -0.5 * (nu @ np.linalg.solve(S, nu) + np.linalg.slogdet(2 * np.pi * S)[1])
    assert joint_log_likelihood(b, z, R, pairing) == pytest.approx(expected, rel=1e-9)
    assert joint_log_likelihood(b, z, R, np.full(3, -1)) == 0.0


def test_a_rival_elsewhere_counts_and_a_neighbour_the_sensor_cannot_tell_apart_does_not() -> None:
    """One sighting 7.5 m ahead; the heading known to 0.24 rad. Landmarks 3 m apart both pass the gate: the rival's
    likelihood ratio is its density over the pairing's. A neighbour 0.05 m from the paired landmark (within the
    sighting's own noise) is no rival; with the heading known to 0.01 rad the far landmark fails the gate."""
    z, R = np.array([[7.5, 0.1]]), R1[None]
    far = [[7.5, 0.0], [7.5 * np.cos(0.4), 7.5 * np.sin(0.4)]]
    b = belief([0.0, 0.0, 0.3], far, [1e-4, 1e-4, 0.24**2])
    pairing = jcbb(b, z, R)
    assert pairing.landmark.tolist() == [1]  # the nearer, in the believed heading
    log_l = individual_log_likelihoods(b, z, R)[1][0]
    ratio = rival_ratio(b, z, R, pairing, distinct=18.42)
    assert ratio == pytest.approx(np.exp(log_l[0] - log_l[1]), rel=1e-9)
    assert 0.1 < ratio < 1.0
    near = belief([0.0, 0.0, 0.3], [far[1], [far[1][0] + 0.05, far[1][1]]], [1e-4, 1e-4, 0.24**2])
    assert rival_ratio(near, z, R, jcbb(near, z, R), distinct=18.42) == 0.0
    sure = belief([0.0, 0.0, 0.3], far, [1e-4, 1e-4, 0.01**2])
    assert rival_ratio(sure, z, R, jcbb(sure, z, R), distinct=18.42) == 0.0
