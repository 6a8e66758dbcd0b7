"""The command line end to end, as a user runs it: tables, JSON, simulate -> replay, bad input."""

from __future__ import annotations

import gzip
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA_VARIABLE
from inprocess import run_cli

from online_slam.sources import square_world, write_stream

EXE = [shutil.which("online-slam")] if shutil.which("online-slam") else [sys.executable, "-m", "online_slam"]


def cli(*args: str, stdin: str | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``online-slam *args`` run in this process (see :mod:`inprocess`)."""
    return run_cli(*args, stdin=stdin, cwd=cwd)


def executable(*args: str) -> subprocess.CompletedProcess:
    """``online-slam *args`` as README runs it: the installed executable, a new process."""
    return subprocess.run([*EXE, *args], capture_output=True, text=True, timeout=300)


def parse_table(text: str) -> dict[str, dict[str, str]]:
    """Rows of the replay table by estimator, then cells by column label (columns are 2+ spaces apart)."""
    lines = text.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("estimator"))
    columns = re.split(r"\s{2,}", lines[header].strip())[1:]
    table = {}
    for line in lines[header + 2 :]:
        if not line.strip():
            break
        cells = re.split(r"\s{2,}", line.strip())
        table[cells[0]] = dict(zip(columns, cells[1:]))
    return table


@pytest.mark.slow
def test_default_replay_prints_the_article_table() -> None:
    done = executable("replay")
    assert done.returncode == 0, done.stderr
    table = parse_table(done.stdout)
    assert table["odometry"]["final RMSE m"] == "1.338"
    assert table["batch"]["final RMSE m"] == "0.082"
    assert table["odometry"]["end gap m"] == "1.870"
    assert table["batch"]["end gap m"] == "0.060"
    assert float(table["ekf"]["online RMSE m"]) < 1.338 / 4
    assert "square: 25 poses, 12 landmarks, 95 observations" in done.stdout


def test_no_command_means_replay() -> None:
    done = executable()
    assert done.returncode == 0 and parse_table(done.stdout)["odometry"]["final RMSE m"] == "1.338"


@pytest.mark.slow
def test_json_to_stdout_keeps_stdout_pure_and_the_table_on_stderr() -> None:
    done = cli("replay", "--json", "-")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["estimators"]["batch"]["final_rmse_m"] > 0.0  # the whole of stdout parses
    assert parse_table(done.stderr)["odometry"]["final RMSE m"] == "1.338"
    done = cli("compare", "square", "--window", "5", "--json", "-")
    assert done.returncode == 0, done.stderr
    assert "smoother W=5..120 D=18 K=1 invariant" in json.loads(done.stdout)["estimators"]
    assert "smoother W=5..120 D=18 K=1 invariant" in done.stderr


@pytest.mark.slow
def test_compare_rows_say_what_ran() -> None:
    """A window kept longer by --window-distance is labelled so; with distance 0 each W is exactly W poses."""
    sized = parse_compare(cli("compare", "square", "--window", "5,20", "--estimators", "smoother").stdout)
    assert set(sized) == {"odometry", "smoother W=5..120 D=18 K=1 invariant", "smoother W=20..120 D=18 K=1 invariant"}
    exact = cli("compare", "square", "--window", "5,20", "--window-distance", "0", "--estimators", "smoother")
    rows = parse_compare(exact.stdout)
    assert set(rows) == {"odometry", "smoother W=5 K=1 invariant", "smoother W=20 K=1 invariant"}
    assert rows["smoother W=5 K=1 invariant"] != rows["smoother W=20 K=1 invariant"]


def parse_compare(text: str) -> dict[str, list[str]]:
    """Rows of the compare table by label."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("estimator")) + 2
    end = lines.index("", start)  # the legend follows the table
    rows = [re.split(r"\s{2,}", line.strip()) for line in lines[start:end]]
    return {row[0]: row[1:6] for row in rows}


def test_help_is_grouped_with_readable_defaults() -> None:
    done, every = cli("replay", "--help"), cli("replay", "--help-all")
    assert done.returncode == 0 and every.returncode == 0
    for group in ("input:", "estimators:", "smoother:", "association:", "outliers:", "output:"):
        assert f"\n{group}\n" in done.stdout
    assert "\nEKF:\n" in every.stdout  # its four options are all research knobs
    text, full = " ".join(done.stdout.split()), " ".join(every.stdout.split())
    assert "(default: 20)" in text and "--window-distance" not in text and "--help-all" in text
    assert "[advanced] keep poses beyond W" in full and "(default: 18 m)" in full and "0.35 rad (20.1 deg)" in full
    assert "world (square, grid, waypoint, circle" in text
    assert not re.search(r"\d\.\d{8,}", cli("simulate", "--help").stdout)  # no 0.008726646259971648


@pytest.mark.slow
def test_first_observation_only_and_json(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    done = cli("replay", "--first-observation-only", "--json", str(out))
    assert done.returncode == 0, done.stderr
    data = json.loads(out.read_text())
    assert set(data) >= {"source", "poses", "landmarks", "observations", "odometry", "estimators"}
    assert set(data["odometry"]) >= {"rmse_m", "endpoint_gap_m"}
    assert set(data["estimators"]["batch"]) >= {"final_rmse_m", "endpoint_gap_m", "landmark_rmse_m", "total_s"}
    assert f"{data['estimators']['batch']['final_rmse_m']:.3f}" == "1.338"
    assert data["observations"] == 12 and data["error"] is None


@pytest.mark.slow
def test_simulate_then_replay_file_gz_and_stdin(tmp_path: Path) -> None:
    plain, packed = tmp_path / "square.jsonl", tmp_path / "square.jsonl.gz"
    assert cli("simulate", "square", "-o", str(plain)).returncode == 0
    assert cli("simulate", "square", "-o", str(packed)).returncode == 0
    expected = json.loads(cli("replay", "--json", "-", "--quiet").stdout)
    for source, stdin in ((str(plain), None), (str(packed), None), ("-", plain.read_text())):
        got = json.loads(cli("replay", source, "--json", "-", "--quiet", stdin=stdin).stdout)
        assert got["odometry"] == expected["odometry"]
        assert got["estimators"]["batch"]["final_rmse_m"] == expected["estimators"]["batch"]["final_rmse_m"]
    assert gzip.decompress(packed.read_bytes()).decode() == plain.read_text()


@pytest.mark.slow
def test_simulate_grid_options(tmp_path: Path) -> None:
    path = tmp_path / "g.jsonl"
    done = cli("simulate", "grid", "--poses", "120", "--landmarks", "30", "--seed", "4", "-o", str(path))
    assert done.returncode == 0, done.stderr
    replayed = json.loads(cli("replay", str(path), "--json", "-", "--quiet").stdout)
    assert replayed["poses"] == 120 and replayed["estimators"]["batch"]["converged"]
    assert cli("simulate", "grid", "--sensor-range", "-1", "-o", str(path)).returncode == 2


@pytest.mark.slow
def test_simulate_waypoint_world(tmp_path: Path) -> None:
    """The random-waypoint world: steps of the given length, turns within the limit, sightings within range and
    outside the blind zone (checked on the written stream's truth), bad settings a one-line error."""
    path = tmp_path / "w.jsonl"
    args = ("--poses", "300", "--landmarks", "150", "--size", "40", "--step", "0.5", "--max-turn", "0.2")
    args += ("--min-range", "0.8")
    done = cli("simulate", "waypoint", *args, "-o", str(path))
    assert done.returncode == 0, done.stderr
    events = [json.loads(line) for line in path.read_text().splitlines()]
    truth = np.array([e["pose"] for e in events if e["type"] == "truth"])
    landmarks = {e["landmark"]: e["position"] for e in events if e["type"] == "landmark_truth"}
    assert len(truth) == 300 and len(landmarks) == 150
    np.testing.assert_allclose(np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1), 0.5, atol=1e-9)
    turns = np.abs(np.angle(np.exp(1j * np.diff(truth[:, 2]))))
    assert turns.max() <= 0.2 + 1e-9 and turns.max() > 0.1  # it does turn
    pose_at = dict(zip([e["t"] for e in events if e["type"] == "truth"], truth))
    sightings = [e for e in events if e["type"] == "observation"]
    assert len(sightings) > 300
    distances = [np.hypot(*(np.array(landmarks[e["landmark"]]) - pose_at[e["t"]][:2])) for e in sightings]
    assert min(distances) >= 0.8 and max(distances) <= 6.0
    replayed = json.loads(cli("replay", str(path), "--json", "-", "--quiet").stdout)
    assert replayed["poses"] == 300 and replayed["estimators"]["batch"]["converged"]
    bad = cli("simulate", "waypoint", "--size", "10", "-o", str(path))
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "size" in bad.stderr
    bad = cli("simulate", "waypoint", "--min-range", "7", "-o", str(path))
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "min range" in bad.stderr


GOOD = [
    {"type": "header", "format": "online-slam", "version": 1, "name": "bad-input"},
    {"type": "observation", "t": 0, "landmark": 1, "range": 2.0, "bearing": 0.5, "sigma": [0.1, 0.01]},
    {"type": "odometry", "t": 1, "delta": [1, 0, 0], "sigma": [0.1, 0.1, 0.01]},
    {"type": "observation", "t": 1, "landmark": 1, "range": 1.5, "bearing": 0.8, "sigma": [0.1, 0.01]},
    {"type": "odometry", "t": 2, "delta": [1, 0, 0], "sigma": [0.1, 0.1, 0.01]},
]
OBS = '{"type": "observation", "t": 2, "landmark": 1, "range": 1.0, "bearing": 0.1, "sigma": [0.1, 0.01]}'
BAD = {
    "bad_json": ('{"type": "odometry", "t": 3,', ":6: ", "invalid JSON"),
    "unknown_type": ('{"type": "gps", "t": 3}', ":6: type: ", "unknown event type"),
    "missing_field": ('{"type": "odometry", "t": 3, "sigma": [1, 1, 1]}', ":6: delta: ", "missing required field"),
    "nan": (OBS.replace('"range": 1.0', '"range": NaN'), ":6: range: ", "finite"),
    "negative_range": (OBS.replace('"range": 1.0', '"range": -1.0'), ":6: range: ", "range > 0"),
    "non_pd_cov": (OBS.replace('"sigma": [0.1, 0.01]', '"cov": [[1, 2], [2, 1]]'), ":6: cov: ", "positive definite"),
    "time_backwards": (OBS.replace('"t": 2', '"t": 1.5'), ":6: t: ", "time goes backwards"),
}


def write_lines(path: Path, lines: list[str]) -> None:
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_gives_one_line_and_exit_2(tmp_path: Path, case: str) -> None:
    line, where, what = BAD[case]
    path = tmp_path / f"{case}.jsonl"
    write_lines(path, [json.dumps(g) for g in GOOD] + [line])
    out = tmp_path / "partial.json"
    done = cli("replay", str(path), "--json", str(out))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr + done.stdout
    errors = done.stderr.strip().splitlines()
    assert len(errors) == 1
    assert errors[0].startswith(f"online-slam: error: {path}{where}") and what in errors[0]
    # What was estimated before the bad line is not lost: every valid event before it is used (three poses:
    # the third's odometry came before the bad line).
    partial = json.loads(out.read_text())
    assert partial["poses"] == 3 and partial["error"] is not None and "batch" in partial["estimators"]


@pytest.mark.slow
def test_truncated_gzip_gives_one_line_and_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "cut.jsonl.gz"
    write_stream(path, square_world())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    done = cli("replay", str(path))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    errors = done.stderr.strip().splitlines()
    assert len(errors) == 1 and errors[0].startswith(f"online-slam: error: {path}:")
    assert "truncated or corrupt gzip" in errors[0]
    assert "final RMSE m" in done.stdout  # the poses before the cut were still estimated and reported


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["replay", "/nonexistent/stream.jsonl"], "no such file"),
        (["replay", "--estimators", "magic"], "unknown estimator"),
        (["replay", "--estimators", ""], "--estimators: give at least one of ekf, smoother, batch"),  # was exit 0
        (["simulate", "square", "--poses", "10"], "--poses shapes the grid and waypoint worlds"),  # was ignored
        (["replay", "--estimators", "ekf", "--window", "5"], "--window: a setting of the smoother, which does not"),
        (["compare", "square", "--estimators", "ekf", "--window", "5,10"], "--window: a setting of the smoother"),
        (["compare", "square", "--window", "0"], "--window: window must be >= 1"),  # was a traceback
        (["compare", "square", "--window", "5,x"], "expected comma-separated ints"),
        (["compare", "square", "--window", "10,,20"], "got an empty item in '10,,20'"),  # was read as 10,20
        (["replay", "--align", "SE2"], "invalid choice 'SE2' (did you mean se2?)"),  # was 23 lines of usage
        (["replay", "--window-max", "0"], "--window-max: "),
        (["sweep", "square", "--robust", "huber,tukey", "--quiet"], "'tukey' is not one of"),
        (["sweep", "square", "--window", "0", "--quiet"], "--window: window must be >= 1"),
        (["replay", "--keyframe-distance", "-1"], "keyframe limits"),
        (["replay", "--dt", "-1"], "--dt"),
        (["replay", "--robust-scale", "-1"], "--robust-scale"),
        (["replay", "--rrd", "/nonexistent/dir/a.rrd"], "cannot write the recording"),  # rerun warned too
        (["replay", "--json", "/nonexistent/dir/r.json"], "--json: cannot write"),  # told before the run
        (["replay", "--tum", str(Path(__file__))], "--tum: "),
        (["replay", "--tum", str(Path(__file__) / "out")], "is a file, expected a folder"),  # was after the run
        (["replay", "--checkpoint", str(Path(__file__)), "--checkpoint-every", "5"], "--checkpoint: "),  # traceback
        (["replay", "--checkpoint", str(Path(__file__) / "ck"), "--checkpoint-every", "5"], "--checkpoint: "),
        (["compare", "square", "--plot", "figure.jpg"], "ending in .png"),
        (["sweep", "/nonexistent/stream.jsonl", "--quiet"], "no such file"),  # was a failed row and exit 1
        (["sweep", "square", "-o", "/nonexistent/dir/rows.csv", "--quiet"], "--output: cannot write"),  # traceback
    ],
)
@pytest.mark.slow
def test_usage_errors_are_one_line(args: list[str], message: str) -> None:
    done = cli(*args)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and message in done.stderr


@pytest.mark.slow
def test_a_failed_convert_writes_nothing_and_keeps_an_existing_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.g2o"  # the second line is cut short: the reader stops there
    bad.write_text("EDGE_SE2 0 1 1.0 0.0 0.0 100 0 0 100 0 100\nEDGE_SE2 1 2 1.0 0.0 0.0\n")
    out = tmp_path / "out.jsonl"
    done = cli("convert", "g2o", str(bad), "-o", str(out))
    assert done.returncode == 2 and f"{bad}:2:" in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.g2o"]  # no output, no .part left behind
    out.write_text("kept\n")
    assert cli("convert", "g2o", str(bad), "-o", str(out)).returncode == 2
    assert out.read_text() == "kept\n"
    (tmp_path / "folder").mkdir()  # an output path that is a folder: refused, and no folder.part left beside it
    assert cli("simulate", "square", "-o", str(tmp_path / "folder")).returncode == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.g2o", "folder", "out.jsonl"]


@pytest.mark.slow
def test_bad_first_line_reports_without_results(tmp_path: Path) -> None:
    path = tmp_path / "empty.jsonl"
    path.write_text("{oops\n")
    done = cli("replay", str(path))
    assert done.returncode == 2 and done.stdout == ""
    assert (
        done.stderr.strip()
        == f"online-slam: error: {path}:1: invalid JSON (Expecting property name enclosed in double quotes at column 2)"
    )


def benchmarks(*args: str, cwd: Path | None = None, data: Path | None = None) -> subprocess.CompletedProcess:
    """``python -m benchmarks`` from the repository root, where the benchmarks live beside the package (or from
    ``cwd``, the benchmarks found through PYTHONPATH); ``data``: the real datasets' folder it is told of."""
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")]))}
    if data is not None:
        env[DATA_VARIABLE] = str(data)
    return subprocess.run(
        [sys.executable, "-m", "benchmarks", *args], capture_output=True, text=True, cwd=cwd or root, timeout=300,
        env=env,
    )  # fmt: skip


def test_benchmarks_ask_for_the_mrclam_folder_before_running(tmp_path: Path) -> None:
    done = benchmarks("--only", "batch,mrclam", cwd=tmp_path)  # no ../shared/data/MRCLAM_Dataset6 from there
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == (
        "benchmarks: error: mrclam: give --mrclam PATH, the MRCLAM Dataset 6 folder (it holds Barcodes.dat)"
    )


@pytest.mark.slow
def test_benchmarks_print_ratio_against_gtsam(tmp_path: Path) -> None:
    pytest.importorskip("gtsam", reason="the 'peers' extra (gtsam) is not installed")
    done = benchmarks(
        "--poses", "100", "--repeats", "1", "--fuzz-cases", "20", "--recording-source", "square",
        "--landmarks", "50,500", "--windows", "20", "--wrong-ids", "0.1", "--scans", "5",
        data=tmp_path,  # no real data: the bag section reads replay/'s 45 s excerpt, not all of Victoria Park
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "online-slam LM" in done.stdout and "GTSAM LM" in done.stdout and "ratio online-slam / GTSAM" in done.stdout
    sections = ("library API overhead", "checkpoint overhead", "compare --rrd: square", "association without ids")
    for section in (*sections, "fuzzing:", "robustness:"):
        assert section in done.stdout
    # the latency ratios come from the smoother and iSAM2 run back to back (one round with --repeats 1)
    assert "back to back, 1 rounds" in done.stdout
    for line in ("ratio smoother default / iSAM2 median: ", "ratio smoother default / iSAM2 p99: "):
        assert re.search(re.escape(line) + r"\d+\.\d\dx \(rounds: \d+\.\d\d\)", done.stdout), line
