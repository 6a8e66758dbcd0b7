"""Sparse nonlinear least-squares solvers over a :class:`~online_slam.factors.FactorGraph`."""

from online_slam.solvers.least_squares import SolverConfig, SolveResult, retract, solve

__all__ = ["SolveResult", "SolverConfig", "retract", "solve"]
