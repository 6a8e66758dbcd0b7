"""Pure SE(2) geometry: angle wrapping and pose composition, each with analytic Jacobians."""

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import (
    between,
    between_with_jacobians,
    compose,
    compose_with_jacobians,
    inverse,
    rotation,
)

__all__ = [
    "between",
    "between_with_jacobians",
    "compose",
    "compose_with_jacobians",
    "inverse",
    "rotation",
    "wrap",
]
