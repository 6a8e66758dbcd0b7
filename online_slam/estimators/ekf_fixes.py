"""The EKF's absolute fixes (a mixin of :class:`~online_slam.estimators.ekf.EkfSlam`).

A fix measures the active robot's pose only: ``h(x) = [x + R(theta) offset, theta]`` whitened by its square-root
information (:mod:`online_slam.models.fix`), the rows it does not measure dropped. So the update is a Kalman
update of unit noise on the pose columns, ``S = H P_rr H^T + I``, its heading residual wrapped by the one wrap
function. A step that grows (``extend``) updates with its new fixes only: each enters once.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from online_slam.estimators.ekf_state import EkfState
from online_slam.frontend.steps import Step
from online_slam.models.fix import fix_factors, fix_residual_with_jacobians

Array = NDArray[np.float64]


class AbsoluteFixes:
    """Updates with a step's ``position`` and ``heading`` fixes."""

    state: EkfState
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
        H, y = H[rows], y[rows]
        PHt = self.P[:, :3] @ H.T
        S = H @ PHt[:3] + np.eye(len(H))
        self.state.fix_nis.append(float(y @ np.linalg.solve(S, y)))
        self._apply(PHt, S, y)
        self.state.fixes_used = len(step.fixes)
