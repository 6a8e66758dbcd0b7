"""The machine-written baseline: RESULTS.md's table is its rendering, and the gate catches a regression."""

from __future__ import annotations

import dataclasses

from benchmarks import baseline, results_page


def _rows(document: dict) -> list[baseline.BaselineRow]:
    return [baseline.BaselineRow(**row) for row in document["rows"]]


def test_results_page_shows_the_recorded_baseline() -> None:
    document = baseline.read()
    assert results_page.block() == results_page.render(document)
    assert {row["source"] for row in document["rows"]} == set(baseline.SOURCES)
    assert document["commit"] and document["date"]


def test_the_gate_passes_the_baseline_itself() -> None:
    document = baseline.read()
    assert baseline.gate(document, _rows(document)) == []


def test_a_five_percent_accuracy_regression_fails_the_gate() -> None:
    document = baseline.read()
    rows = _rows(document)
    k = next(i for i, r in enumerate(rows) if r.source == "grid" and r.estimator == "smoother")
    rows[k] = dataclasses.replace(rows[k], final_rmse_m=rows[k].final_rmse_m * 1.05)
    (failure,) = baseline.gate(document, rows)
    assert failure.startswith("grid smoother final_rmse_m") and "+5.0%" in failure


def test_time_ratios_fail_only_when_they_grow_beyond_their_tolerance() -> None:
    document = baseline.read()
    rows = _rows(document)
    k = next(i for i, r in enumerate(rows) if r.step_ratio is not None)
    slower = list(rows)
    slower[k] = dataclasses.replace(rows[k], step_ratio=rows[k].step_ratio * 1.6)
    faster = list(rows)
    faster[k] = dataclasses.replace(rows[k], step_ratio=rows[k].step_ratio * 0.5)
    assert len(baseline.gate(document, slower)) == 1 and "step_ratio" in baseline.gate(document, slower)[0]
    assert baseline.gate(document, faster) == []


def test_a_row_not_measured_fails_the_gate() -> None:
    document = baseline.read()
    assert baseline.gate(document, _rows(document)[1:])[0].endswith("not measured")


def test_the_live_input_cost_is_gated_to_its_limit_and_shown_once_recorded() -> None:
    document = baseline.read()
    rows = _rows(document)
    limit = document.get("live_limit_ms", 0.1)
    assert baseline.gate(document, rows, live_ms=0.5 * limit) == []
    (failure,) = baseline.gate(document, rows, live_ms=2.0 * limit)
    assert failure.startswith("live input: the socket costs") and f"at most {limit} ms" in failure
    recorded = {**document, "live_ms_per_step": 0.0213, "live_limit_ms": 0.1}
    assert "the socket costs 0.0213 ms per step over a file; `--gate` fails above 0.1 ms" in results_page.render(
        recorded
    )
