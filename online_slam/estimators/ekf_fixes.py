"""The EKF's absolute fixes (a mixin of :class:`~online_slam.estimators.ekf.EkfSlam`).

A fix measures the active robot's pose only: ``h(x) = [x + R(theta) offset, theta]`` whitened by its square-root
information (:mod:`online_slam.models.fix`), the rows it does not measure dropped. So the update is a Kalman
update of unit noise on the pose columns, ``S = H P_rr H^T + I``, its heading residual wrapped by the one wrap
function. A step that grows (``extend``) updates with its new fixes only: each enters once.

Each fix is gated first: its own NIS (against the state before the step's fixes) beyond the chi-square bound a
good fix exceeds with probability :data:`~online_slam.models.fix.FIX_FALSE_ALARM` (41.4 for a position's 2 degrees
of freedom, 37.3 for a heading's 1; ``gate_probability`` 1 turns it off, as for sightings) refuses it, and it is
counted (``fixes_rejected``), so one GPS jump does not drag the estimate off; the rest update jointly
(:func:`~online_slam.factors.fixes.fix_gate`, the smoother's gate too).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.ekf_config import EkfConfig
from online_slam.estimators.ekf_state import EkfState
from online_slam.factors.fixes import fix_gate, fix_report
from online_slam.frontend.steps import Step
from online_slam.models.fix import fix_factors, fix_residual_with_jacobians

Array = NDArray[np.float64]


class AbsoluteFixes:
    """Updates with a step's ``position`` and ``heading`` fixes."""

    state: EkfState
    config: EkfConfig
    x: Array
    P: Array
    _apply: Callable[[Array, Array, Array], None]
    """The filter's update (``x += K y``, ``P -= K S K^T``)."""

    def _fix(self, step: Step, start: int = 0) -> None:
        """Update with the step's fixes ``start:`` (those not used yet)."""
        new = step.fixes[start:]
        if not new:
            return
        mean, offset, W = fix_factors(new)
        e, J = fix_residual_with_jacobians(self.x[:3, 0], offset, mean)
        H, y = (W @ J).reshape(-1, 3), -np.einsum("kij,kj->ki", W, e).reshape(-1)
        rows = np.any(H != 0.0, axis=1)  # what a fix does not measure: zero rows
        owner = np.repeat(np.arange(len(new)), 3)[rows]
        H, y = H[rows], y[rows]
        passed, nis = fix_gate(self.x[:3, 0], self.P[:3, :3], new)  # each by its own covariance, not as widened
        passed |= self.config.gate_probability >= 1.0
        self.state.fix_nis.extend(nis[passed].tolist())
        self.state.fixes_rejected += int(np.count_nonzero(~passed))
        self.state.fixes_used = len(step.fixes)
        keep = passed[owner]
        if keep.any():
            H, y = H[keep], y[keep]
            PHt = self.P[:, :3] @ H.T
            self._apply(PHt, H @ PHt[:3] + np.eye(len(H)), y)

    def _fix_info(self) -> dict[str, int]:
        """Fixes used and refused so far (nothing when none came)."""
        return fix_report(len(self.state.fix_nis), self.state.fixes_rejected)
