"""Factors of the 2D landmark SLAM problem: whitened residuals and sparse Jacobians, no state."""

from online_slam.factors.graph import FactorGraph, SparseLayout, cost, evaluate, layout, linearize, sqrt_information
from online_slam.factors.robust import RobustLoss

__all__ = ["FactorGraph", "RobustLoss", "SparseLayout", "cost", "evaluate", "layout", "linearize", "sqrt_information"]
