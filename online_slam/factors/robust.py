"""Robust losses for observation factors, applied by iteratively reweighted least squares.

A loss maps the squared whitened residual norm ``s = |W e|^2`` of one observation to ``rho(s)``; the cost is
``0.5 * rho(s)`` instead of ``0.5 * s``. Each linearization scales the observation's residual and Jacobian by
``sqrt(rho'(s))`` (as GTSAM's robust noise models do), so Gauss-Newton sees the reweighted problem.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RobustLoss:
    """A robust loss on observation residuals."""

    kind: str = "huber"
    """``huber`` (quadratic within ``scale`` sigmas, linear beyond), ``cauchy``, or ``tail`` (quadratic within
    ``scale`` sigmas — exactly least squares while every residual is inside — and
    a Cauchy tail beyond, weight ``k^2 / s`` at ``s >= k^2``)."""
    scale: float = 1.345
    """Threshold in whitened units (sigmas); 1.345 gives Huber 95% efficiency on Gaussian data."""

    def __post_init__(self) -> None:
        if self.kind not in ("huber", "cauchy", "tail"):
            raise ValueError(f"unknown robust loss {self.kind!r}; expected huber, cauchy or tail")
        if not self.scale > 0:
            raise ValueError("robust loss scale must be > 0")

    @property
    def quadratic_within(self) -> float:
        """Squared norm up to which the loss is exactly least squares (rho(s) = s, weight 1); 0 for Cauchy."""
        return 0.0 if self.kind == "cauchy" else self.scale * self.scale

    def rho(self, s: ArrayLike) -> Array:
        """Loss of squared whitened norms s (any shape); ``rho(s) ~ s`` for small s."""
        s = np.asarray(s, dtype=float)
        k = self.scale
        if self.kind == "huber":
            r = np.sqrt(s)
            return np.where(r <= k, s, 2.0 * k * r - k * k)
        if self.kind == "tail":
            return np.where(s <= k * k, s, k * k + k * k * np.log1p(np.maximum(s - k * k, 0.0) / (k * k)))
        return k * k * np.log1p(s / (k * k))

    def weight(self, s: ArrayLike) -> Array:
        """IRLS weight ``rho'(s)`` in (0, 1]."""
        s = np.asarray(s, dtype=float)
        k = self.scale
        if self.kind == "huber":
            r = np.sqrt(s)
            return np.where(r <= k, 1.0, k / np.maximum(r, 1e-300))
        if self.kind == "tail":
            return np.where(s <= k * k, 1.0, k * k / np.maximum(s, k * k))
        return 1.0 / (1.0 + s / (k * k))


def outlier_threshold(false_alarm: float, dof: int = 2) -> float:
    """The chi-square value an inlier's squared whitened residual exceeds with probability ``false_alarm``."""
    from scipy.stats import chi2

    return float(chi2.isf(false_alarm, dof))
