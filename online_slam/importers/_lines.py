"""Reading whitespace-separated dataset files line by line with file:line errors."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from online_slam.errors import InputError


def numbered_lines(path: str | Path, comment: str = "#") -> Iterator[tuple[int, list[str]]]:
    """Yield (line number, fields) of every non-blank, non-comment line."""
    p = Path(path)
    try:
        handle = p.open("r", encoding="utf-8", errors="strict")
    except OSError as exc:
        raise InputError(str(p), 0, "", f"cannot open: {exc.strerror or exc}") from None
    with handle:
        try:
            for number, line in enumerate(handle, 1):
                text = line.strip()
                if text and not text.startswith(comment):
                    yield number, text.split()
        except UnicodeDecodeError as exc:
            raise InputError(str(p), 0, "", f"not UTF-8 text ({exc.reason})") from None


def numbers(source: str, line: int, fields: list[str], names: tuple[str, ...]) -> list[float]:
    """Parse fields as finite floats, naming the column that is wrong."""
    if len(fields) != len(names):
        raise InputError(source, line, "", f"expected {len(names)} columns ({' '.join(names)}), got {len(fields)}")
    out = []
    for name, text in zip(names, fields):
        try:
            value = float(text)
        except ValueError:
            raise InputError(source, line, name, f"expected a number, got {text!r}") from None
        if not math.isfinite(value):
            raise InputError(source, line, name, f"expected a finite number, got {text!r}")
        out.append(value)
    return out


def covariance_from(
    source: str, line: int, field: str, matrix: np.ndarray, information: bool = False
) -> tuple[tuple[float, ...], ...]:
    """A covariance (inverted when ``information``) as stream-v1 tuples, or a one-line error if not PD."""
    try:
        cov = np.linalg.inv(matrix) if information else np.asarray(matrix, dtype=float)
        cov = 0.5 * (cov + cov.T)
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        what = "information matrix" if information else "noise"
        raise InputError(source, line, field, f"{what} is not positive definite") from None
    return tuple(map(tuple, cov))
