"""The process's BLAS held to one thread while an estimator works (benchmarks/RESULTS.md, "The EKF's BLAS on one
thread")."""

from __future__ import annotations

from typing import Any

from threadpoolctl import ThreadpoolController


class OneThreadBlas:
    """A handle on the process's BLAS libraries: :meth:`limit` holds them to one thread. A copy of an estimator
    shares its handle: the libraries are the process's, not the estimator's."""

    def __init__(self) -> None:
        self._controller = ThreadpoolController()

    def limit(self) -> Any:
        """Context manager: BLAS on one thread inside it."""
        return self._controller.limit(limits=1, user_api="blas")

    def __deepcopy__(self, memo: dict[int, Any]) -> OneThreadBlas:
        return self
