"""EKF benchmarks: the structured update against filterpy's stock update, and per-step latency on a grid run
beside GTSAM's iSAM2 on the same steps."""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
from filterpy.kalman import ExtendedKalmanFilter
from numpy.typing import NDArray

from online_slam import gtsam_peer
from online_slam.engine import Engine
from online_slam.estimators.ekf import EkfSlam
from online_slam.estimators.ekf_config import EkfConfig
from online_slam.geometry.angles import wrap
from online_slam.models.range_bearing import range_bearing, range_bearing_with_jacobians
from online_slam.sources.worlds import GridConfig, grid_world

Array = NDArray[np.float64]


def random_state(rng: np.random.Generator, landmarks: int) -> tuple[Array, Array]:
    """A random EKF-SLAM state with a dense SPD covariance: (x (n,), P (n, n)), n = 3 + 2 * landmarks."""
    n = 3 + 2 * landmarks
    x = np.r_[rng.normal(size=2), rng.uniform(-3, 3), rng.uniform(-20, 20, 2 * landmarks)]
    A = rng.normal(size=(n, n)) * 0.05
    return x, A @ A.T + 0.01 * np.eye(n)


def _wrapped(a: Array, b: Array) -> Array:
    y = a - b
    y[1::2] = wrap(y[1::2])
    return y


@dataclass(frozen=True)
class UpdateTiming:
    """One map size: mean time of one single-observation update, both ways."""

    landmarks: int
    """Landmarks in the state (n = 3 + 2 * landmarks)."""
    structured_ms: float
    """online-slam's structured update, ms."""
    stock_ms: float
    """filterpy's ``ExtendedKalmanFilter.update`` (dense Joseph form), ms."""


def time_updates(landmark_counts: tuple[int, ...] = (50, 200, 500, 1000), seed: int = 0) -> list[UpdateTiming]:
    """Time one range-bearing update of a random landmark, structured vs stock, at each map size."""
    rng = np.random.default_rng(seed)
    out = []
    for m in landmark_counts:
        x, P = random_state(rng, m)
        j = np.array([m // 2])
        z = range_bearing(x[:3], x[3:].reshape(-1, 2)[j]) + [0.05, 0.01]
        R = np.diag([0.01, 0.0003])[None]
        _, J_p, J_l = range_bearing_with_jacobians(x[:3], x[3:].reshape(-1, 2)[j])
        H = np.zeros((2, len(x)))
        H[:, :3], H[:, 3 + 2 * j[0] : 5 + 2 * j[0]] = J_p[0], J_l[0]
        ekf = EkfSlam.from_state(x, P, list(range(m)), EkfConfig(gate_probability=1.0))
        repeats = max(20, int(2e5 / (len(x) ** 2)))
        # Repeated updates with the same observation cost the same as the first; no state reset inside the loop.
        # One untimed call first for each side: the first touch of a fresh n x n buffer costs page faults.
        with ekf.single_threaded():
            ekf.update_structured(j, z, R)
            started = time.perf_counter()
            for _ in range(repeats):
                ekf.update_structured(j, z, R)
            structured = (time.perf_counter() - started) / repeats
        stock = ExtendedKalmanFilter(dim_x=len(x), dim_z=2)
        stock.x, stock.P = x.reshape(-1, 1).copy(), P.copy()
        stock_repeats = max(2, int(2e8 / len(x) ** 3))
        for k in range(stock_repeats + 1):
            if k == 1:
                started = time.perf_counter()
            stock.update(
                z.reshape(-1, 1),
                HJacobian=lambda _x, H=H: H,
                Hx=lambda s, j=j: range_bearing(s[:3, 0], s[3:, 0].reshape(-1, 2)[j]).reshape(-1, 1),
                R=la.block_diag(*R),
                residual=_wrapped,
            )
        stock_s = (time.perf_counter() - started) / stock_repeats
        out.append(UpdateTiming(m, structured * 1e3, stock_s * 1e3))
    return out


@dataclass(frozen=True)
class StepLatency:
    """Per-step wall time of an online estimator over a run, ms, and its online RMSE."""

    label: str
    """Who ran."""
    median_ms: float
    """Median step time."""
    p95_ms: float
    """95th percentile."""
    p99_ms: float
    """99th percentile."""
    max_ms: float
    """Largest."""
    online_rmse_m: float
    """RMSE of each pose as estimated when newest, against truth (first pose anchored by construction)."""


def _latency(label: str, seconds: Array, poses: Array, truth: Array) -> StepLatency:
    ms = seconds * 1e3
    rmse = float(np.sqrt(np.mean(np.sum((poses[:, :2] - truth[:, :2]) ** 2, axis=1))))
    p95, p99 = np.percentile(ms, [95, 99])
    return StepLatency(label, float(np.median(ms)), float(p95), float(p99), float(ms.max()), rmse)


def drive(estimator: object, events: Iterable) -> tuple[Array, Array, list, dict]:
    """Push events through the engine (the one way in).

    Returns:
        (per-step seconds (N,), online poses (N, 3), the steps, the true poses by pose index where the stream has
        them).
    """
    engine = Engine([estimator])  # type: ignore[list-item]
    seconds, poses, steps = [], [], []
    name = estimator.name  # type: ignore[attr-defined]
    for event in [*events, None]:
        records = engine.push(event) if event is not None else [engine.close()]
        for record in records:
            if record is None:
                continue
            seconds.append(record.seconds[name])
            poses.append(record.snapshots[name].pose)
            steps.append(record.step)
    return np.array(seconds), np.array(poses), steps, engine.frontend.truth.poses


def _drive(estimator: object, events: list) -> tuple[Array, Array, Array, list]:
    """:func:`drive` over a world with truth at every pose: per-step seconds, online poses, truth, the steps."""
    seconds, poses, steps, truth = drive(estimator, events)
    return seconds, poses, np.array([truth[s.index] for s in steps]), steps


def time_steps(config: GridConfig, with_peer: bool = True) -> tuple[int, list[StepLatency]]:
    """Run the EKF (and iSAM2, when available) step by step over a grid world, through the engine.

    Returns:
        (number of steps, latency per estimator).
    """
    seconds, poses, truth, steps = _drive(EkfSlam(), list(grid_world(config)))
    rows = [_latency("online-slam EKF", seconds, poses, truth)]
    if with_peer and gtsam_peer.available():
        peer = gtsam_peer.isam2_online(steps)
        rows.append(_latency("GTSAM iSAM2", peer.step_s, peer.poses, truth))
    return len(steps), rows


def time_smoother(config: GridConfig, windows: tuple[int, ...] = (10, 20, 50)) -> list[StepLatency]:
    """Per-step latency and online RMSE of the default smoother, and of the window alone (no global
    relinearization) at several window sizes."""
    from online_slam.estimators.smoother import GlobalConfig, SlidingWindowSmoother, SmootherConfig, WindowConfig

    events = list(grid_world(config))
    rows = []
    seconds, poses, truth, _ = _drive(SlidingWindowSmoother(), events)
    rows.append(_latency("smoother default", seconds, poses, truth))
    for window in windows:
        seconds, poses, truth, _ = _drive(
            SlidingWindowSmoother(SmootherConfig(window=WindowConfig(size=window), global_solve=GlobalConfig(every=0))),
            events,
        )
        rows.append(_latency(f"smoother W={window}", seconds, poses, truth))
    return rows


@dataclass(frozen=True)
class PairedRound:
    """One round of the default smoother and iSAM2 run back to back on the same steps."""

    smoother_median_ms: float
    """The smoother's median step time."""
    peer_median_ms: float
    """iSAM2's median step time."""
    smoother_p99_ms: float
    """The smoother's 99th percentile."""
    peer_p99_ms: float
    """iSAM2's 99th percentile."""


def paired_rounds(config: GridConfig, rounds: int = 3) -> list[PairedRound]:
    """The default smoother and iSAM2, back to back, ``rounds`` times (the first of the pair alternates).

    This machine's speed drifts by tens of per cent within minutes: a ratio of two runs taken minutes apart
    measures the drift as much as the estimators, one of two runs taken back to back (in alternating order,
    so a steady drift cancels over rounds) much less. Empty without GTSAM.
    """
    from online_slam.estimators.smoother import SlidingWindowSmoother

    if not gtsam_peer.available():
        return []
    events = list(grid_world(config))
    steps: list = []  # from the first round's smoother run, which comes first
    out = []
    for k in range(rounds):
        figures: dict[str, tuple[float, float]] = {}
        for who in ("smoother", "peer") if k % 2 == 0 else ("peer", "smoother"):
            if who == "smoother":
                seconds, _, steps, _ = drive(SlidingWindowSmoother(), events)
            else:
                seconds = gtsam_peer.isam2_online(steps).step_s
            ms = np.asarray(seconds) * 1e3
            figures[who] = (float(np.median(ms)), float(np.percentile(ms, 99)))
        out.append(PairedRound(figures["smoother"][0], figures["peer"][0], figures["smoother"][1], figures["peer"][1]))
    return out
