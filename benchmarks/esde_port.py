"""An independent port of esde's circle simulation and standard EKF, and the EKF linearized at the truth.

Written from esde's ``simulations/rws.m``, ``gen_map.m``, ``propagate_std.m`` and ``update_std.m``
(``CAOR-MINES-ParisTech/esde``) without any of online-slam's code, it draws its noise in the order of
:func:`online_slam.sources.worlds.circle_world` (speeds, turn rates, then every visible sighting's two draws pose by
pose, the first pose's included and unused), so its standard EKF must give our EKF's figures on the same seeds: a
check of the world and of the filter. ``truth`` evaluates every Jacobian at the true poses and landmarks (the
"ideal EKF" of Huang et al., IJRR 2010): consistent by construction, the reference no EKF can expect to beat on
these streams. Figures are esde's: pose NEES averaged over runs, position RMSE per step over runs, both averaged
over steps 5..399 (1-based).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
PERP = np.array([[0.0, -1.0], [1.0, 0.0]])
"""esde's ``J``."""


def _rot(t: float) -> Array:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s], [s, c]])


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2.0 * np.pi) - np.pi)


@dataclass(frozen=True)
class PortFigures:
    """One linearization's figures over the runs."""

    anees: float
    """Pose NEES averaged over runs, then over steps 5..399."""
    in_band: float
    """Share of those steps whose run-averaged NEES is inside ``band``."""
    position_rmse_m: float
    """Position RMSE per step over runs, averaged over the steps."""
    band: tuple[float, float]
    """Two-sided 95% band of the ANEES for this many runs (3 dof)."""


def run(seeds: range, jacobians_at: str = "estimate", steps: int = 400) -> PortFigures:
    """esde's standard EKF (``jacobians_at="estimate"``) or the EKF linearized at the truth (``"truth"``).

    Args:
        seeds: ``numpy.random.default_rng`` seeds, one run each.
        jacobians_at: Where every Jacobian is evaluated.
        steps: Poses per run (esde's ``nSteps``).
    """
    from scipy.stats import chi2

    v, w, sigma, sp = 0.25, 0.075, 0.02, 0.1
    sv, sw = sigma / np.sqrt(2.0), 2.0 * np.sqrt(2.0) * sigma
    radius = v / w + 2 * 0.5
    angle = 2 * np.pi * np.arange(1, 16) / 15
    landmarks = np.c_[radius * np.cos(angle) + 0.1251, radius * np.sin(angle) + 3.3318]
    ideal = jacobians_at == "truth"
    nees, err2 = np.zeros((len(seeds), steps)), np.zeros((len(seeds), steps))
    for run_i, seed in enumerate(seeds):
        rng = np.random.default_rng(seed)
        v_m, w_m = v + sv * rng.normal(size=steps), w + sw * rng.normal(size=steps)
        truth = np.zeros((steps, 3))
        for k in range(1, steps):
            th = truth[k - 1, 2]
            truth[k] = truth[k - 1] + [v * np.cos(th), v * np.sin(th), w]
        dist = np.linalg.norm(landmarks[None] - truth[:, None, :2], axis=2)
        pose_of, landmark_of = np.nonzero((dist > 0.5) & (dist < 5.0))
        noise = sp * rng.normal(size=(len(pose_of), 2))
        x, P, seen = np.zeros(3), np.zeros((3, 3)), []
        Q = np.diag([sv**2, sw**2])
        for k in range(steps - 1):
            old = x[:3].copy()  # propagate_std
            x[:3] = [old[0] + v_m[k] * np.cos(old[2]), old[1] + v_m[k] * np.sin(old[2]), _wrap(old[2] + w_m[k])]
            a, b = (truth[k], truth[k + 1]) if ideal else (old, x[:3])
            F = np.eye(3)
            F[:2, 2] = PERP @ (b[:2] - a[:2])
            G = np.array([[np.cos(a[2]), 0.0], [np.sin(a[2]), 0.0], [0.0, 1.0]])
            P[:3, :3] = F @ P[:3, :3] @ F.T + G @ Q @ G.T
            P[:3, 3:] = F @ P[:3, 3:]
            P[3:, :3] = P[:3, 3:].T
            pose = truth[k + 1]  # update_std: the sightings of pose k + 1, known ids
            here = pose_of == k + 1
            z = [(j, _rot(pose[2]).T @ (landmarks[j] - pose[:2]) + n) for j, n in zip(landmark_of[here], noise[here])]
            H, r = [], []
            for j, zj in z:
                if j in seen:
                    f = 3 + 2 * seen.index(j)
                    C = _rot(x[2])
                    Cj, lp, rp = (_rot(pose[2]), landmarks[j], pose[:2]) if ideal else (C, x[f : f + 2], x[:2])
                    Hj = np.zeros((2, len(x)))
                    Hj[:, :3] = -Cj.T @ np.c_[np.eye(2), PERP @ (lp - rp)]
                    Hj[:, f : f + 2] = Cj.T
                    H.append(Hj)
                    r.append(zj - C.T @ (x[f : f + 2] - x[:2]))
            if H:
                Hs, rs = np.vstack(H), np.concatenate(r)
                R = sp**2 * np.eye(len(rs))
                K = P @ Hs.T @ np.linalg.inv(Hs @ P @ Hs.T + R)
                x = x + K @ rs
                IKH = np.eye(len(x)) - K @ Hs
                P = IKH @ P @ IKH.T + K @ R @ K.T
            for j, zj in z:  # augment
                if j not in seen:
                    seen.append(j)
                    C = _rot(x[2])
                    place = x[:2] + C @ zj
                    Cj, lp, rp = (_rot(pose[2]), landmarks[j], pose[:2]) if ideal else (C, place, x[:2])
                    A = np.c_[np.eye(2), PERP @ (lp - rp)]  # d landmark / d robot
                    n = len(x)
                    grown = np.zeros((n + 2, n + 2))
                    grown[:n, :n] = P
                    grown[n:, :n] = A @ P[:3, :n]
                    grown[:n, n:] = grown[n:, :n].T
                    grown[n:, n:] = A @ P[:3, :3] @ A.T + Cj @ (sp**2 * np.eye(2)) @ Cj.T
                    x, P = np.r_[x, place], 0.5 * (grown + grown.T)
            e = truth[k + 1] - x[:3]
            e[2] = _wrap(e[2])
            if k >= 3:  # from step 5 (1-based) on, as esde's figures
                nees[run_i, k + 1] = e @ np.linalg.solve(P[:3, :3], e)
            err2[run_i, k + 1] = e[:2] @ e[:2]
    scored = slice(4, steps - 1)
    anees, rmse = nees.mean(axis=0)[scored], np.sqrt(err2.mean(axis=0))[scored]
    dof = 3 * len(seeds)
    band = (float(chi2.ppf(0.025, dof) / len(seeds)), float(chi2.ppf(0.975, dof) / len(seeds)))
    inside = float(np.mean((anees >= band[0]) & (anees <= band[1])))
    return PortFigures(float(anees.mean()), inside, float(rmse.mean()), band)
