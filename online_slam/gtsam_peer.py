"""GTSAM as a peer: the same factor graph, solved by GTSAM's Levenberg-Marquardt.

Two modes:

- ``exact=False`` uses GTSAM's native factors (``BetweenFactorPose2``, ``BearingRangeFactor2D``). Its odometry
  error is ``Logmap(delta^-1 * between(a, b))``, which differs from the article's ``between(a, b) - delta`` at
  second order, so its optimum differs slightly; this is the fast configuration, used for timing.
- ``exact=True`` models odometry and priors with ``CustomFactor`` computing our residual (Jacobians mapped to
  GTSAM's tangent space), and keeps the native bearing-range factor (its error equals ours), so both solvers
  minimise the same cost: used to cross-check solutions.

Position sightings (the landmark in the robot frame) have no native 2D factor in GTSAM's Python wrapper: both
modes model them with a ``CustomFactor`` computing our residual.
A sighting of one robot by another (several robots) is GTSAM's ``BearingRangeFactorPose2`` between the two
poses in both modes: bearing and range to the seen pose's position, as ours.

Absolute fixes (``position`` and ``heading`` lines) are not modelled: a graph or a step with one is refused with an
:class:`~online_slam.errors.OnlineSlamError` (no peer figure rather than one of another problem).

GTSAM is the optional ``peers`` extra: the package imports this module only where a peer is asked for
(``compare --peer isam2``); the cross-check tests and the benchmarks use it too.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from online_slam.errors import OnlineSlamError
from online_slam.factors.fixes import fix_rows
from online_slam.factors.graph import FactorGraph
from online_slam.geometry.angles import wrap
from online_slam.models.motion import odometry_residual_with_jacobians
from online_slam.models.observation import (
    POSITION,
    landmark_from_sighting,
    predict_with_jacobians,
    split_models,
    wrap_bearings,
)
from online_slam.models.position import position_with_jacobians

try:  # pragma: no cover - depends on the optional extra
    import gtsam
    from gtsam.symbol_shorthand import L, X
except ImportError:  # pragma: no cover
    gtsam = None  # type: ignore[assignment, unused-ignore]  # None marks the extra absent (then no error to ignore)

Array = NDArray[np.float64]
FIXED_SIGMA = 1e-9
"""Standard deviation of the tight prior that stands in for a fixed pose in GTSAM."""
NO_FIXES = "the GTSAM peer does not model absolute fixes (position, heading lines): compare without --peer"
"""The refusal of a stream with absolute fixes."""


def available() -> bool:
    """True when gtsam can be imported."""
    return gtsam is not None


def _covariances(W: Array) -> Array:
    info = np.swapaxes(W, -1, -2) @ W
    return cast(Array, np.linalg.inv(info))  # float64 in, float64 out (numpy's stubs say some float)


def _tangent(theta: float) -> Array:
    """d(world [x, y, theta]) / d(GTSAM local tangent) at a Pose2 with heading theta."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def between_covariance(delta: Array, cov: Array) -> Array:
    """Our odometry covariance (of ``between(a, b) - delta``, in the earlier pose's axes) as GTSAM's between factor
    takes it (of ``Log(delta^-1 between(a, b))``, in the axes of the pose reached): to first order
    ``between - delta = J xi`` with ``J = diag(R(delta_theta), 1)``, so ``cov_xi = J^T cov J``.

    Without this, an increment with a large turn (MRCLAM after a long blind stretch) gets its forward and lateral
    variances swapped in GTSAM.
    """
    J = _tangent(float(delta[2]))
    return J.T @ np.asarray(cov, dtype=float) @ J


def _vec(p: gtsam.Pose2) -> Array:
    return np.array([p.x(), p.y(), p.theta()])


def _odometry_factor(key_a: int, key_b: int, delta: Array, cov: Array) -> gtsam.CustomFactor:
    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list | None) -> Array:
        a, b = values.atPose2(this.keys()[0]), values.atPose2(this.keys()[1])
        e, J_a, J_b = odometry_residual_with_jacobians(_vec(a), _vec(b), delta)
        if H is not None:
            H[0] = J_a @ _tangent(a.theta())
            H[1] = J_b @ _tangent(b.theta())
        return e

    return gtsam.CustomFactor(gtsam.noiseModel.Gaussian.Covariance(cov), [key_a, key_b], error)


def _prior_factor(key: int, mean: Array, cov: Array) -> gtsam.CustomFactor:
    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list | None) -> Array:
        p = values.atPose2(this.keys()[0])
        e = _vec(p) - mean
        e[2] = wrap(e[2])
        if H is not None:
            H[0] = _tangent(p.theta())
        return e

    return gtsam.CustomFactor(gtsam.noiseModel.Gaussian.Covariance(cov), [key], error)


def _position_factor(key_p: int, key_l: int, z: Array, noise: gtsam.noiseModel.Base) -> gtsam.CustomFactor:
    """A position sighting ``z`` (the landmark in the robot frame) with its noise model, as our residual."""

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list | None) -> Array:
        p, point = values.atPose2(this.keys()[0]), values.atPoint2(this.keys()[1])
        z_hat, J_p, J_l = position_with_jacobians(_vec(p), np.asarray(point, dtype=float))
        if H is not None:
            H[0] = J_p @ _tangent(p.theta())
            H[1] = J_l
        return z_hat - z

    return gtsam.CustomFactor(noise, [key_p, key_l], error)


def _mounted_factor(key_p: int, key_l: int, z: Array, model: Any, noise: gtsam.noiseModel.Base) -> gtsam.CustomFactor:
    """A sighting from a mounted sensor (``model`` a :data:`~online_slam.models.observation.SIGHTING` record) with
    its noise model, as our residual (the model's order: range, bearing)."""

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list | None) -> Array:
        p, point = values.atPose2(this.keys()[0]), values.atPoint2(this.keys()[1])
        z_hat, J_p, J_l = predict_with_jacobians(_vec(p), np.asarray(point, dtype=float), model)
        if H is not None:
            H[0] = J_p @ _tangent(p.theta())
            H[1] = J_l
        return wrap_bearings(z_hat - z, model)

    return gtsam.CustomFactor(noise, [key_p, key_l], error)


def _sighting_noise(cov: Array, model: Any) -> gtsam.noiseModel.Base:
    """The Gaussian noise model of a sighting's covariance, in the order its GTSAM factor takes (a bearing-range
    factor orders (bearing, range); a mounted sighting's factor is ours, in our order)."""
    tag, mount = split_models(model)
    native = mount is None and int(tag) != POSITION
    cov = np.asarray(cov)[::-1, ::-1] if native else np.asarray(cov)
    return gtsam.noiseModel.Gaussian.Covariance(np.ascontiguousarray(cov))


def _sighting_factor(
    key_p: int, key_l: int, z: Array, model: Any, noise: gtsam.noiseModel.Base
) -> gtsam.NonlinearFactor:
    """Our sighting as a GTSAM factor: native bearing-range, a position factor, or from a mounted sensor our own
    (noise from :func:`_sighting_noise`, possibly made robust)."""
    tag, mount = split_models(model)
    if mount is not None:
        return _mounted_factor(key_p, key_l, z, model, noise)
    model = int(tag)
    if model == POSITION:
        return _position_factor(key_p, key_l, z, noise)
    return gtsam.BearingRangeFactor2D(key_p, key_l, gtsam.Rot2(z[1]), z[0], noise)


def to_gtsam(graph: FactorGraph, poses: Array, landmarks: Array, exact: bool = False) -> tuple:
    """Build GTSAM's factor graph and initial values from ours.

    Args:
        graph: Our factor graph.
        poses: Initial poses, shape (n_poses, 3).
        landmarks: Initial landmarks, shape (n_landmarks, 2).
        exact: Use custom factors that reproduce our cost exactly (see module docstring).

    Returns:
        (gtsam.NonlinearFactorGraph, gtsam.Values).
    """
    if gtsam is None:
        raise ImportError("gtsam is not installed: pip install '.[peers]'")
    if fix_rows(graph).any():
        raise OnlineSlamError(NO_FIXES)
    fg = gtsam.NonlinearFactorGraph()
    for i in graph.fixed_poses:
        fg.add(
            gtsam.PriorFactorPose2(X(int(i)), gtsam.Pose2(*poses[i]), gtsam.noiseModel.Isotropic.Sigma(3, FIXED_SIGMA))
        )
    for i, mean, cov in zip(graph.prior_pose, graph.prior_mean, _covariances(graph.prior_sqrt_info)):
        if exact:
            fg.add(_prior_factor(X(int(i)), mean, cov))
        else:
            fg.add(gtsam.PriorFactorPose2(X(int(i)), gtsam.Pose2(*mean), gtsam.noiseModel.Gaussian.Covariance(cov)))
    odo_cov = _covariances(graph.odo_sqrt_info)
    for a, b, delta, cov in zip(graph.odo_from, graph.odo_to, graph.odo_delta, odo_cov):
        if exact:
            fg.add(_odometry_factor(X(int(a)), X(int(b)), delta, cov))
        else:
            noise = gtsam.noiseModel.Gaussian.Covariance(between_covariance(delta, cov))
            fg.add(gtsam.BetweenFactorPose2(X(int(a)), X(int(b)), gtsam.Pose2(*delta), noise))
    obs_cov = _covariances(graph.obs_sqrt_info)
    for p, l, z, cov, model in zip(graph.obs_pose, graph.obs_landmark, graph.obs_z, obs_cov, graph.obs_model):
        fg.add(_sighting_factor(X(int(p)), L(int(l)), z, model, _sighting_noise(cov, model)))
    rob_cov: Array | list[Array] = _covariances(graph.rob_sqrt_info)[:, ::-1, ::-1] if len(graph.rob_from) else []
    for a, b, z, cov in zip(graph.rob_from, graph.rob_to, graph.rob_z, rob_cov):
        noise = gtsam.noiseModel.Gaussian.Covariance(np.ascontiguousarray(cov))
        fg.add(gtsam.BearingRangeFactorPose2(X(int(a)), X(int(b)), gtsam.Rot2(z[1]), z[0], noise))
    values = gtsam.Values()
    for i, pose in enumerate(poses):
        values.insert(X(i), gtsam.Pose2(*pose))
    for j, point in enumerate(landmarks):
        values.insert(L(j), gtsam.Point2(*point))
    return fg, values


@dataclass(frozen=True)
class PeerSolution:
    """GTSAM's answer."""

    poses: Array
    """Poses, shape (n_poses, 3)."""
    landmarks: Array
    """Landmarks, shape (n_landmarks, 2)."""
    iterations: int
    """LM iterations."""
    final_cost: float
    """``graph.error`` at the solution (0.5 * chi-square)."""
    solve_s: float
    """Wall time of ``optimize()`` alone, seconds."""


def levenberg_marquardt(
    graph: FactorGraph, poses: Array, landmarks: Array, *, exact: bool = False, tight: bool = False
) -> PeerSolution:
    """Solve with GTSAM's Levenberg-Marquardt from the given initial values.

    Args:
        graph: Our factor graph.
        poses: Initial poses, shape (n_poses, 3).
        landmarks: Initial landmarks, shape (n_landmarks, 2).
        exact: Reproduce our cost exactly (custom factors) instead of GTSAM's native factors.
        tight: Iterate to convergence (relative decrease 1e-10, absolute 1e-15) instead of GTSAM's defaults. A
            tighter relative tolerance adds no digits, only a last iteration in which LM raises lambda ten
            times at the minimum before giving up (time, not accuracy).

    Returns:
        GTSAM's solution and timing.
    """
    fg, values = to_gtsam(graph, poses, landmarks, exact=exact)
    params = gtsam.LevenbergMarquardtParams()
    if tight:
        params.setRelativeErrorTol(1e-10)
        params.setAbsoluteErrorTol(1e-15)
        params.setMaxIterations(200)
    started = time.perf_counter()
    optimizer = gtsam.LevenbergMarquardtOptimizer(fg, values, params)
    result = optimizer.optimize()
    elapsed = time.perf_counter() - started
    out_poses = np.array([_vec(result.atPose2(X(i))) for i in range(graph.n_poses)])
    out_landmarks = np.array([result.atPoint2(L(j)) for j in range(graph.n_landmarks)]).reshape(-1, 2)
    return PeerSolution(out_poses, out_landmarks, optimizer.iterations(), fg.error(result), elapsed)


@dataclass(frozen=True)
class PeerOnline:
    """iSAM2's online run: the latest pose after each step, and per-step wall times."""

    poses: Array
    """Latest pose as estimated right after each step, shape (N, 3)."""
    final_poses: Array
    """All poses at the end of the run, shape (N, 3)."""
    step_s: Array
    """Wall time of each step's update plus reading the latest pose, shape (N,)."""
    covariances: Array | None = None
    """Marginal covariance of the latest pose after each step, in our axes (x, y, theta), shape (N, 3, 3); None
    unless asked for (its time is not in ``step_s``)."""


def isam2_online(
    steps: list,
    relinearize_threshold: float = 0.01,
    relinearize_skip: int = 1,
    cauchy: float | None = None,
    huber: float | None = None,
    covariances: bool = False,
    qr: bool = False,
) -> PeerOnline:
    """Run GTSAM's iSAM2 step by step (one update per step, reading the latest pose), native factors.

    New poses start from the latest estimate composed with the odometry; new landmarks from their first
    observation. The start pose gets a tight prior when fixed (as in :func:`to_gtsam`).

    Args:
        steps: Front-end steps in order.
        relinearize_threshold: iSAM2's relinearization threshold.
        relinearize_skip: Relinearize every this many updates.
        cauchy: Put a Cauchy kernel of this width (sigmas) on the observation factors (None: Gaussian).
        huber: Or a Huber kernel of this width.
        covariances: Also read the latest pose's ``marginalCovariance`` after each step.
        qr: Factorize by QR instead of Cholesky: slower, but it takes information over many orders of magnitude
            (the circle world's lateral odometry sigma of 1e-6 m, beside the fixed start's 1e-9, on which
            Cholesky reports an indeterminate system).

    Returns:
        Online poses, final poses, per-step times (and covariances).
    """
    if gtsam is None:
        raise ImportError("gtsam is not installed: pip install '.[peers]'")
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(relinearize_threshold)
    params.relinearizeSkip = relinearize_skip
    if qr:
        params.setFactorization("QR")
    isam = gtsam.ISAM2(params)
    seen: set = set()
    index: dict = {}
    latest = np.zeros(3)
    online, times, covs = [], [], []
    for step in steps:
        if step.fixes:
            raise OnlineSlamError(NO_FIXES)
        started = time.perf_counter()
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        i = step.index
        if step.odometry is None:
            latest = np.array(step.prior, dtype=float)
            cov = step.prior_cov
            noise: gtsam.noiseModel.Base = (
                gtsam.noiseModel.Isotropic.Sigma(3, FIXED_SIGMA)
                if cov is None
                else gtsam.noiseModel.Gaussian.Covariance(np.asarray(cov))
            )
            graph.add(gtsam.PriorFactorPose2(X(i), gtsam.Pose2(*latest), noise))
        else:
            noise = gtsam.noiseModel.Gaussian.Covariance(between_covariance(step.odometry, step.odometry_cov))
            graph.add(gtsam.BetweenFactorPose2(X(i - 1), X(i), gtsam.Pose2(*step.odometry), noise))
            c, s = np.cos(latest[2]), np.sin(latest[2])
            d = step.odometry
            latest = np.array([latest[0] + c * d[0] - s * d[1], latest[1] + s * d[0] + c * d[1], latest[2] + d[2]])
        values.insert(X(i), gtsam.Pose2(*latest))
        for lid, z, cov, model in zip(step.landmarks, step.z, step.z_cov, step.z_model):
            if lid not in index:
                index[lid] = len(index)
            key = L(index[lid])
            if lid not in seen:
                seen.add(lid)
                values.insert(key, gtsam.Point2(*landmark_from_sighting(latest, z, model)))
            noise = _sighting_noise(cov, model)
            if cauchy is not None:
                noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(cauchy), noise)
            elif huber is not None:
                noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(huber), noise)
            graph.add(_sighting_factor(X(i), key, z, model, noise))
        isam.update(graph, values)
        latest = _vec(isam.calculateEstimatePose2(X(i)))
        times.append(time.perf_counter() - started)
        online.append(latest)
        if covariances:  # GTSAM's is of the pose's local tangent: rotate its position block into world axes
            T = _tangent(latest[2])
            covs.append(T @ isam.marginalCovariance(X(i)) @ T.T)
    estimate = isam.calculateEstimate()
    final = np.array([_vec(estimate.atPose2(X(s.index))) for s in steps])
    return PeerOnline(np.array(online), final, np.array(times), np.array(covs) if covariances else None)
