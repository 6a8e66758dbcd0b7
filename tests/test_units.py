"""Wrong units: most of the first sightings rejected (or lines skipped) give one warning naming the likely cause;
``--strict`` makes it exit 2, keeping the figures before it; clean streams give none."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path

import pytest
from inprocess import run_cli as cli

from online_slam import replay
from online_slam.pipeline import ReplayConfig
from online_slam.sources.events import Event, Observation, Odometry
from online_slam.sources.stream import write_stream
from online_slam.sources.worlds import WaypointConfig, waypoint_world


def _turns_in_degrees(e: Event) -> Event | None:
    if isinstance(e, Odometry):
        return dataclasses.replace(e, delta=(e.delta[0], e.delta[1], math.degrees(e.delta[2])))
    return e


def _ranges_in_centimetres(e: Event) -> Event | None:
    return dataclasses.replace(e, range=e.range * 100) if isinstance(e, Observation) and e.range else e


def _bearings_in_degrees_under_2_pi(e: Event) -> Event | None:
    """Bearings in degrees, keeping only the sightings whose degrees stay within 2 pi (no range check catches
    them)."""
    if not isinstance(e, Observation) or e.bearing is None:
        return e
    degrees = math.degrees(e.bearing)
    return dataclasses.replace(e, bearing=degrees) if abs(degrees) < 2 * math.pi else None


WRONG: dict[str, tuple[Callable[[Event], Event | None], str]] = {
    "turns_deg": (_turns_in_degrees, "odometry headings in degrees?"),
    "ranges_cm": (_ranges_in_centimetres, "ranges in centimetres?"),
    "bearings_deg": (_bearings_in_degrees_under_2_pi, "bearings in degrees?"),
}


@pytest.fixture(scope="module")
def streams(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A small world whose turns stay under 0.08 rad (4.6 degrees: under 2 pi written in degrees), clean and
    written in wrong units."""
    folder = tmp_path_factory.mktemp("units")
    world = list(waypoint_world(WaypointConfig(poses=300, size=30, landmarks=100, max_turn=0.08, seed=3)))
    out = {"clean": folder / "clean.jsonl"}
    write_stream(out["clean"], world)
    for name, (change, _) in WRONG.items():
        out[name] = folder / f"{name}.jsonl"
        write_stream(out[name], [c for c in map(change, world) if c is not None])
    return out


def _suspect(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "suspect input" in line]


@pytest.mark.parametrize("name", list(WRONG))
def test_wrong_units_give_one_warning_naming_the_cause(streams: dict[str, Path], name: str) -> None:
    warned: list[str] = []
    results = replay(streams[name], ReplayConfig(estimators=("ekf",)), on_warning=warned.append)
    assert len(warned) == 1 and WRONG[name][1] in warned[0] and results.warning == warned[0]
    assert results.error is None and results.to_json()["warning"] == warned[0]


@pytest.mark.slow
def test_the_cli_warns_once_and_strict_exits_2_keeping_the_figures(streams: dict[str, Path], tmp_path: Path) -> None:
    done = cli("replay", str(streams["ranges_cm"]), "--estimators", "ekf")
    assert done.returncode == 0 and len(_suspect(done.stderr)) == 1
    assert _suspect(done.stderr)[0].startswith("online-slam: warning: suspect input: ")
    out = tmp_path / "strict.json"
    done = cli("replay", str(streams["turns_deg"]), "--estimators", "ekf", "--strict", "--json", str(out))
    assert done.returncode == 2
    (line,) = _suspect(done.stderr)
    assert line.startswith("online-slam: error: suspect input:") and "odometry headings in degrees?" in line
    report = json.loads(out.read_text())
    assert 0 < report["poses"] < 300 and report["error"].endswith("(--strict)")
    assert "stopped early" in done.stdout


@pytest.mark.slow
def test_most_lines_skipped_give_one_warning_and_few_skip_lines(streams: dict[str, Path], tmp_path: Path) -> None:
    degrees = tmp_path / "degrees.jsonl"
    lines = []
    for line in streams["clean"].read_text().splitlines():
        record = json.loads(line)
        if record.get("type") == "observation":
            record["bearing"] = math.degrees(record["bearing"])
        lines.append(json.dumps(record))
    degrees.write_text("\n".join(lines) + "\n")
    done = cli("replay", str(degrees), "--on-error", "skip", "--estimators", "ekf")
    assert done.returncode == 0
    (line,) = _suspect(done.stderr)
    assert "out_of_range" in line and "angles in degrees?" in line
    assert len(done.stderr.splitlines()) < 30  # not one line per skipped line
    assert cli("replay", str(degrees), "--on-error", "skip", "--estimators", "ekf", "--strict").returncode == 2


# The streams shipped in replay/ are checked by tests/test_shipped_replays.py, and the 2000-pose grid by
# tests/test_smoother.py::test_window_20_on_the_2000_pose_grid, inside the replays they run anyway.
CLEAN = ["clean", "square"]


@pytest.mark.parametrize("source", CLEAN)
def test_clean_streams_raise_no_false_alarm(streams: dict[str, Path], source: str) -> None:
    path: str | Path = streams["clean"] if source == "clean" else source
    warned: list[str] = []
    results = replay(path, ReplayConfig(estimators=("ekf",)), on_warning=warned.append)
    assert warned == [] and results.warning is None
