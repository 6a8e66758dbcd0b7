"""Measurement and motion models: value plus analytic Jacobians, pure and vectorised."""

from online_slam.models.motion import compose_increments, odometry_residual_with_jacobians
from online_slam.models.observation import (
    MODEL_NAMES,
    POSITION,
    RANGE_BEARING,
    landmark_from_sighting,
    landmark_from_sighting_with_jacobians,
    predict,
    predict_with_jacobians,
    wrap_bearings,
)
from online_slam.models.position import (
    landmark_from_position,
    landmark_from_position_with_jacobians,
    position,
    position_with_jacobians,
    range_bearing_from_position,
)
from online_slam.models.range_bearing import (
    landmark_from_observation,
    landmark_from_observation_with_jacobians,
    range_bearing,
    range_bearing_with_jacobians,
)

__all__ = [
    "MODEL_NAMES",
    "POSITION",
    "RANGE_BEARING",
    "compose_increments",
    "landmark_from_observation",
    "landmark_from_observation_with_jacobians",
    "landmark_from_position",
    "landmark_from_position_with_jacobians",
    "landmark_from_sighting",
    "landmark_from_sighting_with_jacobians",
    "odometry_residual_with_jacobians",
    "position",
    "position_with_jacobians",
    "predict",
    "predict_with_jacobians",
    "range_bearing",
    "range_bearing_from_position",
    "range_bearing_with_jacobians",
    "wrap_bearings",
]
