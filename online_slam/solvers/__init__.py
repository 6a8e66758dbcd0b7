"""Sparse nonlinear least-squares solvers over a :class:`~online_slam.factors.FactorGraph`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from online_slam.lazy import lazy_exports

if TYPE_CHECKING:
    from online_slam.solvers.least_squares import QuadraticPrior, SolverConfig, SolveResult, flatten, retract, solve

_HOMES = {
    "QuadraticPrior": "online_slam.solvers.least_squares",
    "SolverConfig": "online_slam.solvers.least_squares",
    "SolveResult": "online_slam.solvers.least_squares",
    "flatten": "online_slam.solvers.least_squares",
    "retract": "online_slam.solvers.least_squares",
    "solve": "online_slam.solvers.least_squares",
}
"""Each public name's module (imported on first use)."""

__all__ = ["QuadraticPrior", "SolveResult", "SolverConfig", "flatten", "retract", "solve"]
__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
