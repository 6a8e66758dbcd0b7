"""Evaluation: pure metrics against truth, and the result records that reports read."""

from online_slam.evaluation.metrics import (
    align_se2,
    anchor_transform,
    apply_transform,
    endpoint_gap,
    landmark_rmse,
    pose_nees,
    position_rmse,
    transform_pose_covariance,
)

__all__ = [
    "align_se2",
    "anchor_transform",
    "apply_transform",
    "endpoint_gap",
    "landmark_rmse",
    "pose_nees",
    "position_rmse",
    "transform_pose_covariance",
]
