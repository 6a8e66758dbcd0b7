"""Measurement and motion models: value plus analytic Jacobians, pure and vectorised."""

from online_slam.models.motion import compose_increments, odometry_residual_with_jacobians
from online_slam.models.range_bearing import (
    landmark_from_observation,
    landmark_from_observation_with_jacobians,
    range_bearing,
    range_bearing_with_jacobians,
)

__all__ = [
    "compose_increments",
    "landmark_from_observation",
    "landmark_from_observation_with_jacobians",
    "odometry_residual_with_jacobians",
    "range_bearing",
    "range_bearing_with_jacobians",
]
