"""Metrics: RMSE, end gap, anchoring and SE(2) alignment; evaluation against truth."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from online_slam.estimators import Estimate
from online_slam.evaluation import align_se2, anchor_transform, apply_transform, endpoint_gap, position_rmse
from online_slam.evaluation.scoring import evaluate
from online_slam.frontend import GroundTruth


def test_rmse_and_gap() -> None:
    est = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    truth = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    assert position_rmse(est, truth) == 1.0
    assert endpoint_gap(est) == np.sqrt(2)
    assert np.isnan(position_rmse(np.zeros((0, 3)), np.zeros((0, 3))))


@settings(max_examples=50)
@given(st.floats(-10, 10), st.floats(-10, 10), st.floats(-3, 3), st.integers(0, 1000))
def test_alignment_recovers_rigid_motion(x: float, y: float, th: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    truth = rng.normal(size=(20, 3)) * [5, 5, 1]
    T = np.array([x, y, th])
    moved = apply_transform(T, truth)  # truth seen in another frame
    back = align_se2(moved, truth)
    assert position_rmse(apply_transform(back, moved), truth) < 1e-9
    anchor = anchor_transform(moved[0], truth[0])
    assert position_rmse(apply_transform(anchor, moved), truth) < 1e-9


def test_evaluate_anchors_at_first_pose_with_truth_and_moves_landmarks_too() -> None:
    truth_poses = np.array([[1.0, 2.0, 0.5], [2.0, 2.0, 0.5], [3.0, 3.0, 1.0]])
    truth_landmarks = np.array([[5.0, 5.0], [0.0, 7.0]])
    T = np.array([-3.0, 4.0, 1.2])
    estimate = Estimate(
        "x", apply_transform(T, truth_poses), ("a", "b", "c"), np.r_[apply_transform(T, truth_landmarks), [[9, 9]]]
    )
    truth = GroundTruth({1: truth_poses[1], 2: truth_poses[2]}, {"a": truth_landmarks[0], "b": truth_landmarks[1]})
    for alignment in ("anchor", "se2"):
        errors = evaluate(estimate, truth, alignment)
        assert errors.rmse_m < 1e-12 and errors.landmark_rmse_m < 1e-12
    assert evaluate(estimate, GroundTruth(), "anchor").rmse_m is None
