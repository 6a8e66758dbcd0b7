"""Settings of the least-squares solver (an import-light module: the option table reads them)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SolverConfig:
    """Settings of the sparse least-squares solver."""

    max_iterations: int = 100
    """Upper bound on accepted plus rejected iterations."""
    initial_lambda: float = 1e-6
    """Initial damping, relative to the diagonal of ``J^T J``; 0 gives pure Gauss-Newton."""
    relative_cost_tolerance: float = 1e-12
    """Stop when an accepted step lowers the cost by less than this fraction."""
    step_tolerance: float = 1e-10
    """Stop when the largest update component is below this (metres / radians)."""
    gradient_tolerance: float = 1e-10
    """Stop when the largest gradient component is below this."""
    model_tolerance: float = 0.0
    """Stop after an accepted, (nearly) undamped step whose actual and predicted cost decreases agree within this
    fraction of the cost: the quadratic model held over the step, so the next step would gain about their
    difference. 0 (default) turns it off; a smoother's per-step solves use it to save one relinearization."""

    def __post_init__(self) -> None:
        if self.max_iterations < 0:
            raise ValueError("max_iterations must be >= 0")
        tolerances = (self.relative_cost_tolerance, self.step_tolerance, self.gradient_tolerance, self.model_tolerance)
        if self.initial_lambda < 0 or min(tolerances) < 0:
            raise ValueError("the solver's damping and tolerances must be >= 0")
