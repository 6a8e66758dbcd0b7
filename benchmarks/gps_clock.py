"""Victoria Park's GPS against the car's own motion: the GPS delay, the laser delay and the antenna position, each
fitted on each half of the log (``python -m benchmarks.gps_clock``, about two minutes).

- GPS delay: the shift of the GPS stamps that best matches GPS speed (over 1 s) to dead-reckoned speed.
- Laser delay: the shift of the scan stamps that best keeps trees still: world positions of the detections
  (dead-reckoned pose at the shifted time, plus the laser point) matched to the nearest detection 2 s later.
- Antenna: one robot-frame point for all 20 s windows, each window's dead reckoning fitted rigidly to GPS.
- GPS scatter: GPS about dead reckoning of the antenna fitted rigidly over 10 s windows.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from benchmarks.gps_fixes import DATA
from online_slam.importers.acfr import GPS_ANTENNA
from online_slam.importers.acfr.reader import AcfrVehicle, _integrate, _table
from online_slam.models.fix import fixed_point

Array = NDArray[np.float64]
CAR = AcfrVehicle()
LAGS = np.round(np.arange(-1.0, 3.01, 0.1), 2)
"""Candidate delays, seconds (positive: the stamp is late)."""


def _rigid(points: Array, gps: Array) -> Array:
    """Residuals of the best rigid motion of ``points`` onto ``gps`` (k, 2)."""
    pc, gc = points - points.mean(0), gps - gps.mean(0)
    U, _, Vt = np.linalg.svd(pc.T @ gc)
    R = (U @ np.diag([1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt).T
    return gc - pc @ R.T


def gps_delay(inputs: Array, t: Array, xy: Array, good: NDArray[np.bool_]) -> tuple[float, float, float]:
    """(best delay, speed error RMS there, at 0) of GPS speed over ~1 s spans against dead-reckoned speed."""
    i = np.flatnonzero(good)
    j = np.searchsorted(t, t[i] + 1.0)
    i, j = i[j < len(t)], j[j < len(t)]
    whole = np.array([good[a : b + 1].all() for a, b in zip(i, j, strict=True)])
    i, j = i[whole], j[whole]
    v_gps = np.linalg.norm(xy[j] - xy[i], axis=1) / (t[j] - t[i])
    errors = []
    for lag in LAGS:
        q = np.r_[t[i], t[j]] - lag
        order = np.argsort(q)
        path = np.empty_like(q)
        path[order] = _integrate(inputs, q[order], CAR)[1]
        errors.append(math.sqrt(np.median((v_gps - (path[len(i) :] - path[: len(i)]) / (t[j] - t[i])) ** 2)))
    best = int(np.argmin(errors))
    return float(LAGS[best]), errors[best], errors[int(np.flatnonzero(LAGS == 0.0)[0])]


def laser_delay(inputs: Array, scans: Array) -> tuple[float, float, float]:
    """(best delay, RMS distance of trees to their match 2 s later there, at 0)."""
    r, b = scans[:, 1], scans[:, 2] - math.pi / 2
    local = np.c_[r * np.cos(b) + CAR.laser_x, r * np.sin(b) + CAR.laser_y]
    lags = LAGS[::2]
    errors = []
    for lag in lags:
        times, at = np.unique(scans[:, 0] - lag, return_inverse=True)
        world = fixed_point(_integrate(inputs, times, CAR)[0][at], local)
        first, last = np.searchsorted(at, np.arange(len(times))), np.searchsorted(at, np.arange(len(times)), "right")
        d = []
        for k, s in enumerate(times):
            m = np.searchsorted(times, s + 2.0)
            if m < len(times) and times[m] <= s + 2.5:
                dist = cKDTree(world[first[m] : last[m]]).query(world[first[k] : last[k]])[0]
                d.append(dist[dist < 2.0])
        errors.append(math.sqrt(np.mean(np.concatenate(d) ** 2)))
    best = int(np.argmin(errors))
    return float(lags[best]), errors[best], errors[int(np.flatnonzero(lags == 0.0)[0])]


def antenna(poses: Array, path: Array, t: Array, xy: Array, good: NDArray[np.bool_]) -> tuple[Array, float, float]:
    """(antenna [forward, left], median residual without it, with it) over 20 s windows fitted rigidly."""
    windows = []
    for a in np.arange(t[good][0], t[good][-1], 20.0):
        m = np.flatnonzero(good & (t >= a) & (t < a + 20.0))
        if len(m) >= 30 and path[m[-1]] - path[m[0]] >= 20.0:
            windows.append(m)

    def residuals(p: Array) -> Array:
        out = []
        for k, m in enumerate(windows):
            phi, tx, ty = p[2 + 3 * k : 5 + 3 * k]
            q = fixed_point(poses[m], p[:2])
            c, s = math.cos(phi), math.sin(phi)
            out.append(np.r_[c * q[:, 0] - s * q[:, 1] + tx - xy[m, 0], s * q[:, 0] + c * q[:, 1] + ty - xy[m, 1]])
        return np.concatenate(out)

    p0 = np.zeros(2 + 3 * len(windows))
    for k, m in enumerate(windows):  # start: each window fitted without an antenna
        pc, gc = poses[m, :2] - poses[m, :2].mean(0), xy[m] - xy[m].mean(0)
        U, _, Vt = np.linalg.svd(pc.T @ gc)
        R = (U @ np.diag([1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt).T
        p0[2 + 3 * k] = math.atan2(R[1, 0], R[0, 0])
        p0[3 + 3 * k : 5 + 3 * k] = xy[m].mean(0) - R @ poses[m, :2].mean(0)
    fit = least_squares(residuals, p0, loss="huber", f_scale=1.0)
    return fit.x[:2], math.sqrt(np.median(residuals(p0) ** 2)), math.sqrt(np.median(fit.fun**2))


def scatter(points: Array, path: Array, t: Array, xy: Array, good: NDArray[np.bool_]) -> tuple[float, float]:
    """(RMS, median) distance of GPS to the antenna's dead reckoning fitted rigidly over 10 s windows."""
    out = []
    for a in np.arange(t[0], t[-1], 10.0):
        m = good & (t >= a) & (t < a + 10.0)
        if m.sum() >= 10 and path[m][-1] - path[m][0] >= 5.0:
            out.append(np.hypot(*_rigid(points[m], xy[m]).T))
    d = np.concatenate(out)
    return math.sqrt(np.mean(d**2)), float(np.median(d))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=DATA, help="the raw Victoria Park folder")
    root = Path(parser.parse_args().data)
    inputs = _table(root / "inputs.dat", ("t", "speed", "steering"))
    scans = _table(root / "measurements.dat", ("t", "range", "bearing", "diameter"))
    gps = _table(root / "gps.dat", ("t", "x", "y"))
    t, xy = gps[:, 0], gps[:, 1:]
    span, step = np.diff(t), np.linalg.norm(np.diff(xy, axis=0), axis=1)
    smooth = (span <= 0.5) & (step <= 10.0 * span + 1e-9)  # the importer's truth rules: no gap, no jump
    good = np.r_[False, smooth] & np.r_[smooth, False] & (t > inputs[0, 0])
    poses, path, _ = _integrate(inputs, t, CAR)
    keep = (scans[:, 1] > 3.0) & (scans[:, 1] < 25.0) & (scans[:, 2] > 0.11) & (scans[:, 2] < 3.09)
    half = 0.5 * (t[0] + t[-1])
    for name, first in (("first half", True), ("second half", False)):
        part = good & ((t < half) if first else (t >= half))
        in_part = (scans[:, 0] < half) if first else (scans[:, 0] >= half)
        lag, err, err0 = gps_delay(inputs, t, xy, part)
        print(f"{name}: GPS delay {lag + 0.0:+.1f} s (speed error {err:.3f} m/s; {err0:.3f} at 0 s)")
        lag, err, err0 = laser_delay(inputs, scans[keep & in_part])
        print(f"{name}: laser delay {lag + 0.0:+.1f} s (tree shift over 2 s {err:.3f} m; {err0:.3f} at 0 s)")
        where, before, after = antenna(poses, path, t, xy, part)
        print(f"{name}: antenna {where[0]:.2f} m ahead, {where[1]:.2f} m left (median residual {before:.3f} -> "
              f"{after:.3f} m)")  # fmt: skip
    rms, median = scatter(fixed_point(poses, GPS_ANTENNA), path, t, xy, good)
    print(f"GPS scatter about dead reckoning over 10 s windows: RMS {rms:.2f} m, median {median:.2f} m")


if __name__ == "__main__":
    main()
