"""The package's exceptions: one base, and the input error that names file, line and field.

:class:`InputError` and :class:`ConfigError` are also ``ValueError``s: a caller catching bad values the Python way
catches them too.
"""

from __future__ import annotations


class OnlineSlamError(Exception):
    """Base of every error this package raises on purpose."""


class InputError(OnlineSlamError, ValueError):
    """A bad input line or call: names the file (or method), the line number, the field and what was expected.

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

    @property
    def reason(self) -> str:
        """A short category of the error, for counts of skipped lines (e.g. ``time_order``, ``not_finite``)."""
        message, field = self.message, self.field
        rules = (
            (message.startswith("late by"), "late"),
            (message.startswith("invalid JSON"), "invalid_json"),
            (message.startswith("expected a JSON object"), "not_an_object"),
            (message.startswith("unknown event type"), "unknown_type"),
            (message.startswith("unknown field"), "unknown_field"),
            (message.startswith("missing"), "missing_field"),
            ("a finite number" in message, "not_finite"),
            ("magnitude" in message or "in degrees?" in message, "out_of_range"),
            ("range > 0" in message, "range_not_positive"),
            (field.startswith(("sigma", "cov")), "bad_noise"),
            (field == "t", "time_order"),
            (field in ("type", "format", "version"), "out_of_order"),
            ("gzip" in message or "UTF-8" in message, "corrupt_data"),
            (message.startswith("cut line"), "cut_line"),
        )
        return next((name for hit, name in rules if hit), "wrong_value")

    def __str__(self) -> str:
        where = f"{self.source}:{self.line}" if self.line else self.source
        what = f"{self.field}: {self.message}" if self.field else self.message
        return f"{where}: {what}"


class LateInput(InputError):
    """A line older than the newest one by more than the latency budget (``--max-latency``): skipped and counted,
    never an end of the run."""


class ConfigError(OnlineSlamError, ValueError):
    """A setting out of range, an unknown option or estimator name."""
