"""Vehicle motion shared by the importers of wheel logs (the raw Victoria Park log, a bag's ``TwistStamped``):
constant-twist integration, the Ackermann conversion of a wheel speed and a steering angle, pose times, and
position truth interpolated at pose times. Pure functions over arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def ackermann(speed: Array, steer: Array, wheelbase: float, encoder_offset: float) -> tuple[Array, Array]:
    """A car's body twist from a wheel speed and the steering angle: forward speed at the rear axle's centre and
    yaw rate, each (n,).

    The speed is measured on a rear wheel ``encoder_offset`` metres left of the axle's centre (0: at the centre):
    ``v_c = v / (1 - tan(steer) H / L)``, ``w = v_c tan(steer) / L``.
    """
    tan = np.tan(steer)
    v = speed / (1.0 - tan * encoder_offset / wheelbase)
    return v, v * tan / wheelbase


def integrate(t_in: Array, v: Array, w: Array, times: Array) -> tuple[Array, Array, Array]:
    """Dead-reckoned poses at ``times`` (N, 3), and path length and turned angle up to each (N,).

    Each twist ``(v, w)`` at ``t_in`` (n,) holds from its time to the next one (zero-order hold); before the
    first one the vehicle stands. Each piece is integrated exactly (an arc).
    """
    edges = np.union1d(t_in, times)
    edges = edges[edges >= min(t_in[0], times[0])]
    k = np.searchsorted(t_in, edges[:-1], side="right") - 1  # twist holding on [edges[i], edges[i+1])
    dt = np.diff(edges)
    vk = np.where(k >= 0, v[np.maximum(k, 0)], 0.0)
    wk = np.where(k >= 0, w[np.maximum(k, 0)], 0.0)
    dtheta = wk * dt
    theta = np.r_[0.0, np.cumsum(dtheta)]
    small = np.abs(dtheta) < 1e-9
    safe = np.where(small, 1.0, dtheta)
    # exact arc in the frame of the segment's start: chord length and direction (half the turn)
    chord = np.where(small, vk * dt, 2.0 * vk * dt * np.sin(safe / 2.0) / safe)
    direction = theta[:-1] + dtheta / 2.0
    x = np.r_[0.0, np.cumsum(chord * np.cos(direction))]
    y = np.r_[0.0, np.cumsum(chord * np.sin(direction))]
    path = np.r_[0.0, np.cumsum(np.abs(vk) * dt)]
    turn = np.r_[0.0, np.cumsum(np.abs(dtheta))]
    at = np.searchsorted(edges, times)
    return np.stack([x[at], y[at], theta[at]], -1), path[at], turn[at]


def pose_times(start: float, sighting_times: Array, end: float, max_gap: float) -> Array:
    """Pose times (sorted, unique): ``start``, every sighting time, and every ``max_gap`` seconds in the stretches
    between them (so long stretches without sightings still have poses), none after ``end``."""
    times = np.union1d(np.r_[start, sighting_times], [])
    gaps = np.diff(np.r_[times, end])
    fillers = [times[i] + max_gap * np.arange(1, math.ceil(g / max_gap)) for i, g in enumerate(gaps)]
    times = np.union1d(times, np.concatenate(fillers) if fillers else [])
    return times[times <= end]


def variances(ds: Array, da: Array, sigma: Array, per_m: Array, per_rad: float) -> Array:
    """Per-increment variances of ``(dx, dy, dtheta)`` (n, 3): ``sigma^2`` plus ``per_m^2`` per metre driven
    ``ds`` (n,), and for the heading ``per_rad^2`` per radian turned ``da`` (n,)."""
    out = np.square(per_m)[None, :] * ds[:, None] + np.square(sigma)[None, :]
    out[:, 2] += per_rad**2 * da
    return out


def truth_at(fixes: Array, times: Array, max_gap: float, max_speed: float) -> tuple[Array, NDArray[np.bool_]]:
    """Positions ``fixes`` (m, 3: t, x, y) interpolated linearly at ``times`` (N, 2), and which times have one:
    those bracketed by two fixes at most ``max_gap`` seconds apart that imply at most ``max_speed`` (a jump)."""
    t = fixes[:, 0]
    b = np.searchsorted(t, times, side="left")
    a = np.maximum(b - 1, 0)
    b = np.minimum(b, len(t) - 1)
    exact = t[b] == times
    a = np.where(exact, b, a)
    span = t[b] - t[a]
    jump = np.linalg.norm(fixes[b, 1:] - fixes[a, 1:], axis=1)
    ok = (t[a] <= times) & (times <= t[b]) & (span <= max_gap) & (jump <= min(max_speed, 1e300) * span + 1e-9)
    weight = np.where(span > 0, (times - t[a]) / np.where(span > 0, span, 1.0), 0.0)
    positions = fixes[a, 1:] + weight[:, None] * (fixes[b, 1:] - fixes[a, 1:])
    return positions, ok


def start_from_positions(poses: Array, path: Array, truth: Array, covered: NDArray[np.bool_], distance: float) -> Array:
    """A start pose in the frame of position truth: the first covered position, and the heading that turns the
    dead-reckoned displacement over the first ``distance`` metres onto the truth's (zeros when it does not allow
    it). ``poses`` (N, 3) dead-reckoned from the origin, ``path`` (N,) metres driven, ``truth`` (N, 2)."""
    first = np.flatnonzero(covered)
    if len(first) == 0:
        return np.zeros(3)
    a = int(first[0])
    later = np.flatnonzero(covered & (path - path[a] >= distance))
    if len(later) == 0:
        return np.zeros(3)
    b = int(later[0])
    gps_move, dr_move = truth[b] - truth[a], poses[b, :2] - poses[a, :2]
    heading = math.atan2(gps_move[1], gps_move[0]) - math.atan2(dr_move[1], dr_move[0])
    c, s = math.cos(heading), math.sin(heading)
    origin = truth[a] - np.array([c * poses[a, 0] - s * poses[a, 1], s * poses[a, 0] + c * poses[a, 1]])
    return np.array([origin[0], origin[1], math.atan2(s, c)])
