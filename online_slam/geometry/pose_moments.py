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

The expectation over ``a`` is a Gauss-Hermite rule (:data:`NODES` nodes; exact for ``v``, which enters linearly).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

NODES = 12
"""Gauss-Hermite nodes of the expectation over the heading error (the arc's moments to ~1e-12 for sigma <= 1)."""
_X, _W = np.polynomial.hermite.hermgauss(NODES)
_W = _W / np.sqrt(np.pi)


def curved_covariance(cov: ArrayLike) -> Array:
    """The second moment about the estimate of a pose belief ``cov`` read as curved (module docstring).

    Args:
        cov: Pose covariances ``[x, y, theta]``, shape (..., 3, 3), symmetric positive semi-definite.

    Returns:
        Their curved second moments, shape (..., 3, 3): the same heading variance and heading-position
        covariance to first order, more position variance along the lever. A heading variance of 0 (or not
        finite covariances) returns ``cov`` unchanged.
    """
    P = np.array(cov, dtype=float)
    var = P[..., 2, 2]
    ok = np.isfinite(P).all(axis=(-2, -1)) & (var > 1e-18)
    if not ok.any():
        return P
    Q = P[ok]
    s2 = Q[:, 2, 2]
    w = Q[:, :2, 2] / s2[:, None]  # position per radian of heading, (k, 2)
    lever = np.stack([w[:, 1], -w[:, 0]], -1)  # l = p - c with J l = w
    S = Q[:, :2, :2] - s2[:, None, None] * w[:, :, None] * w[:, None, :]
    S = 0.5 * (S + S.transpose(0, 2, 1))
    a = np.sqrt(2.0 * s2)[:, None] * _X[None, :]  # (k, n) heading errors at the nodes
    c, s = np.cos(a), np.sin(a)
    small = np.abs(a) < 1e-6
    safe = np.where(small, 1.0, a)
    v1 = np.where(small, 1.0 - a**2 / 6.0, s / safe)  # V(a) = [[v1, -v2], [v2, v1]]
    v2 = np.where(small, a / 2.0, (1.0 - c) / safe)
    # (R(a) - I) l, shape (k, n, 2)
    turn = np.stack(
        [(c - 1.0) * lever[:, None, 0] - s * lever[:, None, 1], s * lever[:, None, 0] + (c - 1.0) * lever[:, None, 1]],
        -1,
    )
    V = np.stack([np.stack([v1, -v2], -1), np.stack([v2, v1], -1)], -2)  # (k, n, 2, 2)
    moved = np.einsum("n,kni,knj->kij", _W, turn, turn) + np.einsum("n,knia,kab,knjb->kij", _W, V, S, V)
    cross = np.einsum("n,kn,kni->ki", _W, a, turn)
    M = np.empty_like(Q)
    M[:, :2, :2] = 0.5 * (moved + moved.transpose(0, 2, 1))
    M[:, :2, 2] = M[:, 2, :2] = cross
    M[:, 2, 2] = s2
    P[ok] = M
    return P


def reported(cov: Array, shape: str) -> Array:
    """A pose covariance (3, 3) as an estimator reports it: ``curved`` (:func:`curved_covariance`) or ``linear``
    (a copy)."""
    return curved_covariance(cov) if shape == "curved" else np.array(cov, dtype=float)
