"""Reading whitespace-separated dataset files line by line with file:line errors."""

from __future__ import annotations

import io
import math
import re
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


_DATA_LINE = re.compile(r"^[ \t]*[^\s#]", re.MULTILINE)
_MID_LINE_COMMENT = re.compile(r"^[ \t]*[^\s#][^\n]*#", re.MULTILINE)


def table(path: str | Path, names: tuple[str, ...]) -> np.ndarray:
    """A file of ``len(names)`` numeric columns (blank and ``#`` lines skipped) as an array (rows, columns).

    numpy's C reader parses it (line by line, MRCLAM's 600,000 lines were most of its import's time); a file it
    refuses, or one with a value that is not finite or a comment after data on a line, is read again line by
    line, which names the file, line and column at fault. Both parse a number to the same double (correctly rounded).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
        if _DATA_LINE.search(text) and not _MID_LINE_COMMENT.search(text):
            rows = np.loadtxt(io.StringIO(text), dtype=np.float64, comments="#", ndmin=2)
            if rows.shape[0] and rows.shape[1] == len(names) and np.isfinite(rows).all():
                return rows
    except (OSError, UnicodeDecodeError, ValueError):
        pass
    rows = np.array([numbers(str(p), number, fields, names) for number, fields in numbered_lines(p)])
    if not len(rows):
        raise InputError(str(p), 0, "", "no data rows")
    return rows


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
