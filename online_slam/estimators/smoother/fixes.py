"""The smoother's gate on absolute fixes: each fix judged once, when it comes, against the newest pose as the window
predicts it (its estimate and covariance before the fix), as the EKF judges it (:func:`~online_slam.factors.fixes.
fix_gate`); a refused fix never enters the window, the marginal prior or the global solves, so one GPS jump of
metres does not drag the estimate (a window solve would spread it over the odometry, where no residual shows it)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from online_slam.factors.fixes import fix_gate, fix_report
from online_slam.frontend.steps import Step

Array = NDArray[np.float64]


def gated(step: Step, decisions: dict[int, list[bool]], pose: Array, cov: Array) -> Step:
    """The step with the fixes the gate refuses left out; ``decisions`` (by pose) holds each fix's verdict and
    grows with the fixes not judged yet, judged against ``pose`` (3,) with covariance ``cov`` (3, 3)."""
    if not step.fixes:
        return step
    judged = decisions.setdefault(step.index, [])
    if len(judged) < len(step.fixes):
        judged += fix_gate(pose, cov, step.fixes[len(judged) :])[0].tolist()
    if all(judged):
        return step
    return replace(step, fixes=tuple(f for f, ok in zip(step.fixes, judged, strict=True) if ok))


def fix_counts(decisions: dict[int, list[bool]]) -> dict[str, int]:
    """Fixes used and refused (nothing when none came), as the EKF reports them."""
    verdicts = [ok for judged in decisions.values() for ok in judged]
    used = int(np.count_nonzero(verdicts))
    return fix_report(used, len(verdicts) - used)
