"""Consensus moves: a landmark goes where its window sightings agree, never where they only roughly cluster."""

from __future__ import annotations

import numpy as np

from online_slam.estimators.smoother.window import consensus
from online_slam.factors.graph import FactorGraph, sqrt_information
from online_slam.factors.robust import outlier_threshold
from online_slam.models.observation import POSITION

BOUND = outlier_threshold(1e-3)
SIGMA = 0.1


def _graph(points: np.ndarray) -> tuple[FactorGraph, np.ndarray]:
    """One pose per sighting, at the origin facing +x, each seeing landmark 0 at ``points`` (position model)."""
    k = len(points)
    none, idx = np.zeros(0, dtype=np.int64), np.arange(k, dtype=np.int64)
    graph = FactorGraph(
        n_poses=k,
        n_landmarks=1,
        fixed_poses=none,
        prior_pose=none,
        prior_mean=np.zeros((0, 3)),
        prior_sqrt_info=np.zeros((0, 3, 3)),
        odo_from=none,
        odo_to=none,
        odo_delta=np.zeros((0, 3)),
        odo_sqrt_info=np.zeros((0, 3, 3)),
        obs_pose=idx,
        obs_landmark=np.zeros(k, dtype=np.int64),
        obs_z=np.asarray(points, dtype=float),
        obs_sqrt_info=sqrt_information(np.broadcast_to(SIGMA**2 * np.eye(2), (k, 2, 2)).copy()),
        obs_model=np.full(k, POSITION, dtype=np.int8),
    )
    return graph, np.zeros((k, 3))


def test_sightings_that_agree_move_a_held_landmark_and_release_it() -> None:
    rng = np.random.default_rng(0)
    points = np.array([4.0, 1.0]) + SIGMA * rng.standard_normal((3, 2))
    graph, poses = _graph(points)
    moves, stale = consensus(graph, np.array([0]), poses, np.array([[0.0, 5.0]]), np.array([0]), BOUND)
    assert stale == [0] and len(moves) == 1
    np.testing.assert_allclose(moves[0][1], [4.0, 1.0], atol=3 * SIGMA)


def test_a_loose_cluster_of_wrong_sightings_does_not_move_a_landmark() -> None:
    # Found on issue 31's waypoint world: three wrong-id sightings of a held landmark, two of them about a metre
    # apart (different true landmarks) and one further off, moved it 12 m by the old rule (their median is within
    # three median spreads of two of them); only one of them agrees with that median within the rejection bound.
    points = np.array([[23.8, 10.6], [24.67, 9.89], [31.36, 10.2]])
    graph, poses = _graph(points)
    for held in (np.array([0]), np.zeros(0, dtype=np.int64)):
        moves, stale = consensus(graph, np.array([0]), poses, np.array([[19.16, 21.65]]), held, BOUND)
        assert moves == [] and stale == []
