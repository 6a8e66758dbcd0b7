"""Lazy re-exports for a package's ``__init__``: a public name is imported from its module on first use.

So that a configuration module (``online_slam.estimators.ekf_config``) imports without its package's heavy
modules (scipy, filterpy, qdldl): ``--help`` and the option table read the configurations' defaults directly.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, homes: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``: each name of ``homes`` is read from its module on first use, a
    subpackage's name imports it (``online_slam.sources``), and ``dir()`` lists the public API (``__all__``) only."""
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name: str) -> Any:
        if name not in homes:
            if importlib.util.find_spec(f"{package}.{name}") is None:
                raise AttributeError(f"module {package!r} has no attribute {name!r}")
            return importlib.import_module(f"{package}.{name}")
        value = getattr(importlib.import_module(homes[name]), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(namespace.get("__all__", homes))

    return __getattr__, __dir__
