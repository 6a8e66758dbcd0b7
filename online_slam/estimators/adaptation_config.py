"""Settings of the noise adaptation (:mod:`~online_slam.estimators.adaptation`), import-light for the options."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class AdaptationConfig:
    """How an estimator adapts the declared noise to its innovations."""

    enabled: bool = True
    """Adapt the declared covariances to the innovations (default; ``--no-adapt-noise``: as given): the odometry's
    and the sightings' inflated while too small, the sightings' also shrunk while too wide (see
    :attr:`sensor_floor`)."""
    memory: float = 100.0
    """Updates the statistics remember (forgetting factor ``1 - 1/memory``)."""
    threshold: float = 3.0
    """A scale moves only while its estimate is this many standard errors from 1."""
    gain: float = 0.1
    """Fraction of the estimate's log a scale moves by per update."""
    max_scale: float = 100.0
    """Largest covariance scale (a sigma 10x the declared)."""
    sensor_floor: float = 0.01
    """Smallest sensor covariance scale (a sigma a tenth of the declared): the sightings' covariance also shrinks
    while the innovations show it too wide, unless the source declares it widened for correlation; the odometry's
    never shrinks. 1: inflate only."""

    def __post_init__(self) -> None:
        if not (self.memory >= 1.0 and self.threshold >= 0.0 and 0.0 < self.gain <= 1.0 and self.max_scale >= 1.0):
            raise ValueError("adaptation: memory >= 1, threshold >= 0, 0 < gain <= 1, max_scale >= 1")
        if not 0.0 < self.sensor_floor <= 1.0:
            raise ValueError("adaptation: 0 < sensor_floor <= 1")
