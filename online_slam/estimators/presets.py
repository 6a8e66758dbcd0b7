"""Named settings shared by the CLI and the library API (one meaning for ``--robust`` and ``robust=``)."""

from __future__ import annotations

from dataclasses import replace

from online_slam.estimators.batch_config import BatchConfig
from online_slam.estimators.smoother.config import RobustConfig, SmootherConfig
from online_slam.factors.robust import RobustLoss

ROBUST_CHOICES = ("auto", "none", "huber", "cauchy")
"""Values of ``--robust`` / ``robust=``."""


def robust_settings(
    robust: str, scale: float, smoother: SmootherConfig, batch: BatchConfig
) -> tuple[SmootherConfig, BatchConfig]:
    """Apply a ``--robust`` choice to the smoother's and the batch's settings.

    ``auto`` keeps their defaults (smoother: least squares with a Cauchy tail beyond 5.3 sigmas in the window,
    outliers judged at marginalization,
    consensus restarts; batch: least squares, robust pass only when its residuals show outliers); ``none`` is
    plain least squares everywhere; ``huber``/``cauchy`` put that loss (``scale`` sigmas) on both.
    """
    if robust not in ROBUST_CHOICES:
        raise ValueError(f"robust must be one of {', '.join(ROBUST_CHOICES)}, not {robust!r}")
    if robust == "auto":
        return smoother, batch
    if robust == "none":
        plain = replace(smoother, robust=RobustConfig(loss=None, consensus=False, reject_false_alarm=0.0))
        return plain, replace(batch, loss=None, outliers="off")
    loss = RobustLoss(robust, scale)
    return replace(smoother, robust=replace(smoother.robust, loss=loss)), replace(batch, loss=loss)


def smoother_label(config: SmootherConfig) -> str:
    """The name of a smoother run beside others (``compare``), saying what its window is.

    ``smoother W=20..120 D=18 K=1``: at least W=20 poses, more until the window's path is 18 m long, at most 120,
    solved every K=1 steps; ``smoother W=5 K=1``: exactly 5 poses (``window_distance`` 0, or a ``window_max``
    that is no more than W); `` FEJ`` ends it with First-Estimates Jacobians, `` invariant`` with the carried
    prior (:attr:`SmootherConfig.linearization`). A row so named keeps its meaning whatever the defaults are.
    """
    window, every = config.window, config.relinearize_every
    most = max(window.size, window.max_poses)
    suffix = {"standard": "", "fej": " FEJ"}.get(config.linearization, f" {config.linearization}")
    if window.distance == 0 or most == window.size:
        return f"smoother W={window.size} K={every}{suffix}"
    return f"smoother W={window.size}..{most} D={window.distance:g} K={every}{suffix}"
