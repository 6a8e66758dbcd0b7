"""Property-based fuzzing of the stream reader and the engine API (hypothesis).

Three kinds of input: arbitrary bytes as a stream file (plain or gzip), arbitrary JSON values as lines, and
valid events with one field perturbed (given to the reader as lines and to :class:`~online_slam.slam.Slam` as
calls; what is accepted is estimated and queried). The property: only :class:`~online_slam.errors.InputError`
(or a clean skip with ``on_error``) ever comes out, never another exception, and every case ends.
"""

from __future__ import annotations

import gzip
import json
import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from online_slam.errors import InputError
from online_slam.slam import Slam
from online_slam.sources.stream import read_stream

VALID_LINES = [
    {"type": "header", "format": "online-slam", "version": 1, "name": "fuzz"},
    {"type": "start", "t": 0.0, "pose": [0.0, 0.0, 0.0]},
    {"type": "observation", "t": 0.0, "landmark": 1, "range": 2.0, "bearing": 0.5, "sigma": [0.1, 0.01]},
    {"type": "odometry", "t": 1.0, "delta": [1.0, 0.0, 0.1], "sigma": [0.1, 0.1, 0.01]},
    {"type": "observation", "t": 1.0, "landmark": "a", "range": 3.0, "bearing": -0.4, "cov": [[0.01, 0], [0, 1e-4]]},
    {"type": "truth", "t": 1.0, "pose": [1.0, 0.0, 0.1]},
    {"type": "landmark_truth", "landmark": 1, "position": [1.7, 1.0]},
    {"type": "odometry", "t": 2.0, "delta": [1.0, 0.1, -0.1], "cov": [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 1e-4]]},
    {"type": "observation", "t": 2.0, "landmark": 1, "range": 1.2, "bearing": 1.1, "sigma": [0.1, 0.01]},
]
"""A small valid stream whose lines the perturbation cases start from."""


@dataclass(frozen=True)
class FuzzReport:
    """How many cases each property ran, and what came out."""

    cases: dict[str, int]
    """Cases run per property."""
    input_errors: dict[str, int]
    """Cases that raised InputError (the expected refusal), per property."""

    @property
    def total(self) -> int:
        """All cases."""
        return sum(self.cases.values())


def _strategies() -> dict[str, Any]:
    from hypothesis import strategies as st

    scalars = st.one_of(
        st.none(),
        st.booleans(),
        st.integers(min_value=-(10**30), max_value=10**30),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([0.0, -0.0, 1e-300, 5e-324, 1e-7, 1e9, -1e9, 1e10, 1e308, 2**63, -(2**63)]),
        st.text(max_size=8),
    )
    json_values = st.recursive(
        scalars,
        lambda children: st.lists(children, max_size=5) | st.dictionaries(st.text(max_size=6), children, max_size=5),
        max_leaves=20,
    )
    return {"scalars": scalars, "json": json_values}


@dataclass
class _Tally:
    """Cases run and InputErrors seen so far, per property (filled while hypothesis runs)."""

    cases: dict[str, int] = field(default_factory=dict)
    """Cases run per property."""
    refused: dict[str, int] = field(default_factory=dict)
    """Cases that raised InputError, per property."""

    def count(self, name: str, outcome: Callable[[], Any]) -> None:
        """Run one case; InputError is the expected refusal, anything else propagates."""
        self.cases[name] = self.cases.get(name, 0) + 1
        try:
            outcome()
        except InputError:
            self.refused[name] = self.refused.get(name, 0) + 1


def _read_all(path: Path, skip: bool) -> None:
    list(read_stream(path, (lambda error: None) if skip else None))


def _file_properties(folder: Path, tally: _Tally, profile: Callable) -> list[Callable[[], None]]:
    """The reader's properties: arbitrary bytes, arbitrary JSON lines, valid lines with one field perturbed."""
    from hypothesis import given
    from hypothesis import strategies as st

    s = _strategies()

    @profile
    @given(data=st.binary(max_size=400), compress=st.booleans(), skip=st.booleans())
    def arbitrary_bytes(data: bytes, compress: bool, skip: bool) -> None:
        path = folder / ("bytes.jsonl.gz" if compress else "bytes.jsonl")
        path.write_bytes(gzip.compress(data) if compress and data[:1] != b"\x00" else data)
        tally.count("bytes", lambda: _read_all(path, skip))

    @profile
    @given(values=st.lists(s["json"], min_size=1, max_size=6), skip=st.booleans())
    def arbitrary_json(values: list, skip: bool) -> None:
        path = folder / "json.jsonl"
        path.write_text("\n".join(json.dumps(v) for v in values) + "\n")
        tally.count("json", lambda: _read_all(path, skip))

    @profile
    @given(data=st.data())
    def perturbed_lines(data: st.DataObject) -> None:
        lines = [dict(r) for r in VALID_LINES]
        k = data.draw(st.integers(0, len(lines) - 1))
        keys = sorted(lines[k]) + ["extra"]
        key = data.draw(st.sampled_from(keys))
        lines[k][key] = data.draw(s["json"])
        path = folder / "perturbed.jsonl"
        path.write_text("\n".join(json.dumps(r) for r in lines) + "\n")
        skip = data.draw(st.booleans())
        tally.count("perturbed lines", lambda: _read_all(path, skip))

    return [arbitrary_bytes, arbitrary_json, perturbed_lines]


def _api_call(slam: Slam, kind: str, t: float, value: Callable[[Any], Any]) -> Callable[[], Any]:
    """One call of the engine API, each argument passed through ``value`` (which may perturb it)."""
    if kind == "odometry":
        return partial(
            slam.add_odometry, value(t), [value(0.5), value(0.0), value(0.1)],
            sigma=[value(0.1), value(0.1), value(0.01)],
        )  # fmt: skip
    if kind == "observation":
        return partial(slam.add_observation, value(t), value(1), value(2.0), value(0.3), [value(0.1), value(0.01)])
    if kind == "scan":
        return partial(
            slam.add_observations, value(t), [value(1), value(2)], [value(2.0), value(3.0)],
            [value(0.3), value(-0.2)], sigma=[value(0.1), value(0.01)],
        )  # fmt: skip
    if kind == "start":
        return partial(slam.start, value(t), [value(0.0), value(0.0), value(0.0)])
    return slam.estimate


def _engine_api_property(tally: _Tally, profile: Callable) -> Callable[[], None]:
    """The engine API's property: a few calls, some arguments perturbed; what is accepted is estimated."""
    from hypothesis import given
    from hypothesis import strategies as st

    numbers = st.one_of(
        st.floats(min_value=-1e9, max_value=1e9), st.sampled_from([1e-6, 1e-8, 1e8, 1e9, 0.5]), _strategies()["scalars"]
    )

    @profile
    @given(data=st.data())
    def engine_api(data: st.DataObject) -> None:
        slam = Slam(data.draw(st.sampled_from(["ekf", "smoother"])))
        t = 0.0
        for _ in range(data.draw(st.integers(1, 10))):
            kind = data.draw(st.sampled_from(["odometry", "observation", "scan", "start", "estimate"]))
            t += data.draw(st.sampled_from([0.0, 0.5, 1.0]))
            perturbed = data.draw(st.booleans())

            def value(default: Any, perturbed: bool = perturbed) -> Any:
                return data.draw(numbers) if perturbed and data.draw(st.booleans()) else default

            tally.count("engine API", _api_call(slam, kind, t, value))
        tally.count("engine API", slam.estimate)
        if slam.poses:
            assert all(math.isfinite(v) for v in slam.estimate().pose)

    return engine_api


def run_fuzz(examples: int = 200, seed: int | None = None) -> FuzzReport:
    """Run every property ``examples`` times (hypothesis, derandomized when ``seed`` is given).

    Raises:
        AssertionError: (from hypothesis, with the failing case) if anything but InputError came out.
    """
    from hypothesis import HealthCheck, settings
    from hypothesis import seed as with_seed

    tally = _Tally()
    folder = Path(tempfile.mkdtemp(prefix="online-slam-fuzz-"))
    profile = settings(max_examples=examples, deadline=2000, suppress_health_check=list(HealthCheck), database=None)
    properties = [*_file_properties(folder, tally, profile), _engine_api_property(tally, profile)]
    try:
        for prop in properties:
            (with_seed(seed)(prop) if seed is not None else prop)()
    finally:
        for path in folder.iterdir():
            path.unlink()
        folder.rmdir()
    return FuzzReport(tally.cases, tally.refused)
