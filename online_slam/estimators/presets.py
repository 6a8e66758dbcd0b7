"""Named settings shared by the CLI and the library API (one meaning for ``--robust`` and ``robust=``)."""

from __future__ import annotations

from dataclasses import replace

from online_slam.estimators.batch import BatchConfig
from online_slam.estimators.smoother import SmootherConfig
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
        plain = replace(smoother, loss=None, reject_false_alarm=0.0, consensus=False)
        return plain, replace(batch, loss=None, outliers="off")
    loss = RobustLoss(robust, scale)
    return replace(smoother, loss=loss), replace(batch, loss=loss)


def smoother_label(config: SmootherConfig) -> str:
    """The name of a smoother run beside others (``compare``), saying what its window is.

    ``smoother W=20..120 D=18 K=1``: at least W=20 poses, more until the window's path is 18 m long, at most 120,
    solved every K=1 steps; ``smoother W=5 K=1``: exactly 5 poses (``window_distance`` 0, or a ``window_max``
    that is no more than W). A row so named keeps its meaning whatever the defaults are.
    """
    most = max(config.window, config.window_max)
    if config.window_distance == 0 or most == config.window:
        return f"smoother W={config.window} K={config.relinearize_every}"
    return f"smoother W={config.window}..{most} D={config.window_distance:g} K={config.relinearize_every}"
