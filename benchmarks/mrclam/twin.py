"""MRCLAM's twin: each robot's Vicon path, pose times and sighting schedule, with odometry and sightings drawn from
the conversion's own model. It tells the estimators' consistency on MRCLAM's geometry (long gaps, one or two
sightings a pose) apart from the model's: on the twin the model is exact.

- Odometry: the Vicon increment between two pose times plus a draw from the increment's covariance in the stream.
- Sightings: range and bearing from the Vicon pose to the surveyed landmark plus errors correlated in time as the
  model says: per robot and landmark, two Ornstein-Uhlenbeck processes of weights ``c1``, ``c2`` and time
  constants ``tau1``, ``tau2`` and white noise for the rest, scaled by the sighting's independent sigma. The
  stream keeps the conversion's sigmas (widened for that correlation).
- The stream stops at the first pose Vicon does not cover.

``python -m benchmarks.mrclam.twin [SEEDS] [FOLDER]`` prints, per robot, the EKF's and the smoother's online RMSE
and mean NEES averaged over seeds 0..SEEDS-1 (default 3), beside the real data's.
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

from online_slam.evaluation.results import EstimatorResult
from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers.mrclam.reader import MrclamNoise, read_mrclam
from online_slam.importers.mrclam.sightings import camera_of, sighting_sigma
from online_slam.pipeline import replay
from online_slam.pipeline.config import ReplayConfig
from online_slam.sources.events import Event, LandmarkTruth, Observation, Odometry, Start, Truth

FOLDER = "../shared/data/MRCLAM_Dataset6"


def correlated_errors(rng: np.random.Generator, times: np.ndarray, terms: tuple[float, ...]) -> np.ndarray:
    """Unit-variance errors at sorted ``times`` whose correlation is ``c1 exp(-dt/tau1) + c2 exp(-dt/tau2)``."""
    c1, tau1, c2, tau2 = terms
    gaps = np.diff(times, prepend=times[0])
    out, fast, slow = np.empty(len(times)), rng.normal(), rng.normal()
    for k, gap in enumerate(gaps):
        a, b = np.exp(-gap / tau1), np.exp(-gap / tau2)
        fast = a * fast + np.sqrt(1.0 - a**2) * rng.normal()
        slow = b * slow + np.sqrt(1.0 - b**2) * rng.normal()
        out[k] = np.sqrt(c1) * fast + np.sqrt(c2) * slow + np.sqrt(max(1.0 - c1 - c2, 0.0)) * rng.normal()
    return out


def twin(folder: str, robot: int, seed: int, noise: MrclamNoise | None = None) -> list[Event]:
    """The robot's converted stream with its odometry and sightings redrawn from the model along Vicon's path."""
    cfg = noise or MrclamNoise()
    rng = np.random.default_rng(seed)
    events = list(read_mrclam(folder, robot, cfg))
    truth = {e.t: np.asarray(e.pose) for e in events if isinstance(e, Start | Truth)}
    landmarks = {e.landmark: np.asarray(e.position) for e in events if isinstance(e, LandmarkTruth)}
    covered = [e for e in events if isinstance(e, Observation) and e.t in truth and e.landmark in landmarks]
    errors: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for landmark in {e.landmark for e in covered}:
        times = np.array([e.t for e in covered if e.landmark == landmark])
        errors[landmark] = (
            correlated_errors(rng, times, cfg.range_correlation),
            correlated_errors(rng, times, cfg.bearing_correlation),
        )
    drawn: dict[int, int] = {}
    out: list[Event] = []
    last = None
    for e in events:
        if isinstance(e, Start):
            last = e.t
        elif isinstance(e, Odometry):
            if last not in truth or e.t not in truth:
                break
            delta = between(truth[last][None], truth[e.t][None])[0]
            delta[2] = wrap(delta[2])
            delta = delta + np.linalg.cholesky(np.asarray(e.cov)) @ rng.standard_normal(3)
            e = dataclasses.replace(e, delta=tuple(map(float, delta)))
            last = e.t
        elif isinstance(e, Observation):
            if e.t not in truth or e.landmark not in landmarks:
                continue
            k = drawn.get(e.landmark, 0)
            drawn[e.landmark] = k + 1
            pose = truth[e.t]
            dx, dy = landmarks[e.landmark] - pose[:2]
            true_range = float(np.hypot(dx, dy))
            sr, sb = sighting_sigma(cfg, e.range, camera_of(cfg, robot))
            er, eb = errors[e.landmark][0][k], errors[e.landmark][1][k]
            bearing = wrap(np.arctan2(dy, dx) - pose[2] + sb * eb)
            e = dataclasses.replace(e, range=max(true_range + sr * er, 1e-3), bearing=float(bearing))
        out.append(e)
    return out


def main(seeds: int = 3, folder: str = FOLDER) -> None:
    """Print the twin's figures beside the real data's, robot by robot: online RMSE and mean NEES of the EKF and the
    smoother, and the batch's final RMSE over the EKF's (the twin's: its median and largest over the seeds)."""
    config = ReplayConfig(estimators=("ekf", "smoother", "batch"))
    print("robot  poses  twin: EKF online m, NEES; smoother online m, NEES; batch / EKF final, median (max)    "
          "real data (the same figures)")  # fmt: skip
    for robot in (1, 2, 3, 4, 5):
        runs, ratios, poses = [], [], 0
        for seed in range(seeds):
            results = replay(twin(folder, robot, seed), config, name=f"twin {robot}")
            figures, poses = results.estimators, results.poses
            runs.append([(figures[k].online_rmse_m, figures[k].nees_mean) for k in ("ekf", "smoother")])
            ratios.append(_batch_over_ekf(figures))
        (ekf, ekf_nees), (sm, sm_nees) = np.mean(runs, axis=0)
        real = replay(folder, dataclasses.replace(config, dataset={"robot": robot})).estimators
        print(
            f"{robot:>5}  {poses:>5}  {ekf:.3f}, {ekf_nees:5.2f}; {sm:.3f}, {sm_nees:5.2f}; "
            f"{np.median(ratios):.2f} ({max(ratios):.2f})    {real['ekf'].online_rmse_m:.3f}, "
            f"{real['ekf'].nees_mean:5.2f}; {real['smoother'].online_rmse_m:.3f}, {real['smoother'].nees_mean:5.2f}; "
            f"{_batch_over_ekf(real):.2f}",
            flush=True,
        )


def _batch_over_ekf(figures: dict[str, EstimatorResult]) -> float:
    """The batch's final RMSE over the EKF's."""
    return float(figures["batch"].final_rmse_m) / float(figures["ekf"].final_rmse_m)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3, *sys.argv[2:3])
