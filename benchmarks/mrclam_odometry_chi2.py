"""How honest the MRCLAM conversion's odometry covariances are, by the length of the increment.

For every increment whose two ends Vicon covers, the squared Mahalanobis distance of its error against the Vicon
increment, ``e^T C^-1 e`` (3 if consistent), averaged per robot over increments grouped by the time they span.
``python -m benchmarks.mrclam_odometry_chi2 [FOLDER]`` (default ``../shared/data/MRCLAM_Dataset6``).

It then compares, by log-likelihood over every robot's covered increments, the model before 2026-12-04 (commands
as logged, each increment perturbed once at its end), the commands calibrated with one speed scale with that
end-only noise and with the heading noise accrued along them (each piece's turning the rest of the path), and the
conversion's model (the speed also slowed by turning): each with its own terms and refitted
(:func:`~online_slam.importers.mrclam_noise.fit_increment_terms`).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from online_slam.geometry.angles import wrap
from online_slam.geometry.se2 import between
from online_slam.importers.mrclam import MrclamNoise, calibrated, load_robot, read_mrclam
from online_slam.importers.mrclam_noise import (
    TERMS,
    IncrementErrors,
    fit_increment_terms,
    increment_errors,
    increment_log_likelihood,
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


def main(folder: str = "../shared/data/MRCLAM_Dataset6") -> None:
    """Print the table, then the models' log-likelihoods."""
    print("robot  " + "  ".join(f"{a:g}-{b:g} s: n, mean chi2".ljust(24) for a, b in SPANS))
    for robot in (1, 2, 3, 4, 5):
        print(f"{robot:>5}  " + "  ".join(f"{n:>5}, {m:6.1f}".ljust(24) for n, m in chi2_by_span(folder, robot)))
    compare_models(folder)


if __name__ == "__main__":
    main(*sys.argv[1:2])
