"""Factors of the 2D landmark SLAM problem: whitened residuals and sparse Jacobians, no state."""

from __future__ import annotations

from typing import TYPE_CHECKING

from online_slam.lazy import lazy_exports

if TYPE_CHECKING:
    from online_slam.factors.graph import FactorGraph, SparseLayout, cost, evaluate, layout, linearize, sqrt_information
    from online_slam.factors.robust import RobustLoss

_HOMES = {
    "FactorGraph": "online_slam.factors.graph",
    "SparseLayout": "online_slam.factors.graph",
    "cost": "online_slam.factors.graph",
    "evaluate": "online_slam.factors.graph",
    "layout": "online_slam.factors.graph",
    "linearize": "online_slam.factors.graph",
    "sqrt_information": "online_slam.factors.graph",
    "RobustLoss": "online_slam.factors.robust",
}
"""Each public name's module (imported on first use)."""

__all__ = ["FactorGraph", "RobustLoss", "SparseLayout", "cost", "evaluate", "layout", "linearize", "sqrt_information"]
__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
