"""Shared test helpers: numerical Jacobians and the shared data folder."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from online_slam.geometry import wrap

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def numerical_jacobian(
    f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, angle_outputs: tuple[int, ...] = (), eps: float = 1e-6
) -> np.ndarray:
    """Central-difference Jacobian of f at x; angle outputs are differenced through wrap()."""
    x = np.asarray(x, dtype=float)
    columns = []
    for k in range(x.size):
        step = np.zeros_like(x)
        step.flat[k] = eps
        diff = np.asarray(f(x + step)) - np.asarray(f(x - step))
        for i in angle_outputs:
            diff[..., i] = wrap(diff[..., i])
        columns.append(diff / (2 * eps))
    return np.stack(columns, axis=-1)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
