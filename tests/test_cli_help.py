"""The command line as a new user meets it: quick help, one-line errors that suggest the right spelling,
outputs named alike, and sources refused with what to pass instead (issue 30, items 3, 7 and 8)."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPLAY

from tests.test_cli import cli

HEAVY = ("scipy", "filterpy", "rerun", "matplotlib", "dask", "pyarrow", "pandas")


def one_error(done: subprocess.CompletedProcess) -> str:
    """The single error line of a run that failed with exit 2 (no traceback, nothing on stdout)."""
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("online-slam: error: "), done.stderr
    return lines[0]


def test_help_loads_no_heavy_library() -> None:
    """Building the parser and every command's help imports none of the numerical or plotting libraries (it
    imported scipy, filterpy and the whole engine: about 2 s per --help)."""
    code = (
        "import sys\n"
        "from online_slam.cli.main import build_parser\n"
        "parser = build_parser()\n"
        "parser.format_help()\n"
        "for action in parser._subparsers._group_actions:\n"
        "    for command in action.choices.values():\n"
        "        command.format_help()\n"
        f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
    assert cli("replay", "--help").returncode == 0


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["replay", "--windw", "10"],
            "unknown option --windw (did you mean --window?); see 'online-slam replay --help'",
        ),
        (["compare", "square", "--estimator", "ekf"], "(did you mean --estimators?)"),  # no abbreviations
        (["replay", "--wind", "10"], "unknown option --wind (did you mean --window?)"),
        (["replay", "sqare"], "sqare: no such file, and not a built-in world (did you mean square?)"),
        (["replai"], "unknown command 'replai' (did you mean replay?)"),
        (["replay", "--align", "SE2"], "invalid choice 'SE2' (did you mean se2?); choose from anchor, se2"),
        (["sweep", "square", "--out", "rows.csv"], "unknown option --out (did you mean --output?)"),
        (["square"], "unknown command 'square' (to replay it: online-slam replay square)"),
        (["replay", "square", "--plot", "x.png"], "--plot is an option of compare, not of replay"),  # was --robot?
        (["replay", "--connect", "square"], "--connect: 'square' is not a viewer address"),  # took the source
    ],
)
def test_usage_errors_suggest_the_closest_spelling(args: list[str], expected: str) -> None:
    assert expected in one_error(cli(*args))


@pytest.mark.slow
def test_output_files_are_named_alike(tmp_path: Path) -> None:
    """-o/--output is the output file of simulate, convert and sweep (sweep had --out)."""
    stream = tmp_path / "s.jsonl"
    assert cli("simulate", "square", "--output", str(stream)).returncode == 0
    assert cli("convert", "stream", str(stream), "-o", str(tmp_path / "s.g2o")).returncode == 0
    rows = tmp_path / "rows.csv"
    done = cli("sweep", str(stream), "--estimators", "ekf", "-o", str(rows), "--quiet")
    assert done.returncode == 0, done.stderr
    assert rows.read_text().count("\n") == 2  # header and the EKF's row


@pytest.mark.slow
def test_connect_without_a_viewer_stops_before_the_replay(tmp_path: Path) -> None:
    """It replayed everything and only then exited 2; now it says how to start a viewer, before any work."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again: nothing listens there
    out = tmp_path / "r.json"
    done = cli("replay", "grid", "--connect", f"rerun+http://127.0.0.1:{port}/proxy", "--json", str(out))
    line = one_error(done)
    assert f"127.0.0.1:{port}" in line and "'rerun'" in line and "rerun --serve-web" in line
    assert done.stdout == "" and not out.exists()  # no replay ran (grid: 2000 poses)


def test_robot_with_a_source_without_robots_is_refused() -> None:
    line = one_error(cli("replay", "square", "--robot", "2"))  # was ignored
    assert "square: --robot applies to mrclam data, not to a built-in world" in line


@pytest.mark.parametrize(
    "world",
    [
        ("grid", "--poses", "0"),
        ("grid", "--poses", "1"),
        ("waypoint", "--poses", "-5"),
        ("waypoint", "--landmarks", "0"),
    ],
)
def test_a_world_too_small_to_simulate_is_one_line(world: tuple[str, ...], tmp_path: Path) -> None:
    """The world's own check raised a ValueError past the command's (a traceback, exit 1)."""
    out = tmp_path / "w.jsonl"
    line = one_error(cli("simulate", *world, "-o", str(out)))
    assert "simulate: a world needs poses >= 2 and landmarks >= 1" in line and not out.exists()


def test_a_map_out_without_the_smoother_or_the_ekf_is_refused_before_the_replay(tmp_path: Path) -> None:
    """It replayed the whole source, printed the table, and only then refused the map."""
    out = tmp_path / "m.json"
    done = cli("replay", "square", "--estimators", "batch", "--map-out", str(out))
    line = one_error(done)
    assert "--map-out: the map's covariances come from the smoother or the EKF" in line
    assert done.stdout == "" and not out.exists()


def test_a_line_cut_short_names_the_column_where_it_ends(tmp_path: Path) -> None:
    """A line missing its closing brace was reported at column 1 (the parser's position past the line's newline)."""
    lines = (REPLAY / "square.jsonl").read_text(encoding="utf-8").splitlines()
    cut = lines[2].rstrip().removesuffix("}")
    path = tmp_path / "cut.jsonl"
    path.write_text("\n".join([*lines[:2], cut, *lines[3:6]]) + "\n", encoding="utf-8")
    line = one_error(cli("replay", str(path)))
    assert f"cut.jsonl:3: invalid JSON (Expecting ',' delimiter at column {len(cut) + 1})" in line


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (("simulate", "square", "--seed", "-1"), "simulate: --seed: expected an integer >= 0, got -1"),
        (("simulate", "grid", "--outlier-seed", "-2"), "simulate: --outlier-seed: expected an integer >= 0, got -2"),
        (("compare", "square", "--runs", "0"), "argument --runs: must be > 0, got 0"),
        (("compare", "square", "--workers", "0"), "argument --workers: must be > 0, got 0"),
        (("sweep", "square", "--workers", "0"), "argument --workers: must be > 0, got 0"),  # was all cores, silently
        (("compare", "square", "--peer", "ideal"), "compare: --peer ideal runs beside Monte Carlo runs: give --runs 2"),
    ],
)
def test_a_bad_count_names_its_flag(args: tuple[str, ...], said: str, tmp_path: Path) -> None:
    """They said 'expected non-negative integer' or 'runs and workers must be >= 1', naming no flag."""
    out = ("-o" if args[0] in ("simulate", "sweep") else "--json", str(tmp_path / "out"))
    assert said in one_error(cli(*args, *out))


def test_a_folder_of_gtsam_text_says_which_file_to_pass(tmp_path: Path) -> None:
    (tmp_path / "victoria.txt").write_text("ODOMETRY 0 1 1.0 0.0 0.0 1 0 0 1 0 1\n")
    line = one_error(cli("replay", str(tmp_path)))
    assert "a folder, but no dataset folder an importer reads" in line and str(tmp_path / "victoria.txt") in line
    assert "no such file" not in line


def test_a_file_of_an_mrclam_folder_asks_for_the_folder(tmp_path: Path) -> None:
    member = tmp_path / "Robot2_Odometry.dat"
    member.write_text("# Time [sec]    v [m/s]    w [rad/s]\n1248272272.841 0.0 0.0\n")
    line = one_error(cli("replay", str(member)))
    assert "a file of an MRCLAM folder: pass the folder with --robot N" in line and "invalid JSON" not in line


def test_a_recording_given_as_a_stream_points_to_inspect(tmp_path: Path) -> None:
    recording = tmp_path / "run.rrd"
    recording.write_bytes(b"RRF2")  # never read: the name says what it is
    assert "a Rerun recording, not a stream: read it with 'online-slam inspect'" in one_error(
        cli("replay", str(recording))
    )


def test_format_is_refused_where_it_does_not_apply_or_fit() -> None:
    assert "square: --format applies to dataset files, not to a built-in world" in one_error(
        cli("replay", "square", "--format", "mrclam")
    )  # it was ignored
    line = one_error(cli("replay", str(Path(__file__).parents[1] / "replay" / "square.jsonl"), "--format", "g2o"))
    assert "--format g2o: not g2o data" in line


def test_a_misspelt_advanced_flag_points_to_help_all() -> None:
    line = one_error(cli("replay", "square", "--window-distanc", "3"))
    assert "did you mean --window-distance?" in line and "--help-all lists it" in line


def test_a_bad_value_of_an_advanced_option_points_at_help_all() -> None:
    """An advanced option is only in ``--help-all``: its errors say so; a plain option's say ``--help``."""
    advanced = cli("compare", "circle", "--pose-covariance", "banana")
    assert advanced.returncode == 2 and "Traceback" not in advanced.stderr
    assert advanced.stderr.strip().endswith("see 'online-slam compare --help-all'"), advanced.stderr
    plain = cli("replay", "--window", "x")
    assert plain.returncode == 2 and plain.stderr.strip().endswith("see 'online-slam replay --help'"), plain.stderr
