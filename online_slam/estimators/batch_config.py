"""Settings of the batch estimator (an import-light module: the option table reads them)."""

from __future__ import annotations

from dataclasses import dataclass, field

from online_slam.factors.robust import RobustLoss
from online_slam.solvers.config import SolverConfig

OUTLIER_MODES = ("auto", "off")
"""What :attr:`BatchConfig.outliers` takes."""


@dataclass(frozen=True)
class BatchConfig:
    """Settings of the batch estimator."""

    solver: SolverConfig = field(default_factory=SolverConfig)
    """Settings of the sparse Levenberg-Marquardt solver."""
    loss: RobustLoss | None = None
    """Robust loss on observations (Huber or Cauchy), or None for plain least squares."""
    outliers: str = "auto"
    """``auto``: solve plain least squares, then test every observation's residual at the solution against a
    chi-square bound at a whole-stream false-alarm rate of ``outlier_false_alarm``; only if one exceeds it
    (a contaminated stream) solve again with a Cauchy loss (``outlier_loss``) from the same initial values, drop
    the observations whose residual there exceeds the per-observation bound ``reject_false_alarm``, and finish
    with plain least squares on the rest. A clean stream keeps the exact least-squares solution. ``off``:
    plain least squares (or ``loss``) only."""
    outlier_false_alarm: float = 1e-3
    """Probability that a clean stream triggers the robust pass (split over its observations)."""
    reject_false_alarm: float = 1e-3
    """Probability that an inlier is dropped once the robust pass has run."""
    outlier_loss: RobustLoss = field(default_factory=lambda: RobustLoss("cauchy", 3.0))
    """Loss of the robust pass."""
    initial: str = "auto"
    """Initial values: ``odometry`` (composed odometry, landmarks from first sight), the final estimate of
    another estimator of the same replay (``ekf``, ``smoother``), or ``auto`` (default): the (first) smoother's if one
    ran, else the EKF's, else odometry. From composed odometry LM can end in a poor local minimum on long real runs
    (MRCLAM; see docs/estimators.md, "Batch")."""
    use_ids: bool = True
    """False (association by ``nn``/``jcbb``): the stream's ids are ignored; the batch solves with the associations
    of the estimate it starts from (each sighting's landmark as that estimator decided, in the end)."""

    def __post_init__(self) -> None:
        if self.outliers not in OUTLIER_MODES:
            raise ValueError(f"batch outliers must be one of {', '.join(OUTLIER_MODES)}, not {self.outliers!r}")
        if not (self.initial in ("auto", "odometry") or self.initial.startswith(("ekf", "smoother"))):
            raise ValueError(f"batch_init must be auto, odometry or an estimator's name, not {self.initial!r}")
        if not (0.0 < self.outlier_false_alarm < 1.0 and 0.0 < self.reject_false_alarm < 1.0):
            raise ValueError("the batch's false-alarm probabilities must be in (0, 1)")
