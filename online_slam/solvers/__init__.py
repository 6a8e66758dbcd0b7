"""Sparse nonlinear least-squares solvers over a :class:`~online_slam.factors.FactorGraph`."""

from online_slam.solvers.least_squares import QuadraticPrior, SolverConfig, SolveResult, flatten, retract, solve

__all__ = ["QuadraticPrior", "SolveResult", "SolverConfig", "flatten", "retract", "solve"]
