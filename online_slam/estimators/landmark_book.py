"""Landmarks for sightings without ids: association against an estimator's own belief, tentative landmarks.

An estimator that associates holds one :class:`LandmarkBook`. For each scan (the sightings of the newest pose)
the book

1. picks the candidate landmarks within reach of the predicted pose and asks the estimator for the joint
   covariance of ``[pose, candidates]`` (its own belief: the EKF's P, the smoother's window information);
2. pairs sightings with confirmed landmarks by nearest neighbour or JCBB (``frontend.association``);
3. keeps a sighting no landmark takes out of everything when a landmark not taken by another sighting of the scan
   passes a wider gate (ambiguous: it could be that one, and a new landmark there would duplicate it);
4. matches the remaining sightings with *tentative* landmarks (nearest, chi-square gate on the two sightings'
   world points, each tentative at most once per scan), or starts a new tentative landmark;
5. confirms a tentative landmark at its ``confirm``-th sighting (in distinct steps). Tentative landmarks not
   confirmed within ``tentative_steps`` steps of their first sighting are dropped: clutter never becomes map.

Where tentative landmarks live depends on the estimator (``inside``):

- *inside* (the EKF): a new landmark enters the estimator's state at once, from its first sighting, and is
  associated like any other (its own covariance); dropping it deletes it from the state (for a Gaussian in
  covariance form, exact marginalization). Maps reported leave tentative landmarks out.
- *outside* (the smoother): the book keeps tentative landmarks itself (a world point fused from the sightings,
  gated on the sightings' noise); at confirmation the estimator gets the confirming sighting with a fresh id, and
  the earlier sightings (``retro``) to add at their poses while those are still in its window.

Each sighting's label (the landmark it went to, if that landmark stayed) is kept for scoring against ids where a
stream has them, and for the batch solver, which solves with these associations.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from online_slam.checkpoint import Checkpointed
from online_slam.estimators.association_config import AssociationConfig
from online_slam.factors.information import floored
from online_slam.frontend.association import (
    Association,
    Belief,
    associate,
    individual_log_likelihoods,
    rival_ratio,
)
from online_slam.models.observation import (
    POSITION,
    RANGE_BEARING,
    as_models,
    distance,
    landmark_from_sighting,
    landmark_from_sighting_with_jacobians,
    split_models,
)
from online_slam.sources.events import GeneratedId, LandmarkId

Array = NDArray[np.float64]
Index = NDArray[np.int64]

CovarianceOf = Callable[[Index], Array]
"""Joint covariance of ``[pose, landmarks idx...]``, shape (3 + 2c, 3 + 2c), for landmark indices (c,)."""


def _point_covariance(pose: Array, z: Array, R: Array, model: NDArray[np.int8]) -> Array:
    """Covariance of each sighting's world point from its measurement noise alone, shape (k, 2, 2)."""
    J = landmark_from_sighting_with_jacobians(pose[None, :], z, model)[2]
    return J @ R @ np.swapaxes(J, 1, 2)


def _rows(*shape: int, dtype: type = float) -> Any:
    """A default of no rows of the given shape."""
    return field(default_factory=lambda: np.zeros((0, *shape), dtype=dtype))


@dataclass(eq=False)
class LandmarkBook(Checkpointed):
    """Association state of one estimator: tentative landmarks, ids given out, each sighting's label.

    Every field is state a checkpoint keeps (:meth:`state_dict`, :meth:`load_state`) but the gates, derived
    from the configuration.
    """

    config: AssociationConfig
    """Method, gates, confirmation."""
    inside: bool
    """Tentative landmarks live in the estimator's state (True) or in the book (False)."""
    _next_key: int = 0
    """Key of the next tentative landmark of the book (outside)."""
    _next_id: int = 0
    """Number of the next landmark id given out (:class:`GeneratedId`: never one of the stream's ids)."""
    _pending: dict[LandmarkId, list[int]] = field(default_factory=dict)
    """Inside: the estimator's tentative landmarks, id -> [sightings, first step, last step]."""
    _deleted: set[LandmarkId] = field(default_factory=set)
    """Inside: tentative landmarks dropped unconfirmed (deleted from the estimator's state)."""
    _keys: Index = _rows(dtype=np.int64)
    """Outside: the book's tentative landmarks, one row each: their keys, shape (T,)."""
    _points: Array = _rows(2)
    """Their world points fused from their sightings, shape (T, 2)."""
    _covs: Array = _rows(2, 2)
    """The points' covariances, shape (T, 2, 2)."""
    _counts: Index = _rows(dtype=np.int64)
    """Sightings of each, shape (T,)."""
    _first: Index = _rows(dtype=np.int64)
    """Step of each one's first sighting, shape (T,)."""
    _last: Index = _rows(dtype=np.int64)
    """Step of each one's last sighting, shape (T,)."""
    _pose_covs: Array = _rows(3, 3)
    """The pose's covariance when each was last seen, shape (T, 3, 3)."""
    _sightings: dict[int, list[tuple[int, Array, Array, Any]]] = field(default_factory=dict)
    """Outside: the sightings ``(step, z, R, model)`` of each tentative landmark, by key (the model a tag, or a
    :data:`SIGHTING` with the sensor's mounting)."""
    _confirmed_keys: dict[int, LandmarkId] = field(default_factory=dict)
    """Outside: the id each confirmed tentative landmark was given, by key."""
    _labels: list[LandmarkId | None] = field(default_factory=list)
    """Per sighting: a landmark id, -(key + 1) for a book-tentative one, or None."""
    retro: list[tuple[LandmarkId, int, Array, Array, Any]] = field(default_factory=list)
    """Outside: earlier sightings ``(id, step, z, R, model tag)`` of the landmarks the last :meth:`assign`
    confirmed."""
    dropped: int = 0
    """Tentative landmarks dropped unconfirmed."""
    ambiguous: int = 0
    """Sightings kept out: no landmark took them, but one was too close for a new landmark."""
    unlikely: int = 0
    """Sightings JCBB paired that were likelier of an unmapped landmark (``new_density``): made new ones."""
    not_in_map: int = 0
    """Sightings no landmark took, left out because no new landmark may start (``new_landmarks`` False)."""
    deferred: int = 0
    """Sightings left out with their scan: a rival pairing put the robot elsewhere about as likely (``rival``)."""
    _gate: float = field(init=False)
    """Individual gate on a sighting's chi-square (2 dof)."""
    _new_gate: float = field(init=False)
    """The wider gate a sighting must fail with every landmark to start a new one."""

    def __post_init__(self) -> None:
        self._gate = float(chi2.isf(1.0 - self.config.gate_probability, 2))
        self._new_gate = float(chi2.isf(1.0 - self.config.new_probability, 2))

    # -- the scan ----------------------------------------------------------------------------------
    def expire(self, step_index: int) -> list[LandmarkId]:
        """Drop tentative landmarks whose time to be confirmed is over; inside: the ids to delete from the state."""
        limit = self.config.tentative_steps
        if self.inside:
            old = [lid for lid, (_, first, _) in self._pending.items() if step_index - first >= limit]
            for lid in old:
                del self._pending[lid]
            self._deleted.update(old)
            self.dropped += len(old)
            return old
        rows = np.flatnonzero(step_index - self._first >= limit)
        if len(rows):
            self.dropped += len(rows)
            for key in self._keys[rows]:
                self._sightings.pop(int(key), None)
            self._remove(rows)
        return []

    def is_tentative(self, lid: LandmarkId) -> bool:
        """Inside: whether the estimator's landmark ``lid`` is still tentative."""
        return lid in self._pending

    @property
    def has_tentative(self) -> bool:
        """Inside: whether any of the estimator's landmarks is tentative."""
        return bool(self._pending)

    def needs(self, ids: Sequence[LandmarkId | None]) -> bool:
        """Whether these sightings ask for association (every one with ``nn``/``jcbb``; else those without id)."""
        return bool(len(ids)) and (self.config.ignores_ids or None in ids)

    def assign_ids(
        self,
        step_index: int,
        ids: Sequence[LandmarkId | None],
        z: Array,
        R: Array,
        model: NDArray[np.int8],
        pose: Array,
        pose_cov: Array,
        positions: Array,
        landmark_ids: Sequence[LandmarkId],
        covariance_of: CovarianceOf,
    ) -> list[LandmarkId | None]:
        """The sightings' ids with those to associate (all, or those without one) filled in by :meth:`assign`."""
        everything = self.config.ignores_ids
        ask = np.array([i for i, lid in enumerate(ids) if everything or lid is None], dtype=np.int64)
        assigned = self.assign(
            step_index, pose, pose_cov, z[ask], R[ask], positions, landmark_ids, covariance_of, model[ask]
        )
        out = list(ids)
        for i, lid in zip(ask, assigned):
            out[int(i)] = lid
        return out

    def assign(
        self,
        step_index: int,
        pose: Array,
        pose_cov: Array,
        z: Array,
        R: Array,
        positions: Array,
        ids: Sequence[LandmarkId],
        covariance_of: CovarianceOf,
        model: Any = RANGE_BEARING,
    ) -> list[LandmarkId | None]:
        """Pair one scan's sightings with landmarks (call :meth:`expire` for the step first).

        Args:
            step_index: Index of the pose that took the scan.
            pose: Its predicted pose, shape (3,); ``pose_cov`` its covariance (3, 3).
            z: Sightings, shape (k, 2); ``R`` their noise, (k, 2, 2).
            positions: Current estimates of the estimator's landmarks, shape (M, 2); ``ids`` their ids (M,).
            covariance_of: The estimator's joint covariance of the pose and some landmarks.
            model: The sightings' model tags (k,), or one tag for all (default range-bearing).

        Returns:
            Per sighting: the id to use (an existing landmark, or a new one to create from this sighting), or
            None (the estimator does not use it).
        """
        k = len(z)
        out: list[LandmarkId | None] = [None] * k
        labels: list[Any] = [None] * k
        self.retro = []
        if k == 0:
            return out
        model = as_models(model, k)
        free = np.ones(k, dtype=bool)
        if len(positions):
            candidates = self._candidates(pose, pose_cov, distance(z, model), positions)
            if len(candidates):
                belief = Belief(pose, positions[candidates], covariance_of(candidates))
                pairing = associate(self.config.scan_method, belief, z, R, self.config.gate_probability, model)
                if self.config.new_density > 0.0:
                    pairing = self._likely(pairing, belief, z, R, model)
                if self.config.rival > 0.0 and (pairing.landmark >= 0).any():
                    ratio = rival_ratio(
                        belief, z, R, pairing, self._new_gate, self.config.gate_probability, model, self._gate
                    )
                    if ratio >= self.config.rival:
                        self.deferred += k
                        self._labels.extend(labels)
                        return out
                for i in np.flatnonzero(pairing.landmark >= 0):
                    lid = ids[int(candidates[pairing.landmark[i]])]
                    out[i] = labels[i] = lid
                    self._seen_again(lid, step_index)
                paired = pairing.landmark >= 0
                distances = pairing.distances.copy()
                distances[:, pairing.landmark[paired]] = np.inf  # a landmark taken in this scan is not that one
                near = distances.min(axis=1) <= self._new_gate
                new = pairing.landmark == -2  # less likely than an unmapped landmark: a new one, however near
                self.ambiguous += int(np.sum(~paired & ~new & near))
                free = (~paired & ~near) | new
        if free.any() and not self.config.new_landmarks:  # localisation on a map: nothing new
            self.not_in_map += int(free.sum())
            free[:] = False
        if free.any():
            if self.inside:
                for i in np.flatnonzero(free):
                    lid = out[i] = labels[i] = self._new_id()
                    if self.config.confirm > 1:
                        self._pending[lid] = [1, step_index, step_index]
            else:
                self._tentative(step_index, pose, pose_cov, (z, R, model), free, out, labels)
        self._labels.extend(labels)
        return out

    def _likely(self, pairing: Association, belief: Belief, z: Array, R: Array, model: NDArray[np.int8]) -> Association:
        """The pairing without pairs less likely than a sighting of an unmapped landmark (``new_density``)."""
        paired = np.flatnonzero(pairing.landmark >= 0)
        if len(paired) == 0:
            return pairing
        _, log_l = individual_log_likelihoods(belief, z[paired], R[paired], model[paired])
        own = log_l[np.arange(len(paired)), pairing.landmark[paired]]
        per_unit = np.where(split_models(model)[0][paired] == POSITION, 1.0, z[paired, 0])  # polar: dA = r dr db
        unlikely = own < np.log(self.config.new_density * per_unit)
        if not unlikely.any():
            return pairing
        landmark = pairing.landmark.copy()
        landmark[paired[unlikely]] = -2
        self.unlikely += int(unlikely.sum())
        return Association(landmark, pairing.joint_distance, pairing.distances)

    def _seen_again(self, lid: LandmarkId, step_index: int) -> None:
        """Inside: a tentative landmark paired again (once per step counts); confirmed at ``confirm``."""
        entry = self._pending.get(lid)
        if entry is None or entry[2] == step_index:
            return
        entry[0] += 1
        entry[2] = step_index
        if entry[0] >= self.config.confirm:
            del self._pending[lid]

    def _candidates(self, pose: Array, pose_cov: Array, distances: Array, positions: Array) -> Index:
        """Landmarks within reach of the predicted pose (a generous Euclidean prefilter of the gate), given how
        far the scan's sightings put their landmarks."""
        longest = float(distances.max())
        position_sigma = float(np.sqrt(max(np.linalg.eigvalsh(pose_cov[:2, :2])[-1], 0.0)))
        heading_sigma = float(np.sqrt(max(pose_cov[2, 2], 0.0)))
        reach = longest + self.config.reach + 3.0 * (position_sigma + longest * heading_sigma)
        offsets = positions - pose[:2]
        return np.flatnonzero(np.einsum("mi,mi->m", offsets, offsets) <= reach * reach)

    def _tentative(
        self,
        step_index: int,
        pose: Array,
        pose_cov: Array,
        sightings: tuple[Array, Array, NDArray[np.int8]],
        free: NDArray[np.bool_],
        out: list,
        labels: list,
    ) -> None:
        """Outside: match free sightings with the book's tentative landmarks; confirm, or start new ones.

        A sighting and a tentative point are compared in the world: their noise, plus what the pose may have
        drifted since the tentative landmark was last seen (the growth of the pose's covariance since then,
        through the sighting's point Jacobian).
        """
        z, R, model = sightings
        rows = np.flatnonzero(free)
        points = landmark_from_sighting(pose[None, :], z[rows], model[rows])
        covs = _point_covariance(pose, z[rows], R[rows], model[rows])
        taken = np.full(len(rows), -1, dtype=np.int64)
        if len(self._keys):
            diff = points[:, None, :] - self._points[None, :, :]  # (f, T, 2)
            growth = floored(np.asarray(pose_cov)[None] - self._pose_covs, 0.0)  # (T, 3, 3), its PSD part
            G = np.zeros((len(rows), 2, 3))  # d(point)/d(pose)
            G[:, 0, 0] = G[:, 1, 1] = 1.0
            G[:, :, 2] = np.stack([-(points[:, 1] - pose[1]), points[:, 0] - pose[0]], -1)
            drift = np.einsum("fai,tij,fbj->ftab", G, growth, G)
            S = covs[:, None] + self._covs[None, :] + drift
            d2 = np.einsum("fti,fti->ft", diff, np.linalg.solve(S, diff[..., None])[..., 0])
            d2[:, self._last == step_index] = np.inf  # one sighting per tentative landmark and step
            used: set[int] = set()
            for flat in np.argsort(d2, axis=None, kind="stable"):
                f, t = np.unravel_index(flat, d2.shape)
                if d2[f, t] > self._gate:
                    break
                if taken[f] < 0 and int(t) not in used:
                    taken[f] = t
                    used.add(int(t))
        confirmed: list[int] = []
        for f, i in enumerate(rows):
            t = int(taken[f])
            if t >= 0:  # fuse the two estimates of the point (information form)
                A, B = np.linalg.inv(self._covs[t]), np.linalg.inv(covs[f])
                C = np.linalg.inv(A + B)
                self._points[t] = C @ (A @ self._points[t] + B @ points[f])
                self._covs[t] = C
                self._counts[t] += 1
                self._last[t] = step_index
                self._pose_covs[t] = pose_cov
                key = int(self._keys[t])
                labels[i] = -(key + 1)
                if self._counts[t] < self.config.confirm:
                    self._sightings[key].append((step_index, z[i].copy(), R[i].copy(), model[i].copy()))
                    continue
                confirmed.append(t)
                lid = out[i] = labels[i] = self._new_id()
                self._confirmed_keys[key] = lid
                self.retro += [(lid, g, zz, RR, m) for g, zz, RR, m in self._sightings.pop(key)]
                continue
            key = self._next_key
            self._next_key += 1
            if self.config.confirm <= 1:
                out[i] = labels[i] = self._confirmed_keys[key] = self._new_id()
                continue
            labels[i] = -(key + 1)
            self._sightings[key] = [(step_index, z[i].copy(), R[i].copy(), model[i].copy())]
            self._keys = np.r_[self._keys, key]
            self._points = np.vstack([self._points, points[f]])
            self._covs = np.concatenate([self._covs, covs[f][None]])
            self._counts = np.r_[self._counts, 1]
            self._first = np.r_[self._first, step_index]
            self._last = np.r_[self._last, step_index]
            self._pose_covs = np.concatenate([self._pose_covs, np.asarray(pose_cov, dtype=float)[None]])
        if confirmed:
            self._remove(np.array(confirmed, dtype=np.int64))

    def _new_id(self) -> GeneratedId:
        """A fresh landmark id."""
        self._next_id += 1
        return GeneratedId(self._next_id - 1)

    def _remove(self, rows: Index) -> None:
        keep = np.ones(len(self._keys), dtype=bool)
        keep[rows] = False
        self._keys, self._points, self._covs = self._keys[keep], self._points[keep], self._covs[keep]
        self._counts, self._first, self._last = self._counts[keep], self._first[keep], self._last[keep]
        self._pose_covs = self._pose_covs[keep]

    # -- reports -----------------------------------------------------------------------------------
    @property
    def tentative(self) -> int:
        """Tentative landmarks held now."""
        return len(self._pending) if self.inside else len(self._keys)

    def labels(self) -> list[LandmarkId | None]:
        """Per sighting the book saw, in order: the landmark it went to (if that one stayed), or None."""
        resolved, deleted, pending = self._confirmed_keys, self._deleted, self._pending

        def label(value: Any) -> LandmarkId | None:
            if isinstance(value, int) and not isinstance(value, bool) and value < 0 and not self.inside:
                return resolved.get(-value - 1)
            return None if value in deleted or value in pending else value

        return [label(value) for value in self._labels]

    def info(self) -> dict[str, Any]:
        """For an estimate's info: ``association`` (counts) and ``labels``, once the book has associated ({})."""
        if not self.config.ignores_ids and not self._labels:
            return {}
        return {"association": self.report(), "labels": self.labels()}

    def report(self) -> dict[str, Any]:
        """Counts for the estimator's final info."""
        return {
            "method": self.config.method,
            "tentative_dropped": self.dropped,
            "tentative_left": self.tentative,
            "ambiguous_sightings": self.ambiguous,
            "unlikely_pairings": self.unlikely,
            **({"rival_scans_sightings": self.deferred} if self.config.rival > 0 else {}),
            **({"not_in_map": self.not_in_map} if not self.config.new_landmarks else {}),
        }
