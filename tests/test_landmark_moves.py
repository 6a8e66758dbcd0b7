"""Landmarks born, merged and unstacked while a run is paired again (``online_slam.solvers.landmark_moves``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from test_pairing import BOUND, _odometry, _solved, _world

from online_slam.solvers.landmark_moves import births, distinct, merged_away, reseeded, stacked_groups
from online_slam.solvers.pairing import repair


def _nearest(estimated: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each true landmark's nearest estimated landmark and its distance."""
    d = np.linalg.norm(truth[:, None] - estimated[None], axis=2)
    return np.argmin(d, axis=1), d.min(axis=1)


def test_stacked_landmarks_are_grouped_and_placed_apart_again() -> None:
    landmarks = np.array([[0.0, 0.0], [0.001, 0.0], [0.0, 0.002], [1.0, 0.0], [5.0, 5.0], [5.03, 5.0]])
    groups = stacked_groups(landmarks, scale=0.1)  # stacked: nearer than half a spread, 0.05
    assert sorted(map(list, groups)) == [[0, 1, 2], [4, 5]]
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [0.2, 0.0], [0.4, 0.0]])
    points = np.concatenate([c + rng.normal(0.0, 0.03, (40, 2)) for c in centres])
    placed = reseeded(points, 3)
    assert np.sort(_nearest(placed, centres)[0]).tolist() == [0, 1, 2]
    assert _nearest(placed, centres)[1].max() < 0.03


def test_a_stack_is_as_many_landmarks_as_scans_see_there_at_once() -> None:
    one_each = np.arange(20)  # a landmark mapped three times: every scan sees it once
    assert distinct(one_each, 3) == 1
    pairs = np.r_[np.arange(20), np.arange(0, 20, 2)]  # ten scans see two there
    assert distinct(pairs, 3) == 2 and distinct(pairs, 1) == 1
    assert distinct(np.r_[np.arange(20), [4, 4, 9]], 3) == 1  # two scans with two: not enough


def test_landmarks_are_born_only_from_sightings_of_several_scans_away_from_the_map() -> None:
    landmarks = np.array([[0.0, 0.0]])
    points = np.array([[0.5, 0.0], [0.52, 0.01], [0.49, -0.01], [0.05, 0.0], [0.04, 0.01], [0.06, 0.0]])
    scans = np.array([1, 2, 3, 4, 5, 6])
    born = births(points, scans, landmarks, scale=0.1)
    assert len(born) == 1 and np.linalg.norm(born[0] - [0.5, 0.0]) < 0.02  # the others lie on the landmark
    assert not len(births(points[:3], np.array([1, 1, 2]), landmarks, scale=0.1))  # two scans only
    two = births(np.r_[points[:3], points[:3] + [1.0, 0.0]], np.arange(6), landmarks, scale=0.1)
    assert np.allclose(np.sort(two[:, 0]), [0.5, 1.5], atol=0.02)


def test_landmarks_scans_pick_together_stay_and_a_duplicate_goes() -> None:
    landmarks = np.array([[0.0, 0.0], [0.18, 0.0], [0.03, 0.0]])  # two tubes and a copy of the first
    scan = np.repeat(np.arange(10), 2)
    pick = np.tile([0, 1], 10)  # each scan sees both tubes
    pick[::4] = 2  # some scans give the first tube's sighting to its copy instead
    assert merged_away(landmarks, pick, scan, scale=0.1).tolist() == [2]  # fewer sightings than landmark 0's
    assert merged_away(landmarks[:2], np.tile([0, 1], 10), scan, scale=0.1).tolist() == []


def test_pairing_again_adds_the_landmark_the_map_lacks() -> None:
    """Each pair's first landmark missing from the map, its sightings given to its neighbour: landmarks are born
    where the sightings that lost their scan's landmark gather, and the run pairs as with the true map."""
    truth, landmarks, graph, s, true_label = _world(0)
    right = _solved(graph, s, true_label, _odometry(graph), landmarks + 0.1)
    lacking = true_label.copy()
    lacking[true_label < 10] += 10  # 0..9 missing: their sightings on 10..19
    start = _solved(graph, s, lacking, _odometry(graph), landmarks + 0.1)
    widened = replace(s, sqrt_info=s.sqrt_info / 3.0)  # declared looser (as MRCLAM's widened sightings): the
    paired = repair(graph, widened, start.poses, start.landmarks[10:], BOUND, None)  # neighbour takes them
    assert len(paired.landmarks) == 20 and (paired.origin < 0).sum() >= 10
    assert np.sort(_nearest(paired.landmarks, right.landmarks)[0]).tolist() == list(range(20))
    assert _nearest(paired.landmarks, right.landmarks)[1].max() < 0.1  # the true pairing's map (tubes 0.3 m apart)
    which = np.argmin(np.linalg.norm(paired.landmarks[:, None] - right.landmarks[None], axis=2), axis=1)
    paired_to = np.where(paired.likeliest >= 0, which[paired.likeliest], -1)
    assert np.mean(paired_to == true_label) > 0.95  # each sighting on its own landmark


def test_pairing_again_parts_stacked_landmarks_and_merges_a_copy() -> None:
    """Each pair's two landmarks stacked at its middle (every sighting's weight split in two, a fixed point of
    EM), and a copy of one landmark: the pair is parted, the copy merged away."""
    truth, landmarks, graph, s, true_label = _world(1)
    right = _solved(graph, s, true_label, _odometry(graph), landmarks + 0.1)
    stacked = right.landmarks.copy()
    middle = 0.5 * (stacked[:10] + stacked[10:])
    stacked[:10], stacked[10:] = middle + [0.001, 0.0], middle - [0.001, 0.0]
    start = np.vstack([stacked, right.landmarks[3] + [0.0, 0.02]])
    paired = repair(graph, s, right.poses, start, BOUND, None)
    assert len(paired.landmarks) == 20 and len({3, 20} & set(paired.origin.tolist())) == 1  # one of the two
    assert np.sort(_nearest(paired.landmarks, right.landmarks)[0]).tolist() == list(range(20))
    assert _nearest(paired.landmarks, right.landmarks)[1].max() < 0.1  # the true pairing's map (tubes 0.3 m apart)
