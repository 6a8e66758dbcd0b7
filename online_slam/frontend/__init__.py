"""Front-end: turns events into steps (one pose each, with its odometry and observations)."""

from online_slam.frontend.steps import FrontEnd, FrontEndConfig, GroundTruth, KeyframeConfig, Step

__all__ = ["FrontEnd", "FrontEndConfig", "GroundTruth", "KeyframeConfig", "Step"]
