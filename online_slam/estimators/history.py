"""A record of poses that no longer change in the window, readable without copying."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class PoseHistory:
    """Poses in order, appended once (amortized O(1) per append), rewritten only as a whole (:meth:`replace`).

    :meth:`view` returns a read-only view of the rows so far; later appends and replacements never change those
    rows (a growth or a replacement moves to a new buffer, and an old view keeps the old one), so a view is a
    valid snapshot for as long as it lives. A checkpoint holds its rows (:meth:`to_tree`, :meth:`from_tree`).
    """

    def __init__(self, rows: Array | None = None) -> None:
        rows = np.zeros((0, 3)) if rows is None else np.asarray(rows, dtype=float).reshape(-1, 3)
        self._buffer = np.empty((max(64, 2 * len(rows)), 3))
        self._buffer[: len(rows)] = rows
        self._n = len(rows)

    def __len__(self) -> int:
        return self._n

    def append(self, pose: Array) -> None:
        """Add the next pose, shape (3,)."""
        if self._n == len(self._buffer):
            grown = np.empty((2 * len(self._buffer), 3))
            grown[: self._n] = self._buffer[: self._n]
            self._buffer = grown
        self._buffer[self._n] = pose
        self._n += 1

    def view(self) -> Array:
        """The poses so far, shape (N, 3), read-only, without a copy."""
        out = self._buffer[: self._n]
        out.flags.writeable = False
        return out

    def to_tree(self) -> Array:
        """Its state for a checkpoint: the rows, shape (N, 3)."""
        return self._buffer[: self._n]

    @classmethod
    def from_tree(cls, tree: Array) -> PoseHistory:
        """The history holding a checkpoint's rows."""
        if not isinstance(tree, np.ndarray):
            raise TypeError(f"expected the rows of a pose history, got {type(tree).__name__}")
        return cls(tree)

    def replace(self, rows: Array) -> None:
        """Rewrite every pose at once (a global relinearization revised them), shape (N, 3), N = len(self)."""
        rows = np.asarray(rows, dtype=float).reshape(-1, 3)
        if len(rows) != self._n:
            raise ValueError(f"expected {self._n} poses, got {len(rows)}")
        buffer = np.empty_like(self._buffer)  # earlier views keep the old buffer
        buffer[: self._n] = rows
        self._buffer = buffer
