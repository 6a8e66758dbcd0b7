"""Settings of the noise adaptation (:mod:`~online_slam.estimators.adaptation`), import-light for the options."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class AdaptationConfig:
    """How an estimator adapts the declared noise to its innovations."""

    enabled: bool = False
    """Inflate the declared covariances while the innovations show them too small, never below what was declared
    (``--adapt-noise``); False (default): the declared covariances as given."""
    memory: float = 100.0
    """Updates the statistics remember (forgetting factor ``1 - 1/memory``)."""
    threshold: float = 3.0
    """A scale moves only while its estimate is this many standard errors from 1."""
    gain: float = 0.1
    """Fraction of the estimate's log a scale moves by per update."""
    max_scale: float = 100.0
    """Largest covariance scale (a sigma 10x the declared)."""

    def __post_init__(self) -> None:
        if not (self.memory >= 1.0 and self.threshold >= 0.0 and 0.0 < self.gain <= 1.0 and self.max_scale >= 1.0):
            raise ValueError("adaptation: memory >= 1, threshold >= 0, 0 < gain <= 1, max_scale >= 1")
