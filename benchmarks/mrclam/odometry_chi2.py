"""How honest the MRCLAM conversion's odometry covariances are, by the seconds an increment spans.

For every increment whose two ends Vicon covers, the squared Mahalanobis distance of its error against the Vicon
increment, ``e^T C^-1 e`` (3 if consistent), averaged per robot over increments grouped by the time they span.
``python -m benchmarks.mrclam.odometry_chi2 [FOLDER]`` (default ``../shared/data/MRCLAM_Dataset6``).

It then compares, by log-likelihood over every robot's covered increments, the model before 2026-12-04 (commands
as logged, each increment perturbed once at its end), two models of the commands calibrated with one speed scale
(one with that end-only noise, one with the heading noise accrued along the commands, each piece's turning the
rest of the path), and the conversion's model (the speed also slowed by turning): each with its own terms and refitted
(:func:`~online_slam.importers.mrclam.noise.fit_increment_terms`) on the increments alone. Last, over consecutive
windows of the lengths the conversion's fit also uses (:data:`~online_slam.importers.mrclam.noise.WINDOWS_S`), the
mean squared Mahalanobis distance, of the pose and of the heading alone, under the terms fitted on the increments
alone and under the conversion's; and each robot's heading drift against the distance it covers.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers.mrclam.noise import (
    TERMS,
    WINDOWS_S,
    IncrementErrors,
    fit_increment_terms,
    increment_errors,
    increment_log_likelihood,
    window_errors,
)
from online_slam.importers.mrclam.reader import MrclamNoise, calibrated, load_robot, model_covariances, read_mrclam
from online_slam.sources.events import Odometry, Start, Truth

SPANS = ((0.0, 1.0), (1.0, 5.0), (5.0, 15.0), (15.0, np.inf))
"""Groups of increments by the seconds they span."""


def chi2_by_span(folder: str, robot: int) -> tuple[list[tuple[int, float]], tuple[float, float]]:
    """(count, mean squared Mahalanobis distance) of one robot's increments in each of :data:`SPANS`, and (seconds,
    squared Mahalanobis distance) of its longest increment."""
    truth: dict[float, np.ndarray] = {}
    increments = []
    last = 0.0
    for event in read_mrclam(folder, robot):
        if isinstance(event, Start | Truth):
            truth[event.t] = np.asarray(event.pose, dtype=float)
        if isinstance(event, Start):
            last = event.t
        elif isinstance(event, Odometry):
            increments.append((last, event.t, np.asarray(event.delta), np.asarray(event.cov)))
            last = event.t
    spans, chi2 = [], []
    for t0, t1, delta, cov in increments:
        if t0 in truth and t1 in truth:
            error = delta - between(truth[t0][None], truth[t1][None])[0]
            error[2] = wrap(error[2])
            spans.append(t1 - t0)
            chi2.append(float(error @ np.linalg.solve(cov, error)))
    s, c = np.array(spans), np.array(chi2)
    groups = [(s >= low) & (s < high) for low, high in SPANS]
    longest = int(np.argmax(s))
    return [(int(np.sum(m)), float(c[m].mean()) if m.any() else float("nan")) for m in groups], (s[longest], c[longest])


EARLIER = MrclamNoise(
    x_per_s=2.9e-5,
    x_per_m2=0.019,
    y_per_s=4.7e-7,
    y_per_m2=0.0011,
    theta_per_s=3.0e-4,
    theta_per_rad=0.020,
    heading_along_path=False,
    command_lag_s=0.0,
    speed_scale=1.0,
    turn_scale=1.0,
    speed_per_turn=0.0,
)
"""The conversion's model before 2026-12-04: commands as logged, heading noise at each increment's end."""
WITHOUT_TURN_LOSS = {"speed_scale": 0.955, "speed_per_turn": 0.0}
"""The first calibration (2026-12-04): one speed scale, turning or not."""


def compare_models(folder: str) -> None:
    """Print the increments' log-likelihoods under the earlier model and the conversion's, each refitted."""
    datas = [load_robot(Path(folder), robot) for robot in (1, 2, 3, 4, 5)]
    now = MrclamNoise()
    models = (
        ("commands as logged, heading noise at the end (before 2026-12-04)", EARLIER),
        (
            "calibrated, no turn loss, heading noise at the end",
            replace(now, heading_along_path=False, **WITHOUT_TURN_LOSS),
        ),
        ("calibrated, no turn loss, heading noise along the commands", replace(now, **WITHOUT_TURN_LOSS)),
        ("calibrated with the speed lost turning, heading noise along (the conversion's)", now),
    )
    print(f"log-likelihood of the increments Vicon covers (terms: {', '.join(TERMS)})")
    for name, model in models:
        errors = IncrementErrors.pooled([increment_errors(d, calibrated(d.odometry, model)) for d in datas])
        fitted = fit_increment_terms(errors, model)
        terms = ", ".join(f"{getattr(fitted, t):.3g}" for t in TERMS)
        own, refitted = increment_log_likelihood(model, errors), increment_log_likelihood(fitted, errors)
        print(f"{name}: {own:.1f} with its terms; refitted {refitted:.1f} ({terms})")


def window_chi2(noise: MrclamNoise, e: IncrementErrors) -> tuple[float, float]:
    """Mean squared Mahalanobis distance of the increments' errors (pose, 3 if consistent; heading, 1)."""
    cov = model_covariances(noise, e.commanded, (e.dt, e.path, e.turn), (e.per_s, e.per_rad))
    pose = np.einsum("ki,ki->k", e.errors, np.linalg.solve(cov, e.errors[..., None])[..., 0])
    return float(pose.mean()), float(np.mean(e.errors[:, 2] ** 2 / cov[:, 2, 2]))


def compare_windows(folder: str) -> None:
    """Print the windows' figures under the terms fitted on the increments alone and under the conversion's."""
    datas = [load_robot(Path(folder), robot) for robot in (1, 2, 3, 4, 5)]
    now = MrclamNoise()
    commands = [calibrated(d.odometry, now) for d in datas]
    alone = fit_increment_terms(IncrementErrors.pooled([increment_errors(d, c) for d, c in zip(datas, commands)]), now)
    print("windows of s: mean chi2 pose, heading; terms fitted on the increments alone -> the conversion's")
    for width in WINDOWS_S:
        windows = IncrementErrors.pooled([window_errors(d, c, width) for d, c in zip(datas, commands)])
        (a_pose, a_heading), (c_pose, c_heading) = window_chi2(alone, windows), window_chi2(now, windows)
        print(f"{width:>4g} s (n {len(windows.dt):>4}): {a_pose:.2f}, {a_heading:.2f} -> {c_pose:.2f}, {c_heading:.2f}")


def heading_drift(folder: str, width: float = 5.0) -> None:
    """Print each robot's heading drift: the least-squares slope of Vicon's turn minus the calibrated commands'
    over windows of ``width`` seconds against the distance commanded in them, rad/m (negative: clockwise), over
    the whole run and over its first and second halves, with the windows' RMS heading error before and after."""
    now = MrclamNoise()
    print(f"heading drift, {width:g} s windows: rad/m over the run (first half, second half); RMS rad before -> after")
    for robot in (1, 2, 3, 4, 5):
        data = load_robot(Path(folder), robot)
        w = window_errors(data, calibrated(data.odometry, now), width)
        turn, distance = -w.errors[:, 2], w.path  # Vicon minus commanded; the commands never go backwards
        half = len(turn) // 2
        parts = (slice(None), slice(None, half), slice(half, None))
        slopes = [float(distance[k] @ turn[k] / (distance[k] @ distance[k])) for k in parts]
        before, after = np.sqrt(np.mean(turn**2)), np.sqrt(np.mean((turn - slopes[0] * distance) ** 2))
        print(f"{robot:>5}  {slopes[0]:+.4f} ({slopes[1]:+.4f}, {slopes[2]:+.4f}); {before:.4f} -> {after:.4f}")


def main(folder: str = "../shared/data/MRCLAM_Dataset6") -> None:
    """Print the table, the models' log-likelihoods, the windows' figures and the robots' heading drift."""
    print("robot  " + "  ".join(f"{a:g}-{b:g} s: n, mean chi2".ljust(24) for a, b in SPANS) + "  longest: s, chi2")
    for robot in (1, 2, 3, 4, 5):
        spans, (seconds, chi2) = chi2_by_span(folder, robot)
        cells = "  ".join(f"{n:>5}, {m:6.1f}".ljust(24) for n, m in spans)
        print(f"{robot:>5}  {cells}  {seconds:.1f}, {chi2:.1f}")
    compare_models(folder)
    compare_windows(folder)
    heading_drift(folder)


if __name__ == "__main__":
    main(*sys.argv[1:2])
