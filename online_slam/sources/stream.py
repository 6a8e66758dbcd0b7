"""Stream format v1 (JSON Lines): a lazy validating reader and a writer that round-trips.

Every line is checked (JSON syntax, known type, required fields and shapes, finite numbers, sigma > 0 or a
symmetric positive definite covariance, range > 0, non-decreasing timestamps, observations of an existing
pose); the first bad line raises :class:`~online_slam.errors.InputError` naming ``file:line``, the field and
what was expected. Memory use does not grow with the length of the stream.
"""

from __future__ import annotations

import gzip
import io
import json
import math
import sys
import zlib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

from online_slam.errors import InputError
from online_slam.sources.events import (
    Event,
    Header,
    LandmarkId,
    LandmarkTruth,
    Observation,
    Odometry,
    Start,
    Truth,
)

FORMAT = "online-slam"
VERSION = 1

_FIELDS: dict[str, set[str]] = {
    "header": {"type"},  # free-form: every other field is metadata
    "start": {"type", "t", "pose", "sigma", "cov"},
    "odometry": {"type", "t", "delta", "sigma", "cov"},
    "observation": {"type", "t", "landmark", "range", "bearing", "sigma", "cov"},
    "truth": {"type", "t", "pose"},
    "landmark_truth": {"type", "landmark", "position"},
}


def source_name(path: str | Path) -> str:
    """The name used for a source in messages: the path, or ``<stdin>`` for ``-``."""
    return "<stdin>" if str(path) == "-" else str(path)


def _open_text(path: str | Path) -> IO[str]:
    if str(path) == "-":
        return io.TextIOWrapper(sys.stdin.buffer, encoding="utf-8")
    p = Path(path)
    try:
        if p.suffix == ".gz":
            return gzip.open(p, "rt", encoding="utf-8")
        return p.open("r", encoding="utf-8")
    except OSError as exc:
        raise InputError(str(path), 0, "", f"cannot open: {exc.strerror or exc}") from None


def read_stream(path: str | Path) -> Iterator[Event]:
    """Read a stream v1 file lazily.

    Args:
        path: A ``.jsonl`` path, a ``.gz`` path, or ``-`` for standard input.

    Yields:
        Events in file order.

    Raises:
        InputError: On the first bad line (or an unreadable/truncated file).
    """
    name = source_name(path)
    handle = _open_text(path)
    validator = _Validator(name)
    number = 0
    try:
        with handle:
            while True:
                try:
                    line = handle.readline()
                except (EOFError, OSError, zlib.error) as exc:
                    raise InputError(name, number + 1, "", f"truncated or corrupt gzip data ({exc})") from None
                except UnicodeDecodeError as exc:
                    raise InputError(name, number + 1, "", f"not UTF-8 text ({exc.reason})") from None
                if not line:
                    return
                number += 1
                if not line.strip():
                    continue
                event = validator.parse(line, number)
                if event is not None:
                    yield event
    finally:
        handle.close()


def write_stream(destination: str | Path | IO[str], events: Iterable[Event]) -> int:
    """Write events as stream v1.

    Args:
        destination: A path (``.gz`` compresses), ``-`` for standard output, or an open text file.
        events: Events to write, in order.

    Returns:
        Number of lines written.
    """
    if hasattr(destination, "write"):
        return _write_lines(destination, events)  # type: ignore[arg-type]
    if str(destination) == "-":
        return _write_lines(sys.stdout, events)
    p = Path(destination)
    opener = gzip.open if p.suffix == ".gz" else open
    with opener(p, "wt", encoding="utf-8") as handle:  # type: ignore[operator]
        return _write_lines(handle, events)


def _write_lines(handle: IO[str], events: Iterable[Event]) -> int:
    count = 0
    for event in events:
        handle.write(json.dumps(event.to_record(), allow_nan=False, separators=(", ", ": ")))
        handle.write("\n")
        count += 1
    return count


class _Validator:
    """Checks one line at a time and keeps the little state that cross-line rules need."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.last_t = -math.inf
        self.first_pose_t: float | None = None
        self.seen_content = False

    def fail(self, line: int, field: str, message: str) -> InputError:
        return InputError(self.name, line, field, message)

    def parse(self, text: str, line: int) -> Event | None:
        try:
            record = json.loads(text)
        except json.JSONDecodeError as exc:
            raise self.fail(line, "", f"invalid JSON ({exc.msg} at column {exc.colno})") from None
        if not isinstance(record, dict):
            raise self.fail(line, "", "expected a JSON object")
        kind = record.get("type")
        if kind not in _FIELDS:
            expected = ", ".join(sorted(_FIELDS))
            raise self.fail(line, "type", f"unknown event type {kind!r}; expected one of {expected}")
        if kind != "header":
            unknown = set(record) - _FIELDS[kind]
            if unknown:
                raise self.fail(line, sorted(unknown)[0], f"unknown field for a {kind} event")
        return getattr(self, f"_{kind}")(record, line)

    # -- field helpers -------------------------------------------------------------------------
    def number(self, record: dict[str, Any], key: str, line: int) -> float:
        if key not in record:
            raise self.fail(line, key, "missing required field")
        value = record[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(line, key, f"expected a number, got {json.dumps(value)}")
        if not math.isfinite(value):
            raise self.fail(line, key, f"expected a finite number, got {value}")
        return float(value)

    def vector(self, record: dict[str, Any], key: str, n: int, line: int) -> tuple[float, ...]:
        if key not in record:
            raise self.fail(line, key, "missing required field")
        value = record[key]
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(line, key, f"expected a list of {n} numbers, got {json.dumps(value)}")
        out = []
        for i, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, (int, float)):
                raise self.fail(line, f"{key}[{i}]", f"expected a number, got {json.dumps(item)}")
            if not math.isfinite(item):
                raise self.fail(line, f"{key}[{i}]", f"expected a finite number, got {item}")
            out.append(float(item))
        return tuple(out)

    def noise(
        self, record: dict[str, Any], n: int, line: int, required: bool = True
    ) -> tuple[tuple[float, ...] | None, tuple[tuple[float, ...], ...] | None]:
        has_sigma, has_cov = "sigma" in record, "cov" in record
        if has_sigma and has_cov:
            raise self.fail(line, "cov", "give either sigma or cov, not both")
        if has_sigma:
            sigma = self.vector(record, "sigma", n, line)
            for i, s in enumerate(sigma):
                if s <= 0.0:
                    raise self.fail(line, f"sigma[{i}]", f"expected a standard deviation > 0, got {s}")
            return sigma, None
        if has_cov:
            value = record["cov"]
            if not isinstance(value, list) or len(value) != n or not all(isinstance(r, list) for r in value):
                raise self.fail(line, "cov", f"expected a {n}x{n} list of lists, got {json.dumps(value)}")
            rows = tuple(self.vector({"cov": row}, "cov", n, line) for row in value)
            matrix = np.array(rows)
            scale = max(float(np.max(np.abs(matrix))), 1e-300)
            if not np.allclose(matrix, matrix.T, rtol=0.0, atol=1e-9 * scale):
                raise self.fail(line, "cov", "expected a symmetric matrix")
            try:
                np.linalg.cholesky(matrix)
            except np.linalg.LinAlgError:
                raise self.fail(line, "cov", "expected a positive definite covariance") from None
            return None, rows
        if required:
            raise self.fail(line, "sigma", "missing noise: give sigma or cov")
        return None, None

    def time(self, record: dict[str, Any], line: int) -> float:
        t = self.number(record, "t", line)
        if t < self.last_t:
            raise self.fail(line, "t", f"time goes backwards ({t} after {self.last_t}); expected non-decreasing")
        self.last_t = t
        if self.first_pose_t is None:
            self.first_pose_t = t
        elif t < self.first_pose_t:
            raise self.fail(line, "t", f"no pose exists at t={t}: the first pose is at t={self.first_pose_t}")
        self.seen_content = True
        return t

    def landmark(self, record: dict[str, Any], line: int) -> LandmarkId:
        if "landmark" not in record:
            raise self.fail(line, "landmark", "missing required field")
        value = record["landmark"]
        if isinstance(value, bool) or not isinstance(value, (int, str)) or value == "":
            raise self.fail(line, "landmark", f"expected an integer or a non-empty string id, got {json.dumps(value)}")
        return value

    # -- one method per event type -------------------------------------------------------------
    def _header(self, record: dict[str, Any], line: int) -> Header:
        if self.seen_content:
            raise self.fail(line, "type", "a header must be the first line")
        if record.get("format", FORMAT) != FORMAT:
            raise self.fail(line, "format", f"expected {FORMAT!r}, got {json.dumps(record.get('format'))}")
        version = record.get("version", VERSION)
        if version != VERSION or isinstance(version, bool):
            raise self.fail(line, "version", f"unsupported version {json.dumps(version)}; this reader knows 1")
        name = record.get("name")
        if name is not None and not isinstance(name, str):
            raise self.fail(line, "name", f"expected a string, got {json.dumps(name)}")
        meta = {k: v for k, v in record.items() if k not in {"type", "format", "version", "name"}}
        self.seen_content = True
        return Header(name=name, meta=meta, version=VERSION)

    def _start(self, record: dict[str, Any], line: int) -> Start:
        if self.first_pose_t is not None:
            raise self.fail(line, "type", "start must come before every timed event")
        t = self.time(record, line)
        pose = self.vector(record, "pose", 3, line)
        sigma, cov = self.noise(record, 3, line, required=False)
        return Start(t=t, pose=pose, sigma=sigma, cov=cov)

    def _odometry(self, record: dict[str, Any], line: int) -> Odometry:
        t = self.time(record, line)
        delta = self.vector(record, "delta", 3, line)
        sigma, cov = self.noise(record, 3, line)
        return Odometry(t=t, delta=delta, sigma=sigma, cov=cov)

    def _observation(self, record: dict[str, Any], line: int) -> Observation:
        t = self.time(record, line)
        landmark = self.landmark(record, line)
        rng = self.number(record, "range", line)
        if rng <= 0.0:
            raise self.fail(line, "range", f"expected a range > 0, got {rng}")
        bearing = self.number(record, "bearing", line)
        sigma, cov = self.noise(record, 2, line)
        return Observation(t=t, landmark=landmark, range=rng, bearing=bearing, sigma=sigma, cov=cov)

    def _truth(self, record: dict[str, Any], line: int) -> Truth:
        t = self.time(record, line)
        return Truth(t=t, pose=self.vector(record, "pose", 3, line))

    def _landmark_truth(self, record: dict[str, Any], line: int) -> LandmarkTruth:
        landmark = self.landmark(record, line)
        self.seen_content = True
        return LandmarkTruth(landmark=landmark, position=self.vector(record, "position", 2, line))
