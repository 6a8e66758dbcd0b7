"""``--on-error skip``: bad lines are reported once, skipped, and change nothing else."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from inprocess import run_cli as cli

from online_slam.sources.stream import write_stream
from online_slam.sources.worlds import GridConfig, grid_world

BAD_LINES = [
    ('{"type": "odometry", "t": 3,', "invalid_json"),
    ('{"type": "gps", "t": 3}', "unknown_type"),
    ('{"type": "observation", "t": 1e9, "landmark": 1, "range": NaN, "bearing": 0.1, "sigma": [0.1, 0.01]}', None),
    ('{"type": "observation", "t": 1e9, "landmark": 1, "range": -0.01, "bearing": 0.1, "sigma": [0.1, 0.01]}', None),
    ('{"type": "odometry", "t": 0.5, "delta": [1, 0, 0], "sigma": [0.1, 0.1, 0.01]}', "time_order"),
    ('{"type": "odometry", "t": 1e9, "sigma": [0.1, 0.1, 0.01]}', "missing_field"),
    ('{"type": "truth", "t": 1e9, "pose": [0, 0, 0], "speed": 3}', "unknown_field"),
    ('{"type": "observation", "t": 1e9, "landmark": 1, "range": 1, "bearing": 0, "cov": [[1, 2], [2, 1]]}', None),
    ('{"type": "start", "t": 0, "pose": [0, 0, 0]}', "out_of_order"),
    ("[1, 2, 3]", "not_an_object"),
]


def _figures(document: dict) -> dict:
    """The results JSON without timings."""
    out = dict(document)
    out.pop("input", None)
    out.pop("source", None)
    for figures in out["estimators"].values():
        for key in ("total_s", "step_ms", "solve_s", "final_solve_s"):
            figures.pop(key, None)
    return out


@pytest.fixture(scope="module")
def streams(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, list[str]]:
    folder = tmp_path_factory.mktemp("onerror")
    clean = folder / "clean.jsonl"
    write_stream(clean, grid_world(GridConfig(poses=150, landmarks=40, seed=2)))
    lines = clean.read_text().splitlines()
    dirty = list(lines)
    # spread the bad lines through the stream; times that must be "now" are set from the line before
    for k, (bad, _) in reversed(list(enumerate(BAD_LINES))):
        at = 30 + (len(lines) - 60) // len(BAD_LINES) * k
        t_now = json.loads(dirty[at - 1]).get("t", 0.0)
        dirty.insert(at, bad.replace("1e9", repr(t_now)))
    path = folder / "dirty.jsonl"
    path.write_text("\n".join(dirty) + "\n")
    return clean, path, dirty


@pytest.mark.slow
def test_skip_reports_each_bad_line_once_and_changes_nothing_else(streams, tmp_path: Path) -> None:
    clean, dirty, _ = streams
    done = cli("replay", str(dirty), "--on-error", "skip", "--json", str(tmp_path / "d.json"), "--quiet")
    assert done.returncode == 0, done.stderr
    skipped = [line for line in done.stderr.splitlines() if line.startswith("online-slam: skipped")]
    assert len(skipped) == 10 and all(f"{dirty}:" in line for line in skipped)
    assert "Traceback" not in done.stderr
    report = json.loads((tmp_path / "d.json").read_text())
    assert report["input"]["skipped_lines"] == 10
    reasons = report["input"]["skipped_by_reason"]
    assert sum(reasons.values()) == 10
    for _, reason in BAD_LINES:
        if reason is not None:
            assert reasons.get(reason, 0) >= 1, reasons
    assert {"not_finite", "range_not_positive", "bad_noise"} <= set(reasons)
    assert cli("replay", str(clean), "--json", str(tmp_path / "c.json"), "--quiet").returncode == 0
    reference = json.loads((tmp_path / "c.json").read_text())
    assert reference["input"] == {"skipped_lines": 0, "skipped_by_reason": {}, "after_last_odometry": 0}
    assert _figures(report) == _figures(reference)


@pytest.mark.slow
def test_stop_is_the_default_for_files_and_skip_for_stdin(streams) -> None:
    _, dirty, lines = streams
    stopped = cli("replay", str(dirty), "--quiet", "--json", "-")
    assert stopped.returncode == 2 and ":31: " in stopped.stderr  # the first bad line, and nothing after
    piped = cli("replay", "-", "--quiet", "--json", "-", "--estimators", "ekf", stdin="\n".join(lines) + "\n")
    assert piped.returncode == 0, piped.stderr
    assert json.loads(piped.stdout)["input"]["skipped_lines"] == 10
    forced = cli("replay", "-", "--quiet", "--on-error", "stop", "--estimators", "ekf", stdin="\n".join(lines))
    assert forced.returncode == 2


@pytest.mark.slow
def test_compare_and_convert_skip_too(streams, tmp_path: Path) -> None:
    clean, dirty, _ = streams
    done = cli("compare", str(dirty), "--on-error", "skip", "--json", "-", "--quiet", "--window", "10")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["input"]["skipped_lines"] == 10
    out_dirty, out_clean = tmp_path / "d.g2o", tmp_path / "c.g2o"
    assert cli("convert", "stream", str(dirty), "-o", str(out_dirty), "--on-error", "skip").returncode == 0
    assert cli("convert", "stream", str(clean), "-o", str(out_clean)).returncode == 0
    assert out_dirty.read_text() == out_clean.read_text()


def test_a_stop_request_ends_the_replay_and_scores_what_came_before() -> None:
    """``replay(stop=...)``, what Ctrl-C sets: the figures of the poses so far, ``error`` "interrupted"."""
    import online_slam
    from online_slam.reports.table import notes

    steps = []
    results = online_slam.replay("square", stop=lambda: steps.append(1) or len(steps) >= 10)
    assert results.error == "interrupted" and results.poses == 11
    assert results.estimators["batch"].final_rmse_m is not None
    assert "stopped early: interrupted; figures cover the 11 poses before it" in notes(results)
