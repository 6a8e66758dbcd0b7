"""A pose's Gaussian belief read as what it is in the plane: the second moment of a curved ("banana") error.

A linearized estimator holds a pose's uncertainty as a 3x3 covariance ``P`` whose position part is correlated with
the heading: ``P_ptheta = sigma^2 w``, one radian of heading error moving the position by ``w``. That correlation is
a turn about a pivot ``c`` at lever ``l = p - c`` with ``J l = w`` (``J``: +90 degrees), and a turn moves the position
on an arc, not along the line ``w``: ``p(a) = c + R(a) l``. Read as Gaussian in exponential coordinates about that
pivot (Long et al., "The banana distribution is Gaussian", RSS 2012), the error of ``x = [p, theta]`` from the
estimate is

    d(a, v) = [(R(a) - I) l + V(a) v, a],    a ~ N(0, sigma^2),  v ~ N(0, S),  S = P_pp - sigma^2 w w^T

(``V(a)``: SE(2)'s left Jacobian; ``v`` independent of ``a`` by construction), whose second moment about the estimate
``E[d d^T]`` is reported instead of ``P``. To first order in ``a`` it is ``P``; it adds about ``0.75 |l|^2 sigma^4`` of
variance along the lever, which matters where a thin position covariance meets a heading that is uncertain far
from its pivot (esde's circle world; the figures are in benchmarks/RESULTS.md, "Curved pose covariances").
The pivot comes from ``P`` itself, so the result does not depend on the frame's origin.

Its expectations over ``a`` have closed forms (``E[cos a] = exp(-sigma^2 / 2)``, and ``E[(1 - cos a) / a^2]`` through
``erf``); ``v`` enters linearly.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def _g(sigma: float) -> float:
    """``E[(1 - cos a) / a^2]`` for ``a ~ N(0, sigma^2)``: ``int_0^1 (1 - t) exp(-t^2 sigma^2 / 2) dt``."""
    return math.sqrt(math.pi / 2.0) / sigma * math.erf(sigma / math.sqrt(2.0)) + math.expm1(-0.5 * sigma**2) / sigma**2


def _curved(P: Array) -> Array:
    """:func:`curved_covariance` of one (3, 3) covariance with a positive heading variance (closed form)."""
    s2 = float(P[2, 2])
    s = math.sqrt(s2)
    wx, wy = float(P[0, 2]) / s2, float(P[1, 2]) / s2
    lx, ly = wy, -wx  # the lever l, J l = w
    sxx, sxy, syy = P[0, 0] - s2 * wx * wx, P[0, 1] - s2 * wx * wy, P[1, 1] - s2 * wy * wy  # S
    c1, c2 = math.exp(-0.5 * s2), math.exp(-2.0 * s2)  # E[cos a], E[cos 2a]
    g1, g2 = _g(s), _g(2.0 * s)
    # In complex numbers: (R(a) - I) l = (e^ia - 1) l and V(a) v = nu(a) v with nu = (e^ia - 1) / (i a); a 2x2
    # second moment is |z|^2 / 2 I plus the traceless part of z^2 / 2 (and likewise for nu S nu^*).
    iso = (1.0 - c1) * (lx * lx + ly * ly) + g1 * (sxx + syy)  # E|e^ia - 1|^2 = 2 - 2 c1, E|nu|^2 = 2 g1
    turn2, nu2 = c2 - 2.0 * c1 + 1.0, 4.0 * g2 - 2.0 * g1  # E[(e^ia - 1)^2], E[nu^2] (both real)
    dr = 0.5 * turn2 * (lx * lx - ly * ly) + nu2 * 0.5 * (sxx - syy)
    di = turn2 * lx * ly + nu2 * sxy
    return np.array(
        [
            [iso + dr, di, s2 * c1 * wx],  # E[a (e^ia - 1)] l = i sigma^2 c1 l = sigma^2 c1 w
            [di, iso - dr, s2 * c1 * wy],
            [s2 * c1 * wx, s2 * c1 * wy, s2],
        ]
    )


def curved_covariance(cov: ArrayLike) -> Array:
    """The second moment about the estimate of a pose belief ``cov`` read as curved (module docstring).

    Args:
        cov: Pose covariances ``[x, y, theta]``, shape (..., 3, 3), symmetric positive semi-definite.

    Returns:
        Their curved second moments, shape (..., 3, 3): the same heading variance, the heading-position
        covariance times ``exp(-sigma^2 / 2)``, position variance added along the lever and a relative ``sigma^2``
        taken across it. A heading variance of 0 (or a covariance not finite) is returned unchanged.
    """
    P = np.array(cov, dtype=float)
    flat = P.reshape(-1, 3, 3)
    for k in range(len(flat)):  # one per step in use; stacks are for analysis
        if np.isfinite(flat[k]).all() and flat[k, 2, 2] > 1e-18:
            flat[k] = _curved(flat[k])
    return P


def reported(cov: Array, shape: str) -> Array:
    """A pose covariance (3, 3) as an estimator reports it: ``curved`` (:func:`curved_covariance`) or ``linear``
    (a copy)."""
    return curved_covariance(cov) if shape == "curved" else np.array(cov, dtype=float)
