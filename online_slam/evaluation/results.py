"""Result records of a replay: what tables, JSON files and plots all read."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from online_slam.estimators.protocol import Estimate


def _finite_or_none(value: float | None) -> float | None:
    if value is None or value != value:  # NaN
        return None
    return float(value)


@dataclass(frozen=True)
class OdometryResult:
    """Dead-reckoning figures (composed odometry from the start pose)."""

    rmse_m: float | None
    """Position RMSE against truth, metres (None without truth)."""
    endpoint_gap_m: float
    """Distance between the last and first composed positions, metres."""
    landmark_rmse_m: float | None = None
    """RMSE of landmarks placed from their first observation, metres (None without truth)."""


@dataclass(frozen=True)
class EstimatorResult:
    """One estimator's figures over the whole stream."""

    final_rmse_m: float | None
    """Position RMSE of the final estimate against truth, metres (None without truth)."""
    endpoint_gap_m: float
    """Distance between the last and first estimated positions, metres."""
    landmark_rmse_m: float | None
    """Landmark RMSE against truth, metres (None without landmark truth)."""
    total_s: float
    """Wall time spent in this estimator (every step plus the final solve), seconds."""
    details: dict[str, Any] = field(default_factory=dict)
    """Estimator-specific report (iterations, convergence, costs, ...)."""

    def to_json(self) -> dict[str, Any]:
        """The JSON object of this result."""
        return {
            "final_rmse_m": _finite_or_none(self.final_rmse_m),
            "endpoint_gap_m": self.endpoint_gap_m,
            "landmark_rmse_m": _finite_or_none(self.landmark_rmse_m),
            "total_s": self.total_s,
            **self.details,
        }


@dataclass(frozen=True)
class Results:
    """Everything a replay produced."""

    source: str
    """Name of the source (path, ``<stdin>`` or built-in world)."""
    poses: int
    """Number of poses (steps) replayed."""
    landmarks: int
    """Number of distinct landmarks observed."""
    observations: int
    """Number of observations given to the estimators."""
    odometry: OdometryResult
    """Dead-reckoning figures."""
    estimators: dict[str, EstimatorResult]
    """Figures per estimator, by name."""
    estimates: dict[str, Estimate] = field(default_factory=dict, repr=False)
    """Final estimates per estimator (``odometry`` included), for plots and further analysis."""
    alignment: str = "anchor"
    """How estimates were put in the truth's frame: ``anchor`` (first pose) or ``se2`` (least squares)."""
    error: str | None = None
    """The input error that ended the stream early, or None; the figures cover what came before it."""

    def to_json(self) -> dict[str, Any]:
        """The documented JSON schema of ``online-slam replay --json``."""
        return {
            "source": self.source,
            "poses": self.poses,
            "landmarks": self.landmarks,
            "observations": self.observations,
            "alignment": self.alignment,
            "odometry": {
                "rmse_m": _finite_or_none(self.odometry.rmse_m),
                "endpoint_gap_m": self.odometry.endpoint_gap_m,
                "landmark_rmse_m": _finite_or_none(self.odometry.landmark_rmse_m),
            },
            "estimators": {name: result.to_json() for name, result in self.estimators.items()},
            "error": self.error,
        }
