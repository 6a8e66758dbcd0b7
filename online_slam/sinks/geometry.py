"""Drawing helpers shared by the sinks and plots (pure)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def ellipses(means: Array, covariances: Array, sigmas: float = 2.0, points: int = 24) -> Array:
    """Closed polylines of ``sigmas``-sigma ellipses.

    Args:
        means: Centres, shape (M, 2).
        covariances: 2x2 position covariances, shape (M, 2, 2).
        sigmas: Scale of the ellipse.
        points: Vertices per ellipse (the first is repeated at the end).

    Returns:
        Shape (M, points + 1, 2).
    """
    values, vectors = np.linalg.eigh(0.5 * (covariances + np.swapaxes(covariances, 1, 2)))
    radii = sigmas * np.sqrt(np.clip(values, 0.0, None))  # (M, 2)
    angle = np.linspace(0.0, 2.0 * np.pi, points + 1)
    unit = np.stack([np.cos(angle), np.sin(angle)], -1)  # (P, 2)
    return means[:, None, :] + np.einsum("mij,mj,pj->mpi", vectors, radii, unit)
