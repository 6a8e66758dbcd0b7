"""The package's exceptions: one base, and the input error that names file, line and field."""

from __future__ import annotations


class OnlineSlamError(Exception):
    """Base of every error this package raises on purpose."""


class InputError(OnlineSlamError):
    """A bad input line: names the file, the line number, the field and what was expected.

    Attributes:
        source: File name (or ``<stdin>``) the line came from.
        line: 1-based line number, or 0 when the error is not tied to one line.
        field: The offending field (``""`` when the whole line is at fault).
        message: What was wrong and what was expected.
    """

    def __init__(self, source: str, line: int, field: str, message: str) -> None:
        self.source = source
        self.line = line
        self.field = field
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.source}:{self.line}" if self.line else self.source
        what = f"{self.field}: {self.message}" if self.field else self.message
        return f"{where}: {what}"


class ConfigError(OnlineSlamError, ValueError):
    """A setting out of range, an unknown option or estimator name."""
