"""Factors of the 2D landmark SLAM problem: whitened residuals and sparse Jacobians, no state."""

from online_slam.factors.graph import FactorGraph, SparseLayout, evaluate, layout, linearize, sqrt_information

__all__ = ["FactorGraph", "SparseLayout", "evaluate", "layout", "linearize", "sqrt_information"]
