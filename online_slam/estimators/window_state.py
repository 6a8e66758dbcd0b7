"""The sliding-window smoother's window factors as stacked arrays, and back (for checkpoints)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
Index = NDArray[np.int64]


def pack_odometry(factors: dict[int, tuple[Array, Array, Array]]) -> dict[str, Any]:
    """Window odometry factors (delta, cov, sqrt-information) as stacked arrays (for checkpoints)."""
    rows = list(factors.values())
    return {
        "poses": np.array(list(factors), dtype=np.int64),
        "delta": np.array([r[0] for r in rows]).reshape(-1, 3),
        "cov": np.array([r[1] for r in rows]).reshape(-1, 3, 3),
        "sqrt_info": np.array([r[2] for r in rows]).reshape(-1, 3, 3),
    }


def unpack_odometry(state: dict[str, Any]) -> dict[int, tuple[Array, Array, Array]]:
    """The window odometry factors from :func:`pack_odometry`'s arrays (copies), keyed by pose."""
    parts = [np.array(state[k], dtype=float) for k in ("delta", "cov", "sqrt_info")]
    return {int(i): (parts[0][k].copy(), parts[1][k].copy(), parts[2][k].copy()) for k, i in enumerate(state["poses"])}


def pack_observations(factors: dict[int, tuple[Index, Array, Array, Array]]) -> dict[str, Any]:
    """Window observation factors (landmarks, z, cov, sqrt-information) concatenated (for checkpoints)."""
    rows = list(factors.values())

    def cat(k: int, shape: tuple[int, ...], dtype: type) -> np.ndarray:
        return np.concatenate([r[k] for r in rows]) if rows else np.zeros((0, *shape), dtype=dtype)

    return {
        "poses": np.array(list(factors), dtype=np.int64),
        "sizes": np.array([len(r[0]) for r in rows], dtype=np.int64),
        "landmarks": cat(0, (), np.int64),
        "z": cat(1, (2,), float),
        "cov": cat(2, (2, 2), float),
        "sqrt_info": cat(3, (2, 2), float),
    }


def unpack_observations(state: dict[str, Any]) -> dict[int, tuple[Index, Array, Array, Array]]:
    """The window observation factors from :func:`pack_observations`'s arrays (copies), keyed by pose."""
    cuts = np.cumsum(np.array(state["sizes"], dtype=np.int64))[:-1]
    landmarks = np.split(np.array(state["landmarks"], dtype=np.int64), cuts)
    z, cov, w = (np.split(np.array(state[k], dtype=float), cuts) for k in ("z", "cov", "sqrt_info"))
    return {
        int(i): (landmarks[k].copy(), z[k].copy(), cov[k].copy(), w[k].copy()) for k, i in enumerate(state["poses"])
    }
