"""The EKF's map (a mixin of :class:`~online_slam.estimators.ekf.EkfSlam`): started from one (``--map``,
``--map-fixed``), and as reported."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.estimators.ekf_state import EkfState
from online_slam.sources.events import LandmarkId
from online_slam.sources.landmark_map import LandmarkMap

Array = NDArray[np.float64]


class PriorMap:
    """Loads a map's landmarks into the state before the first step; the map as reported."""

    state: EkfState
    dim_x: int
    x: Array
    P: Array
    _offset: int
    _grow: Callable[[Array, Array, Array], None]
    """Appends rows to the state: values, their cross-covariance with the state, their own covariance block."""

    def load_map(self, landmark_map: LandmarkMap, fixed: bool = False) -> None:
        """Start from a map (before the first step): its landmarks enter the state as priors with their joint
        covariance (independent when the map has none), confirmed. ``fixed``: with zero covariance instead, so
        that no update moves them (their rows of the gain are exactly zero: they act as known points) and they are
        never re-anchored; the invariant retraction, which turns the whole map with each heading correction, gives
        way to the standard update."""
        if len(self.state.landmark_ids) or len(self.state.history):
            raise OnlineSlamError("a map is loaded before the first step, into an empty filter")
        m = len(landmark_map)
        block = np.zeros((2 * m, 2 * m)) if fixed else landmark_map.covariance.copy()
        self.state.landmark_ids.extend(landmark_map.ids)
        self.state.index = {lid: j for j, lid in enumerate(self.state.landmark_ids)}
        self.state.streak, self.state.confirmed = np.zeros(m, dtype=np.int64), np.ones(m, dtype=bool)
        self.state.first = landmark_map.xy.copy()
        self.state.fixed = m if fixed else 0
        self._grow(landmark_map.xy.reshape(-1), np.zeros((2 * m, self.dim_x)), block)

    def landmark_marginals(self) -> Array:
        """2x2 marginal covariance of every landmark, shape (M, 2, 2)."""
        m = len(self.state.landmark_ids)
        first = len(self.P) - 2 * m + 2 * np.arange(m)  # the landmarks follow the robots' poses
        rows = first[:, None, None] + np.arange(2)[None, :, None]
        cols = first[:, None, None] + np.arange(2)[None, None, :]
        return self.P[rows, cols]

    def landmark_joint(self) -> Array:
        """Joint covariance of the reported map's landmarks (tentative ones left out), shape (2M, 2M)."""
        first = len(self.P) - 2 * len(self.state.landmark_ids)  # after the robots' poses
        block = self.P[first:, first:]
        mapped = self._mapped()
        if mapped is None:
            return block.copy()
        keep = np.repeat(mapped, 2)
        return block[np.ix_(keep, keep)]

    def _mapped(self) -> NDArray[np.bool_] | None:
        """Which landmarks belong to the reported map (None: all; tentative ones do not)."""
        book = self.state.book
        if not book.has_tentative:
            return None
        return np.array([not book.is_tentative(lid) for lid in self.state.landmark_ids], dtype=bool)

    def _map(self) -> tuple[tuple[LandmarkId, ...], Array, Array]:
        """The reported map: ids, positions (M, 2), marginal covariances (M, 2, 2); tentative landmarks left out."""
        landmarks, covs = self.x[self._offset :, 0].reshape(-1, 2).copy(), self.landmark_marginals()
        mapped = self._mapped()
        if mapped is None:
            return tuple(self.state.landmark_ids), landmarks, covs
        ids = tuple(lid for lid, ok in zip(self.state.landmark_ids, mapped) if ok)
        return ids, landmarks[mapped], covs[mapped]
