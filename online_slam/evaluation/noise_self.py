"""Calibrating a stream's noise from its own data, without truth (``--noise self``).

A real robot has no truth to fit its noise to (:mod:`~online_slam.evaluation.noise_fit` needs it). But the batch
solution's residuals tell how far the data disagree with each other, and how far each kind of measurement may
disagree is what its covariance says. Maximum likelihood over the scales of the covariances is variance-component
estimation (Helmert; Forstner 1979), iterated:

1. Solve the batch problem (every pose, landmark and factor: the batch solver's graph and Levenberg-Marquardt)
   with the covariances scaled by the current estimates: the odometry's by ``s_o``, every sighting's (landmarks
   and robots) by ``s_z``, exactly as ``--odometry-noise-scale`` and ``--sensor-noise-scale`` would.
2. For each group, its weighted residual square sum over its redundancy (its share of the degrees of freedom,
   ``m_g - tr(N^-1 N_g)``: :mod:`online_slam.solvers.redundancy`) is the factor its scale is off by.
3. Repeat until the scales settle (a relative change under ``tolerance``). The fixed point is the maximum
   likelihood (REML) estimate of both scales; started at the declared covariances, it needs 5-20 solves.

Each sensor's range and bearing bias (a sensor: a sighting's ``sensor`` name, None for the robot's centre; only
range-bearing landmark sightings) is a parameter of the same solve: a Gauss-Newton step on ``[poses, landmarks,
biases]`` at each solution (the biases' columns beside the batch's Jacobian), iterated with the scales. The
biases' parameters take their share of the sightings' redundancy. A bias is applied only where it is beyond noise
(``bias_false_alarm``): taken off the sightings, an estimate's noise would be a bias of its own.

Outliers (a sighting carrying another landmark's id) are left out of the solve and the estimate when their squared
whitened residual, under the current scale, exceeds the chi-square quantile at ``gate_probability``; every
sighting is judged again at each solve, by its residual standardized with the sightings' mean leverage (see
:func:`_kept`), until the kept set comes back to one it was two or more solves before (sightings on the gate's edge
taking turns): from then on that set stays. The first solve (from an estimator's estimate, when given) has a Cauchy
loss and a robust (median) scale for the first gate, so that a few outliers cannot set the start. The sightings'
scale is divided by the share of a chi-square's mean that the gate keeps (``P(chi2_4 < gate)``), which the gate
would otherwise take off inliers.

Only sightings with a landmark id are used: associating sightings without one depends on the very covariances
being fitted (every gate is drawn with them), so a fit on such associations would check itself. A stream with no
sighting with an id is refused.

A source whose sightings are widened for the correlation of repeated sightings (header ``sightings_correlated``)
gets its sensor scale and biases measured and shown, not applied: the fit sees each sighting as independent and takes
the widening for an overstatement (MRCLAM reads 0.007-0.023). Where the lines also say by how much each was widened
(``widened``: :meth:`~online_slam.frontend.pose.Step.z_own_cov`), :func:`own_sensor_scale` fits the scale again
against the sightings' own covariances. The errors the landmarks' positions absorb (those alike over a landmark's
sightings) lower that reading, by as much as the source's errors are alike, which the data alone cannot tell (MRCLAM
declared right: 0.197-0.509). A source that declares the range its streams declared right read (header
``sightings_own_scale``: range and spread; MRCLAM 0.197-0.509 and 1.6) gets a reading beyond the range and its spread
applied over the range's low end (MRCLAM declared 0.3x reads 2.1-5.6, 3x 0.022-0.056), and nothing within. The low
end: a stream read against the lowest is rescaled least too sure (none on Dataset 6) and at most high / low (2.6x)
too unsure. Without a declared range, a reading above 1 is applied (a lower bound of the factor the sensor is off
by), and nothing below.

What it cannot see: errors correlated in time (a slip that lasts, one landmark's errors alike for a while) look to
it like independent ones, and a component of a covariance off against the others (range against bearing) is
scaled with them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.stats import chi2, norm

from online_slam.errors import OnlineSlamError
from online_slam.estimators.batch import median_landmarks
from online_slam.estimators.problem import ProblemLog
from online_slam.estimators.protocol import Estimate
from online_slam.factors.graph import FactorGraph, evaluate, layout, linearize, subgraph
from online_slam.factors.robust import RobustLoss
from online_slam.frontend.noise import SensorBias
from online_slam.frontend.steps import Step
from online_slam.models.observation import RANGE_BEARING, split_models, wrap_bearings
from online_slam.solvers.config import SolverConfig
from online_slam.solvers.least_squares import retract, solve
from online_slam.solvers.redundancy import SingularMatrix, gauss_newton, group_traces

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class SelfFitConfig:
    """Settings of the self-calibration."""

    gate_probability: float = 0.999
    """A sighting whose squared whitened residual, under the current scale, exceeds the chi-square quantile (2 dof)
    at this probability is left out of the solve and the estimate."""
    max_iterations: int = 50
    """Most solves."""
    tolerance: float = 1e-4
    """The iterations stop when no scale changes by more than this fraction and no bias by more than this many
    of its standard deviations."""
    min_sightings: int = 20
    """A sensor with fewer range-bearing landmark sightings gets no bias."""
    bias_false_alarm: float = 1e-3
    """A bias is applied only where it is this unlikely (two-sided) to be noise: beyond 3.3 standard deviations by
    default. An estimate's noise taken off the sightings would be a bias of its own: a bearing bias of the robot's
    centre is a heading offset, and a few thousandths of a radian already move the estimated headings by more than
    their sigma."""
    min_range_sigmas: float = 3.0
    """A range-bearing sighting (of a landmark or a robot) measured closer than this many range sigmas (under the
    current scale) is left out: a landmark on the pose explains its bearing, where the model's Jacobian grows
    without bound, and the solution can collapse there (the normal matrix then is singular)."""
    min_redundancy: float = 5.0
    """A group with less redundancy than this keeps its declared covariances (scale 1): the data cannot tell."""
    initial_loss: RobustLoss = field(default_factory=lambda: RobustLoss("cauchy", 3.0))
    """Loss on sightings of the first solve (the batch's robust pass), before any sighting is judged."""
    solver: SolverConfig = field(default_factory=SolverConfig)
    """Settings of each batch solve."""


@dataclass(frozen=True)
class BiasFit:
    """One sensor's bias: what its range-bearing sightings read beyond the solution's range and bearing."""

    sensor: str | None
    """The sensor's name; None: the robot's centre."""
    sightings: int
    """Its range-bearing landmark sightings used."""
    range_m: float
    """Range bias, metres (measured minus solved)."""
    bearing_rad: float
    """Bearing bias, radians."""
    range_sd: float
    """Standard deviation of the range bias, metres."""
    bearing_sd: float
    """Standard deviation of the bearing bias, radians."""
    significant: tuple[bool, bool]
    """Whether the range and the bearing bias are beyond noise (``bias_false_alarm``): those are taken off the
    sightings (unless the source's sightings are correlated: :attr:`SelfFit.sightings_correlated`)."""


@dataclass(frozen=True)
class SelfFit:
    """A stream's noise calibrated from its own data: the scales of its covariances and its sensors' biases."""

    increments: int
    """Odometry increments."""
    sightings: int
    """Landmark sightings with an id (the others are not used)."""
    without_id: int
    """Landmark sightings without an id, left out."""
    robot_sightings: int
    """Sightings of robots (in the sensor group, without bias)."""
    gated: int
    """Sightings (of landmarks and robots) left out by the gate at the last solve."""
    close: int
    """Range-bearing sightings left out as measured within ``min_range_sigmas`` of the sensor."""
    odometry_scale: float
    """Maximum-likelihood scale of the odometry covariances (1 when the odometry's redundancy is too small)."""
    sensor_scale: float
    """Maximum-likelihood scale of the sighting covariances (1 when their redundancy is too small)."""
    odometry_redundancy: float
    """The odometry's share of the degrees of freedom, of ``3 x increments`` residuals."""
    sensor_redundancy: float
    """The kept sightings' share, of 2 residuals each."""
    biases: tuple[BiasFit, ...]
    """Each sensor's bias (sensors with at least ``min_sightings`` range-bearing sightings)."""
    iterations: int
    """Solves made."""
    converged: bool
    """The scales and biases settled within the tolerance."""
    sightings_correlated: bool = False
    """The source declares (header ``sightings_correlated``) that its sighting sigmas allow for the correlation of
    repeated sightings: the sensor scale and the biases are measured and shown, not applied. The fit sees each
    sighting as independent: it takes the widening for an overstatement, and a landmark's errors that stay alike for
    a while for a bias; applied on MRCLAM, both made every estimator overconfident (docs/commands.md)."""
    own_sensor_scale: float | None = None
    """For correlated sightings whose lines say their widening: the sensor scale fitted against their own
    covariances (:func:`own_sensor_scale`); None: not fitted."""
    own_range: tuple[float, float, float] | None = None
    """The source's ``(low, high, spread)`` (header ``sightings_own_scale``): the lowest and highest
    :attr:`own_sensor_scale` its streams declared right read, and the factor beyond them within which a reading
    still says nothing. None: not declared; a reading then counts only above 1, as a lower bound."""

    @property
    def applied_sensor_scale(self) -> float:
        """The sensor scale a replay applies: :attr:`sensor_scale`; for correlated sightings, their own reading over
        the low end of the declared range where beyond the range and its spread (else 1); without a declared range,
        the reading where above 1 (else 1). See the module's docstring."""
        if not self.sightings_correlated:
            return self.sensor_scale
        own = self.own_sensor_scale
        if own is None:
            return 1.0
        if self.own_range is None:
            return max(1.0, own)
        return own / self.own_range[0] if _beyond(own, self.own_range) else 1.0

    @property
    def sensor_bias(self) -> tuple[SensorBias, ...]:
        """The biases applied, as the front-end takes them (``FrontEndConfig.sensor_bias``; 0 for one not applied;
        none for correlated sightings)."""
        if self.sightings_correlated:
            return ()
        return tuple(
            (b.sensor, b.range_m if b.significant[0] else 0.0, b.bearing_rad if b.significant[1] else 0.0)
            for b in self.biases
            if any(b.significant)
        )

    def flags(self) -> str:
        """The options that replay with these scales (the biases have none: see ``FrontEndConfig.sensor_bias``)."""
        return f"--odometry-noise-scale {self.odometry_scale:.4g} --sensor-noise-scale {self.applied_sensor_scale:.4g}"


@dataclass(frozen=True)
class _Data:
    """The problem as the stream declares it: every factor, the sightings' sensors, initial values."""

    graph: FactorGraph
    """Every factor, with the declared covariances and the measured z (every landmark sighting with an id)."""
    poses: Array
    """Initial poses (an estimator's, or composed odometry), shape (n_poses, 3)."""
    landmarks: Array
    """Initial landmarks (an estimator's, else each at the median of its sightings), shape (M, 2)."""
    sensor_of: NDArray[np.int64]
    """Each sighting's sensor, an index into ``sensors`` (-1: no bias: a position sighting, or too few), shape (L,)."""
    sensors: tuple[str | None, ...]
    """The sensors given a bias."""
    reach: Array
    """Each sighting's measured range over its declared range sigma, landmark sightings then robot sightings (inf
    for a position sighting), shape (L + R,)."""
    without_id: int
    """Landmark sightings without an id."""


@dataclass(frozen=True)
class _State:
    """Where the iterations are: scales, biases, which sightings are kept, the solution."""

    scales: tuple[float, float]
    """(odometry, sensor)."""
    biases: Array
    """Each bias-fitted sensor's (range, bearing) bias, shape (S, 2)."""
    kept: Mask
    """Landmark sightings inside the gate, shape (L,)."""
    kept_robots: Mask
    """Robot sightings inside the gate, shape (R,)."""
    poses: Array
    """The solution's poses, shape (n_poses, 3)."""
    landmarks: Array
    """The solution's landmarks, shape (M, 2)."""
    redundancy: tuple[float, float] = (0.0, 0.0)
    """(odometry, sensor) redundancy at the last solve."""
    bias_sd: Array = field(default_factory=lambda: np.zeros((0, 2)))
    """Standard deviations of the biases, shape (S, 2)."""


def fit_self(steps: Iterable[Step], config: SelfFitConfig | None = None, initial: Estimate | None = None) -> SelfFit:
    """Calibrate a stream's covariance scales and sensor biases from its own data (see the module's docstring).

    Args:
        steps: The stream's steps (a front-end's, every scale at 1 and no bias), in order; consumed.
        config: Settings.
        initial: Where the first solve starts: an estimator's final estimate of the same steps (every pose; its
            landmarks by id, the others placed at the median of their sightings). None: composed odometry, from
            which Levenberg-Marquardt can stop in a poor minimum (the circle worlds: use an EKF's estimate).

    Raises:
        OnlineSlamError: The stream has no landmark sighting with an id; the solution's normal matrix is singular.
        ValueError: An initial estimate of another number of poses.
    """
    cfg = config or SelfFitConfig()
    data = _data(steps, cfg.min_sightings, initial)
    gate = float(chi2.isf(1.0 - cfg.gate_probability, 2))
    state = _start(data, cfg, gate)
    converged, iterations, judged = False, 0, [_key(state)]
    while not converged and iterations < cfg.max_iterations:
        iterations += 1
        try:
            state, change = _iterate(data, state, cfg, gate, judge=bool(judged))
        except SingularMatrix as exc:
            raise OnlineSlamError(f"--noise self: at solve {iterations}, {exc}") from None
        converged = bool(change < cfg.tolerance)
        key = _key(state)
        if judged and key != judged[-1]:
            judged = [] if key in judged else [*judged, key]  # back to an earlier set: it cycles; judge no more
    close = int(np.sum(data.reach <= cfg.min_range_sigmas * math.sqrt(state.scales[1])))
    return _result(data, state, iterations, converged, float(norm.isf(cfg.bias_false_alarm / 2.0)), close)


def own_sensor_scale(
    steps: Iterable[Step], config: SelfFitConfig | None = None, initial: Estimate | None = None
) -> float | None:
    """The sensor scale :func:`fit_self` reads with each sighting's covariance divided by its widening (its own,
    :meth:`~online_slam.frontend.pose.Step.z_own_cov`); None when no sighting says it was widened. Arguments as
    :func:`fit_self`'s."""
    steps = list(steps)
    if all((step.z_widening == 1.0).all() for step in steps):
        return None
    own = [dataclasses.replace(s, z_cov=s.z_own_cov(), z_widening=np.ones_like(s.z_widening)) for s in steps]
    return fit_self(own, config, initial).sensor_scale


def _data(steps: Iterable[Step], min_sightings: int, initial: Estimate | None) -> _Data:
    """The problem the steps make (the batch's log), with each sighting's sensor and initial values."""
    log = ProblemLog()
    names: list[str | None] = []
    for step in steps:
        log.add(step)
        names.extend(step.sensors or (None,) * len(step.landmarks))
    with_id = log.sightings()[1] >= 0
    if not with_id.any():
        raise OnlineSlamError(
            "--noise self: the source has no landmark sighting with an id to calibrate against (sightings without "
            "ids are associated with the very covariances it would fit)"
        )
    graph = log.graph()  # its sightings: those with ids, in the order logged
    ranged = split_models(graph.obs_model)[0] == RANGE_BEARING
    sensors, sensor_of = _sensors([n for n, ok in zip(names, with_id) if ok], ranged, min_sightings)
    poses = np.array(log.poses).reshape(-1, 3)
    if initial is not None:
        if len(initial.poses) != len(poses):
            raise ValueError(f"initial estimate of {len(initial.poses)} poses, expected {len(poses)}")
        poses = initial.poses.copy()
    landmarks = median_landmarks(graph, poses, log.landmarks)
    if initial is not None:
        given = {lid: k for k, lid in enumerate(initial.landmark_ids)}
        for k, lid in enumerate(log.landmark_ids):
            if lid in given:
                landmarks[k] = initial.landmarks[given[lid]]
    return _Data(graph, poses, landmarks, sensor_of, sensors, _reach(graph), int((~with_id).sum()))


def _reach(graph: FactorGraph) -> Array:
    """Each sighting's measured range in range sigmas (see :attr:`_Data.reach`)."""
    parts = []
    for z, W, ranged in (
        (graph.obs_z, graph.obs_sqrt_info, split_models(graph.obs_model)[0] == RANGE_BEARING),
        (graph.rob_z, graph.rob_sqrt_info, np.ones(len(graph.rob_z), dtype=bool)),
    ):
        sigma = np.sqrt(np.linalg.inv(np.einsum("kji,kjl->kil", W, W))[:, 0, 0]) if len(W) else np.zeros(0)
        parts.append(np.where(ranged, z[:, 0] / sigma, np.inf))
    return np.concatenate(parts)


def _sensors(
    names: list[str | None], ranged: Mask, min_sightings: int
) -> tuple[tuple[str | None, ...], NDArray[np.int64]]:
    """The sensors with at least ``min_sightings`` range-bearing sightings (the centre first, then by name), and
    each sighting's index among them (-1: none)."""
    counts: dict[str | None, int] = {}
    for name, rb in zip(names, ranged):
        counts[name] = counts.get(name, 0) + int(rb)
    sensors = tuple(
        sorted((n for n, k in counts.items() if k >= min_sightings), key=lambda n: (n is not None, n or ""))
    )
    index = {n: k for k, n in enumerate(sensors)}
    return sensors, np.array([index.get(n, -1) if rb else -1 for n, rb in zip(names, ranged)], dtype=np.int64)


def _start(data: _Data, cfg: SelfFitConfig, gate: float) -> _State:
    """The first solve (Cauchy loss on sightings, declared covariances) and the first gate, at a robust scale."""
    first = solve(data.graph, data.poses, data.landmarks, cfg.solver, loss=cfg.initial_loss)
    q_obs, q_rob = _sighting_squares(data.graph, first.poses, first.landmarks)
    q = np.concatenate([q_obs, q_rob])
    sensor = float(np.median(q)) / (2.0 * math.log(2.0)) if len(q) else 1.0  # a chi-square's median, 2 dof
    biases = np.zeros((len(data.sensors), 2))
    kept, kept_robots = _kept(data, (q_obs, q_rob), sensor, cfg, gate, np.ones(len(q), dtype=bool), 0.0)
    return _State((1.0, sensor), biases, kept, kept_robots, first.poses, first.landmarks, bias_sd=biases.copy())


def _key(state: _State) -> bytes:
    """Which sightings a state keeps, as a key."""
    return np.packbits(np.concatenate([state.kept, state.kept_robots])).tobytes()


def _iterate(data: _Data, state: _State, cfg: SelfFitConfig, gate: float, judge: bool) -> tuple[_State, float]:
    """One solve at the current scales and biases; new scales, biases and (``judge``) gate; the largest change."""
    graph, seen = _weighted(_corrected(data, state.biases), state)
    result = solve(graph, state.poses, state.landmarks[seen], cfg.solver)
    r, J = linearize(graph, layout(graph), result.poses, result.landmarks)
    columns, fitted = _bias_columns(data, state, graph)
    A = sp.hstack([J, columns], format="csr")
    scales, redundancy = _scales(A, r, graph, state.scales, cfg, gate)
    step, cov = gauss_newton(A, r, columns.shape[1])
    x_step, b_step = np.split(step, [len(step) - columns.shape[1]])
    landmarks = state.landmarks.copy()
    poses, landmarks[seen] = retract(layout(graph, entries=False), result.poses, result.landmarks, x_step)
    biases, sd = state.biases.copy(), np.zeros_like(state.biases)
    biases[fitted] += b_step.reshape(-1, 2)
    sd[fitted] = np.sqrt(np.diag(cov)).reshape(-1, 2)
    q_obs, q_rob = _sighting_squares(_corrected(data, biases), poses, landmarks)
    solved = np.concatenate([state.kept, state.kept_robots])
    leverage = 1.0 - redundancy[1] / max(2.0 * float(solved.sum()), 1.0)  # the sightings' mean, over their rows
    kept, kept_robots = _kept(data, (q_obs, q_rob), scales[1], cfg, gate, solved, leverage)
    if not judge:
        kept, kept_robots = state.kept, state.kept_robots
    moves = [abs(math.log(a / b)) for a, b in zip(scales, state.scales)] + list(np.abs(b_step) / sd[fitted].ravel())
    return _State(scales, biases, kept, kept_robots, poses, landmarks, redundancy, sd), max(moves)


def _scales(
    A: sp.csr_matrix, r: Array, graph: FactorGraph, scales: tuple[float, float], cfg: SelfFitConfig, gate: float
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The next (odometry, sensor) scales from a solution's residuals and Jacobian (biases' columns included),
    and the two groups' redundancies."""
    rows = _groups(graph)
    traces = group_traces(A, rows)
    redundancy = (float(rows["odometry"].sum()) - traces["odometry"], float(rows["sensor"].sum()) - traces["sensor"])
    kept_share = (1.0, float(chi2.cdf(gate, 4)))  # of a chi-square's mean, the gate keeps this share
    new = [
        s * float(r[rows[g]] @ r[rows[g]]) / red / share if red >= cfg.min_redundancy else 1.0
        for s, g, red, share in zip(scales, ("odometry", "sensor"), redundancy, kept_share)
    ]
    return (new[0], new[1]), redundancy


def _kept(
    data: _Data, q: tuple[Array, Array], scale: float, cfg: SelfFitConfig, gate: float, solved: Mask, leverage: float
) -> tuple[Mask, Mask]:
    """The landmark and robot sightings inside the gate and not too close, under the sensor scale.

    A residual is judged standardized: over ``1 - h`` for a sighting in the solve (``solved``), which pulled the
    solution its way, over ``1 + h`` for one left out, which did not (``h``: the sightings' mean leverage). Judged
    as they are, a sighting left out near the gate would stay out for having been left out.
    """
    squares = np.concatenate(q)
    standard = squares / np.where(solved, 1.0 - leverage, 1.0 + leverage)
    kept = (standard < gate * scale) & (data.reach > cfg.min_range_sigmas * math.sqrt(scale))
    return kept[: len(q[0])], kept[len(q[0]) :]


def _corrected(data: _Data, biases: Array) -> FactorGraph:
    """The declared graph with each sensor's bias taken off its sightings (``z - b``, bearing wrapped)."""
    if not len(biases):
        return data.graph
    z = data.graph.obs_z.copy()
    has = data.sensor_of >= 0
    z[has] -= biases[data.sensor_of[has]]
    return dataclasses.replace(data.graph, obs_z=wrap_bearings(z, data.graph.obs_model))


def _weighted(base: FactorGraph, state: _State) -> tuple[FactorGraph, Mask]:
    """The kept factors with the covariances scaled, over the landmarks some kept sighting sees (and which)."""
    seen = np.bincount(base.obs_landmark[state.kept], minlength=base.n_landmarks) > 0
    number = np.cumsum(seen) - 1
    graph = subgraph(
        base,
        base.n_poses,
        base.fixed_poses,
        np.ones(len(base.prior_pose), dtype=bool),
        np.ones(len(base.odo_from), dtype=bool),
        state.kept,
        state.kept_robots,
    )
    odometry, sensor = (1.0 / math.sqrt(s) for s in state.scales)
    graph = dataclasses.replace(
        graph,
        n_landmarks=int(seen.sum()),
        obs_landmark=number[graph.obs_landmark],
        odo_sqrt_info=graph.odo_sqrt_info * odometry,
        obs_sqrt_info=graph.obs_sqrt_info * sensor,
        rob_sqrt_info=graph.rob_sqrt_info * sensor,
    )
    return graph, seen


def _groups(graph: FactorGraph) -> dict[str, Mask]:
    """The rows of the odometry and of the sightings (landmarks and robots) among the graph's residuals."""
    P, K = 3 * len(graph.prior_pose), 3 * len(graph.odo_from)
    rows = np.arange(graph.n_residuals)
    return {"odometry": (rows >= P) & (rows < P + K), "sensor": rows >= P + K}


def _bias_columns(data: _Data, state: _State, graph: FactorGraph) -> tuple[sp.csr_matrix, Mask]:
    """The Jacobian of the whitened residuals in the biases of the sensors with enough kept sightings (and which).

    A sighting's residual is ``W (h - (z - b))``: its columns of sensor s's bias are W.
    """
    sensor_of = data.sensor_of[state.kept]
    counts = np.bincount(sensor_of[sensor_of >= 0], minlength=len(data.sensors))
    fitted = counts > 0
    column = np.cumsum(fitted) - 1
    rows_of = np.flatnonzero(sensor_of >= 0)
    first = 3 * len(graph.prior_pose) + 3 * len(graph.odo_from) + 2 * rows_of
    cols = 2 * column[sensor_of[rows_of]]
    row_index = (first[:, None] + np.array([0, 0, 1, 1])).ravel()
    col_index = (cols[:, None] + np.array([0, 1, 0, 1])).ravel()
    values = graph.obs_sqrt_info[rows_of].reshape(-1)
    shape = (graph.n_residuals, 2 * int(fitted.sum()))
    return sp.csr_matrix((values, (row_index, col_index)), shape=shape), fitted


def _sighting_squares(graph: FactorGraph, poses: Array, landmarks: Array) -> tuple[Array, Array]:
    """Squared whitened residual of each landmark sighting (L,) and robot sighting (R,) under the graph's weights."""
    r = evaluate(graph, poses, landmarks)
    start = 3 * len(graph.prior_pose) + 3 * len(graph.odo_from)
    pairs = r[start:].reshape(-1, 2)
    q = np.sum(pairs * pairs, axis=1)
    return q[: len(graph.obs_pose)], q[len(graph.obs_pose) :]


def _result(data: _Data, state: _State, iterations: int, converged: bool, bound: float, close: int) -> SelfFit:
    """The fit as reported; a bias is significant beyond ``bound`` standard deviations; ``close`` sightings were
    left out as too close."""
    counts = np.bincount(data.sensor_of[state.kept & (data.sensor_of >= 0)], minlength=len(data.sensors))
    significant = np.abs(state.biases) > bound * state.bias_sd
    biases = tuple(
        BiasFit(name, int(n), float(b[0]), float(b[1]), float(sd[0]), float(sd[1]), (bool(a[0]), bool(a[1])))
        for name, n, b, sd, a in zip(data.sensors, counts, state.biases, state.bias_sd, significant)
        if n
    )
    graph = data.graph
    return SelfFit(
        increments=len(graph.odo_from),
        sightings=len(graph.obs_pose),
        without_id=data.without_id,
        robot_sightings=len(graph.rob_from),
        gated=int((~state.kept).sum() + (~state.kept_robots).sum()) - close,
        close=close,
        odometry_scale=state.scales[0],
        sensor_scale=state.scales[1],
        odometry_redundancy=state.redundancy[0],
        sensor_redundancy=state.redundancy[1],
        biases=biases,
        iterations=iterations,
        converged=converged,
    )


def describe(fit: SelfFit) -> str:
    """The fit as a user reads it: what it used, the scales with their redundancies, each sensor's bias."""
    used = f"{fit.increments} odometry increments, {fit.sightings} landmark sightings"
    if fit.robot_sightings:
        used += f", {fit.robot_sightings} robot sightings"
    lines = [f"noise self-fit (no truth): {used}"]
    left = [f"{fit.gated} beyond the gate"] + ([f"{fit.close} too close"] if fit.close else [])
    left += [f"{fit.without_id} without id"] if fit.without_id else []
    settled = "settled" if fit.converged else "not settled"
    lines.append(f"  {fit.iterations} batch solves, {settled}; sightings left out: {', '.join(left)}")
    lines.append(f"  odometry scale {fit.odometry_scale:.3g} (redundancy {fit.odometry_redundancy:.0f} of "
                 f"{3 * fit.increments} residuals)")  # fmt: skip
    lines.append(f"  sensor scale {fit.sensor_scale:.3g} (redundancy {fit.sensor_redundancy:.0f})")
    if fit.sightings_correlated:
        lines.append(
            "  that sensor scale and the biases not applied: the source's header says sightings_correlated (its "
            "sigmas are widened on purpose for the correlation of repeated sightings)"
        )
        if fit.own_sensor_scale is not None:
            lines.append(
                f"  sensor scale against the sightings' own covariances {fit.own_sensor_scale:.3g} ({_verdict(fit)})"
            )
    rows = [("sensor", "sightings", "range bias", "bearing bias")]
    for b in fit.biases:
        cells = (
            _bias_cell(b.range_m, b.range_sd, "m", b.significant[0]),
            _bias_cell(b.bearing_rad, b.bearing_sd, "rad", b.significant[1]),
        )
        rows.append((b.sensor or "(centre)", str(b.sightings), *cells))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    if fit.biases:
        lines += ["  " + "  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
        lines.append(
            "  (*: beyond noise" + ("; not applied, as above)" if fit.sightings_correlated else ", taken off)")
        )
    biased = " and the biases marked * taken off" if fit.sensor_bias else ""
    lines.append(f"replaying with {fit.flags()}{biased}")
    return "\n".join(lines)


def _verdict(fit: SelfFit) -> str:
    """What the own-covariance reading says, as :attr:`SelfFit.applied_sensor_scale` takes it."""
    own = fit.own_sensor_scale or 1.0
    if fit.own_range is None:
        if own > 1.0:
            return "above 1: the sensor is declared too sure by at least that much, applied"
        return "not above 1: says nothing, as the landmarks absorb errors alike over their sightings"
    low, high, spread = fit.own_range
    where = f"the source's range for sightings declared right {low:.3g}-{high:.3g}"
    if not _beyond(own, fit.own_range):
        return f"within {spread:.3g}x of {where}: says nothing, not applied"
    return f"beyond {spread:.3g}x of {where}: {own / low:.3g}x its low end applied"


def _beyond(own: float, own_range: tuple[float, float, float]) -> bool:
    """Whether an own-covariance reading lies more than the spread outside the declared ``(low, high, spread)``."""
    low, high, spread = own_range
    return not low / spread <= own <= high * spread


def _bias_cell(value: float, sd: float, unit: str, significant: bool) -> str:
    """A bias with its standard deviation, marked when it is beyond noise."""
    return f"{value:+.3g} +- {sd:.2g} {unit}" + (" *" if significant else "")
