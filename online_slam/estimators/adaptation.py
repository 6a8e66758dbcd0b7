"""Noise adaptation: the declared odometry and sensor covariances scaled when the innovations show a sustained
mismatch (on by default; ``--no-adapt-noise``).

Each update's innovations ``y`` (m,) are modelled as ``N(0, a A + b B)``: ``A = H P H^T`` the part the predicted
state gives (too small when the odometry is declared too sure: the pose error shows in every sighting of a step
alike), ``B = blockdiag(R)`` the sightings' own (too small when the sensor is: independent per sighting), both as
declared times the scales already applied, so ``a = b = 1`` when they fit. The unbiased quadratic estimate of
``(a, b)`` (MINQUE; variance components as in ``--noise self``, here on innovations) is ``F^-1 q`` with
``F_ij = tr(S^-1 V_i S^-1 V_j)``, ``q_i = y^T S^-1 V_i S^-1 y``, ``S = a_w A + b_w B`` at a working point
``(a_w, b_w)``: the estimate so far. ``F`` and ``q`` are summed over the recent updates with exponential
forgetting. A scale moves by a fraction of its estimate's log per update while that estimate is beyond
``threshold`` standard errors from 1:

- up, on the standard error independent Gaussian innovations give (``2 F^-1``): a declaration too sure diverges
  the estimator, and inflating wrongly costs little. When the odometry scale rises, the estimator's covariance
  built with the odometry too sure rises with it (the EKF's ``P``, the smoother's marginal prior), as the steps to
  come do;
- down, on the larger of that and the scores' own dispersion (a sandwich with lags, Newey & West 1987: errors
  correlated in time, or heavy-tailed, are weaker evidence), and only the sensor's (to ``sensor_floor``), only
  while the predicted part is not too small (then the split between the parts is not to be trusted), and never for
  a source that declares its sightings widened for correlation (MRCLAM: its sigmas allow for errors correlated in
  time, which innovations do not show, so they read too wide). The odometry's never goes below 1: ``A`` holds the
  map's covariance too, and an odometry shrunk on it made the EKF diverge (benchmarks/RESULTS.md, "Declared noise
  that is wrong").

Where a sighting's line says by how much its covariance was widened (``widened``,
:meth:`~online_slam.frontend.pose.Step.z_own_cov`), a second set of statistics (:attr:`Adaptation.own`) builds
``B`` from each sighting's own covariance and moves the sensor scale: against the widened one, MRCLAM's innovations
show 2-4% of the variance declared, and a sensor declared 0.3x went unseen. The odometry scale stays with the
statistics read against the covariances as the estimator uses them: read against the own ones it no longer rose
where it had kept MRCLAM's held-out NEES lower (robot 5's whole run 4.72 -> 6.02). Sightings whose landmark the
estimator chose (``nn``, ``jcbb``, or a line without an id) are judged by the covariance declared: against their
own, a wrong pairing's slack reads as sensor noise (MRCLAM robot 1 with JCBB: the sensor scale rose to 1.44 and the
final error from 0.057 to 0.088 m).

The EKF and the smoother each keep their own (:class:`Adaptation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor, cho_solve

from online_slam.estimators.adaptation_config import AdaptationConfig
from online_slam.estimators.kalman import stacked_jacobian
from online_slam.frontend.steps import Step
from online_slam.models.observation import predict_with_jacobians, wrap_bearings

Array = NDArray[np.float64]

WORKING_RANGE = (0.02, 100.0)
"""Bounds of the working point (:attr:`Adaptation.working`)."""
WORKING_AFTER = 20
"""Updates before the working point follows the estimate (the first few say little)."""
LAG_DECAY = 0.95
"""Weight per update of a lag in the scores' long-run covariance (an exponential kernel of ~20 updates)."""
GATE = -2.0 * math.log(1e-4)
"""A sighting whose NIS exceeds this (18.4: the chi-square bound, 2 dof, an inlier exceeds with probability 1e-4,
the EKF's default gate) is an outlier and tells nothing of the noise."""


@dataclass
class Adaptation:
    """An estimator's adapted scales and the statistics behind them."""

    odometry_scale: float = 1.0
    """Multiplies every odometry covariance from now on."""
    sensor_scale: float = 1.0
    """Multiplies every sighting's covariance from now on."""
    information: Array = field(default_factory=lambda: np.zeros((2, 2)))
    """``F`` summed with forgetting, shape (2, 2)."""
    quadratic: Array = field(default_factory=lambda: np.zeros(2))
    """``q`` summed with forgetting, shape (2,)."""
    updates: int = 0
    """Updates seen."""
    working: Array = field(default_factory=lambda: np.ones(2))
    """``(a_w, b_w)``: where the next update's statistics are taken (the estimate so far, within
    :data:`WORKING_RANGE`)."""
    dispersion: Array = field(default_factory=lambda: np.zeros((2, 2)))
    """``Omega``: the scores' ``g = q - F theta`` long-run covariance, summed with forgetting (lags weighted
    ``LAG_DECAY ** l``), shape (2, 2)."""
    widened: bool = False
    """The newest step's sightings are declared widened for correlation (:attr:`Step.z_widened`): the sensor scale
    does not go below 1."""
    recent: Array = field(default_factory=lambda: np.zeros(2))
    """The recent scores, summed with ``LAG_DECAY`` (the lags' side of :attr:`dispersion`), shape (2,)."""
    own: Adaptation | None = None
    """Once sightings declared widened by their lines came (:meth:`Step.z_own_cov`): the statistics read against
    their own covariances, which move the sensor scale; these, read against the covariances as the estimator uses
    them, move the odometry's (module docs). None before."""


def innovation_statistics(y: Array, A: Array, B: Array, working: Array | None = None) -> tuple[Array, Array]:
    """``(F (2, 2), q (2,))`` of one update: innovations ``y`` (m,), predicted part ``A`` and sensor part ``B``
    (m, m) of their covariance, taken at ``working`` (2,) (None: (1, 1))."""
    S = A + B if working is None else working[0] * A + working[1] * B
    try:
        factor = cho_factor(S, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return np.zeros((2, 2)), np.zeros(2)
    m = len(y)
    solved = cho_solve(factor, np.hstack([A, B, y[:, None]]), check_finite=False)  # S^-1 [A, B, y]
    MA, MB, w = solved[:, :m], solved[:, m : 2 * m], solved[:, -1]
    F = np.array([[np.sum(MA * MA.T), np.sum(MA * MB.T)], [0.0, np.sum(MB * MB.T)]])
    F[1, 0] = F[0, 1]
    return F, np.array([w @ A @ w, w @ B @ w])


def adapt(
    state: Adaptation, F: Array, q: Array, config: AdaptationConfig, moves: tuple[bool, bool] = (True, True)
) -> float:
    """Fold one update's statistics in and move the scales (in place; only those ``moves`` says, odometry and sensor);
    the factor the odometry scale rose by (1: it did not rise), for the estimator to apply to the state's covariance
    built with it."""
    keep = 1.0 - 1.0 / config.memory
    state.information = keep * state.information + F
    state.quadratic = keep * state.quadratic + q
    state.updates += 1
    if (inverse := _inverse(state.information)) is None:
        return 1.0
    estimate = inverse @ state.quadratic
    g = q - F @ estimate
    state.dispersion = keep * state.dispersion + np.outer(g, g) + np.outer(g, state.recent) + np.outer(state.recent, g)
    state.recent = LAG_DECAY * state.recent + g
    # rises on the independent Gaussian standard error, shrinks on the larger of it and the sandwich (module docs)
    independent = np.sqrt(2.0 * np.diag(inverse))
    robust = np.maximum(independent, np.sqrt(np.maximum(np.diag(inverse @ state.dispersion @ inverse), 0.0)))
    before = np.array([state.odometry_scale, state.sensor_scale])
    scales = before.copy()
    for i in range(2):
        # before the statistics span their memory they say too little (a 2000-pose grid declared right moved both
        # scales by 4% in its first 40 updates), and a variance estimate below zero says only that it is uncertain
        if state.updates < config.memory or estimate[i] <= 0.0 or not moves[i]:
            continue
        rises = estimate[i] > 1.0
        if not rises and i == 1 and estimate[0] - 1.0 > config.threshold * independent[0]:
            continue  # while the predicted part is too small, the split between the parts is not to be trusted
        if abs(estimate[i] - 1.0) > config.threshold * (independent[i] if rises else robust[i]):
            floor = 1.0 if i == 0 or state.widened else config.sensor_floor
            scales[i] = min(config.max_scale, max(floor, scales[i] * math.exp(config.gain * math.log(estimate[i]))))
    _carry(state, inverse, estimate, before, scales)
    return max(1.0, state.odometry_scale / float(before[0]))


def _inverse(info: Array) -> Array | None:
    """The inverse of a 2x2 information ``F``; None while one part is not seen yet (nothing to say of it)."""
    a, b, d = info[0, 0], info[0, 1], info[1, 1]
    det = a * d - b * b
    if a <= 0.0 or d <= 0.0 or det <= 1e-12 * (a + d) ** 2:
        return None
    return np.array([[d, -b], [-b, a]]) / det


def _carry(state: Adaptation, inverse: Array, estimate: Array, before: Array, after: Array) -> None:
    """Set the scales to ``after`` (in place), the remembered statistics with them: they were judged under the scales
    ``before``, so what they say of the new ones is their ``estimate`` over the change (without this the scales wind
    up past the truth while the memory lags)."""
    info = state.information
    now = estimate * before / after
    state.quadratic = info @ now
    if (after != before).any():  # the scores' dispersion in the new units: theta' = D theta, so Omega' = M Omega M^T
        M = info @ np.diag(before / after) @ inverse
        state.dispersion = M @ state.dispersion @ M.T
        state.recent = M @ state.recent
    state.odometry_scale, state.sensor_scale = float(after[0]), float(after[1])
    if state.updates >= WORKING_AFTER:
        state.working = np.clip(now, *WORKING_RANGE)


def update_adaptation(
    state: Adaptation, S: Array, R: Array, y: Array, config: AdaptationConfig, own: Array | None = None
) -> float:
    """Fold an EKF update in: innovations y (a, 2) with covariance S (2a, 2a), R (a, 2, 2) of it the sightings';
    ``own`` (a, 2, 2): the sightings' own covariances where R is widened (:meth:`Step.z_own_cov`; None: R).
    Returns the factor the odometry scale rose by (:func:`adapt`)."""
    B, y = _block_diagonal(R), y.reshape(-1)
    declared = innovation_statistics(y, S - B, B, state.working)
    if own is None or np.array_equal(own, R):
        return fold(state, declared, None, config)
    return fold(
        state, declared, innovation_statistics(y, S - B, _block_diagonal(own), own_statistics(state).working), config
    )


def fold(
    state: Adaptation,
    declared: tuple[Array, Array],
    own: tuple[Array, Array] | None,
    config: AdaptationConfig,
) -> float:
    """Fold one update's statistics ``(F, q)`` in: read against the sightings' covariances as declared, and against
    their own where they are widened (None: not). Returns the factor the odometry scale rose by (:func:`adapt`)."""
    if own is None and state.own is None:
        return adapt(state, *declared, config)
    rise = adapt(state, *declared, config, moves=(True, own is None and state.own is None))
    if own is not None:
        sightings = own_statistics(state)
        sightings.widened = state.widened
        adapt(sightings, *own, config, moves=(False, True))
        _rescale(state, state.odometry_scale, sightings.sensor_scale)
    if state.own is not None:
        _rescale(state.own, state.odometry_scale, state.sensor_scale)
    return rise


def own_statistics(state: Adaptation) -> Adaptation:
    """The statistics read against widened sightings' own covariances (made at the scales so far)."""
    if state.own is None:
        state.own = Adaptation(state.odometry_scale, state.sensor_scale, widened=state.widened)
    return state.own


def _rescale(state: Adaptation, odometry: float, sensor: float) -> None:
    """Set the scales (in place), the remembered statistics taken to them as :func:`adapt` takes them."""
    before, after = np.array([state.odometry_scale, state.sensor_scale]), np.array([odometry, sensor])
    if (before == after).all():
        return
    if (inverse := _inverse(state.information)) is None:
        state.odometry_scale, state.sensor_scale = odometry, sensor
        return
    _carry(state, inverse, inverse @ state.quadratic, before, after)


def _block_diagonal(R: Array) -> Array:
    """``blockdiag(R)`` of k 2x2 blocks ``R`` (k, 2, 2), shape (2k, 2k)."""
    k = len(R)
    B = np.zeros((2 * k, 2 * k))
    B.reshape(k, 2, k, 2)[np.arange(k), :, np.arange(k), :] = R
    return B


def sighting_statistics(
    pose: Array,
    landmarks: Array,
    z: Array,
    R: Array,
    model: NDArray[np.int8],
    joint: Array,
    gate: float,
    working: Array,
    own: Array | None = None,
) -> tuple[Array, Array]:
    """``(F, q)`` of k sightings ``z`` (k, 2) with covariances ``R`` (k, 2, 2) of ``landmarks`` (k, 2) from the
    predicted ``pose`` (3,), ``joint`` the covariance (3 + 2k, 3 + 2k) of the pose and those landmarks (in that
    order, one block per sighting), taken at ``working`` (2,); with ``own`` (k, 2, 2), the sightings' own
    covariances where R is widened, read against those instead. Sightings whose NIS (against R) exceeds ``gate``
    are left out (outliers)."""
    z_hat, J_p, J_l = predict_with_jacobians(pose, landmarks, model)
    y = wrap_bearings(z - z_hat, model)
    H = stacked_jacobian(J_p, J_l)
    A = H @ joint @ H.T
    k = len(z)
    blocks = A.reshape(k, 2, k, 2)[np.arange(k), :, np.arange(k), :] + R
    try:
        nis = np.einsum("ki,ki->k", y, np.linalg.solve(blocks, y[..., None])[..., 0])
    except np.linalg.LinAlgError:
        return np.zeros((2, 2)), np.zeros(2)
    keep = np.repeat(nis <= gate, 2)
    if not keep.any():
        return np.zeros((2, 2)), np.zeros(2)
    B = _block_diagonal(R if own is None else own)
    return innovation_statistics(y.reshape(-1)[keep], A[np.ix_(keep, keep)], B[np.ix_(keep, keep)], working)


def fold_sightings(
    state: Adaptation,
    pose: Array,
    landmarks: Array,
    z: Array,
    R: Array,
    own: Array,
    model: NDArray[np.int8],
    joint: Array,
    config: AdaptationConfig,
) -> float:
    """:func:`fold` the statistics of k sightings (:func:`sighting_statistics`; ``own`` (k, 2, 2) their own
    covariances, equal to R where nothing is widened). Returns the factor the odometry scale rose by."""
    declared = sighting_statistics(pose, landmarks, z, R, model, joint, GATE, state.working)
    if np.array_equal(own, R):
        return fold(state, declared, None, config)
    working = own_statistics(state).working
    return fold(state, declared, sighting_statistics(pose, landmarks, z, R, model, joint, GATE, working, own), config)


def entering(step: Step, state: Adaptation) -> Step:
    """A step as an estimator takes it: its sightings' declaration noted (:attr:`Adaptation.widened`), its odometry
    and sightings' covariances times the adapted scales (the step itself while both are 1: always, when not
    adapting)."""
    state.widened = step.z_widened
    if state.odometry_scale == 1.0 and state.sensor_scale == 1.0:
        return step
    odometry_cov = None if step.odometry_cov is None else step.odometry_cov * state.odometry_scale
    return replace(step, odometry_cov=odometry_cov, z_cov=step.z_cov * state.sensor_scale)


def adapted_info(state: Adaptation, config: AdaptationConfig) -> dict[str, tuple[float, float]]:
    """The final estimate's report entry: ``adapted_noise`` (odometry scale, sensor scale) when adapting."""
    return {"adapted_noise": (state.odometry_scale, state.sensor_scale)} if config.enabled else {}
