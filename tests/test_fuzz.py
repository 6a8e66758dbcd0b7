"""Fuzzing: the stream reader and the engine API give only InputError (or a clean skip), never a crash."""

from __future__ import annotations

import pytest

from benchmarks.fuzz import run_fuzz


@pytest.mark.slow
def test_reader_and_engine_api_refuse_bad_input_with_input_error_only() -> None:
    report = run_fuzz(examples=150, seed=20261201)
    assert report.cases["bytes"] == report.cases["json"] == report.cases["perturbed lines"] == 150
    assert report.cases["engine API"] >= 150
    # the perturbations do reach both outcomes: refusals and accepted events
    for name, count in report.cases.items():
        assert 0 < report.input_errors.get(name, 0) < count or name == "bytes", (name, report)
