"""How honest the MRCLAM conversion's odometry covariances are, by the length of the increment.

For every increment whose two ends Vicon covers, the squared Mahalanobis distance of its error against the Vicon
increment, ``e^T C^-1 e`` (3 if consistent), averaged per robot over increments grouped by the time they span.
``python -m benchmarks.mrclam_odometry_chi2 [FOLDER]`` (default ``../shared/data/MRCLAM_Dataset6``).

It then compares, by log-likelihood over every robot's covered increments, the conversion's model (each increment
perturbed once, at its end) with one whose heading noise is spread along the increment's commands, each piece's
turning the rest of the path (the position noise ``q J r r^T J^T`` and its cross term with the heading): both
with the default coefficients and each refitted (full 3x3 covariances, the six terms the defaults use).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers.mrclam import (
    MrclamNoise,
    _dead_reckoning,
    _interpolate_truth,
    increment_covariances,
    load_robot,
    pieces,
    read_mrclam,
)
from online_slam.sources.events import Odometry, Start, Truth

SPANS = ((0.0, 1.0), (1.0, 5.0), (5.0, 15.0), (15.0, np.inf))
"""Groups of increments by the seconds they span."""


def chi2_by_span(folder: str, robot: int) -> list[tuple[int, float]]:
    """(count, mean squared Mahalanobis distance) of one robot's increments in each of :data:`SPANS`."""
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
    return [(int(np.sum(m)), float(c[m].mean()) if m.any() else float("nan")) for m in groups]


def heading_levers(commands: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per increment between ``times``, the covariance that unit heading noise per second and per radian turned,
    spread over its commands, causes at its end in the earlier pose's frame, each shape (len(times) - 1, 3, 3)."""
    p = pieces(commands, times)
    at, (x, y, heading) = p.at, p.poses.T
    piece = np.searchsorted(at, np.arange(len(p.dt)), side="right") - 1  # the increment each piece belongs to
    inside = (piece >= 0) & (piece < len(times) - 1)
    end = at[np.minimum(piece + 1, len(at) - 1)]
    start_heading = heading[at[np.clip(piece, 0, len(at) - 1)]]
    c, s = np.cos(start_heading), np.sin(start_heading)
    rx, ry = x[end] - x[1:], y[end] - y[1:]
    jr = np.stack([-(-s * rx + c * ry), c * rx + s * ry, np.ones_like(rx)], -1)  # [J r; 1], earlier frame
    outer = jr[:, :, None] * jr[:, None, :]
    levers = []
    for q in (p.dt, np.abs(p.turn)):
        total = np.zeros((len(times) - 1, 3, 3))
        np.add.at(total, piece[inside], (q[:, None, None] * outer)[inside])
        levers.append(total)
    return levers[0], levers[1]


def compare_models(folder: str) -> None:
    """Print the log-likelihoods of the end-only and the spread heading models, default and refitted."""
    parts = []
    for robot in (1, 2, 3, 4, 5):
        data = load_robot(Path(folder), robot)
        poses, path, turn = _dead_reckoning(data.odometry, data.times)
        commanded = between(poses[:-1], poses[1:])
        truth, covered = _interpolate_truth(data.truth, data.times)
        both = covered[:-1] & covered[1:]
        error = commanded - between(truth[:-1], truth[1:])
        error[:, 2] = wrap(error[:, 2])
        per_s, per_rad = heading_levers(data.odometry, data.times)
        parts.append([a[both] for a in (error, np.diff(data.times), np.diff(path), np.diff(turn), per_s, per_rad)])
        parts[-1].append(commanded[both])
    error, dt, path, turn, per_s, per_rad, commanded = (np.concatenate([p[k] for p in parts]) for k in range(7))
    floor = MrclamNoise().floor

    def log_likelihood(log_terms: np.ndarray, spread: bool) -> float:
        x_s, x_m2, y_s, y_m2, t_s, t_rad = np.exp(log_terms)
        heading = np.zeros_like(dt) if spread else t_s * dt + t_rad * turn
        variances = np.stack([x_s * dt + x_m2 * path**2, y_s * dt + y_m2 * path**2, heading], -1) + floor
        cov = increment_covariances(commanded, variances)
        if spread:
            cov = cov + t_s * per_s + t_rad * per_rad
        _, log_det = np.linalg.slogdet(cov)
        chi2 = np.einsum("ki,ki->k", error, np.linalg.solve(cov, error[..., None])[..., 0])
        return -0.5 * float(np.sum(log_det + chi2))

    d = MrclamNoise()
    defaults = np.log([d.x_per_s, d.x_per_m2, d.y_per_s, d.y_per_m2, d.theta_per_s, d.theta_per_rad])
    names = "x per s, x per m^2, y per s, y per m^2, theta per s, theta per rad"
    print(f"log-likelihood over {len(dt)} increments (terms: {names})")
    for spread in (False, True):
        model = "heading spread along the commands" if spread else "end-only (the conversion's)"
        fit = minimize(
            lambda p, s=spread: -log_likelihood(p, s), defaults, method="L-BFGS-B", bounds=[(-40.0, 10.0)] * 6
        )
        terms = ", ".join(f"{t:.3g}" for t in np.exp(fit.x))
        print(f"{model}: default terms {log_likelihood(defaults, spread):.1f}; refitted {-fit.fun:.1f} ({terms})")


def main(folder: str = "../shared/data/MRCLAM_Dataset6") -> None:
    """Print the table, then the models' log-likelihoods."""
    print("robot  " + "  ".join(f"{a:g}-{b:g} s: n, mean chi2".ljust(24) for a, b in SPANS))
    for robot in (1, 2, 3, 4, 5):
        print(f"{robot:>5}  " + "  ".join(f"{n:>5}, {m:6.1f}".ljust(24) for n, m in chi2_by_span(folder, robot)))
    compare_models(folder)


if __name__ == "__main__":
    main(*sys.argv[1:2])
