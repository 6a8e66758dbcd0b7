"""The results table that replay and compare print: one layout, honest labels, a legend, the robot."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from online_slam.compare import CompareConfig, compare
from online_slam.estimators.smoother import SmootherConfig, WindowConfig
from online_slam.evaluation.results import Results
from online_slam.evaluation.scoring import nees_bounds
from online_slam.pipeline import ReplayConfig, replay
from online_slam.reports.compare_table import format_comparison
from online_slam.reports.table import format_results, path_closure

MRCLAM = Path(__file__).resolve().parents[1] / "replay" / "mrclam6_robot1.jsonl.gz"


@pytest.fixture(scope="module")
def square() -> Results:
    return replay("square")


@pytest.fixture(scope="module")
def mrclam() -> Results:
    return replay(MRCLAM, ReplayConfig(estimators=("ekf",)))


def table(text: str) -> tuple[list[str], dict[str, dict[str, str]]]:
    """The column labels and the rows by estimator, then by label (cells are 2+ spaces apart)."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("estimator"))
    labels = re.split(r"\s{2,}", lines[start].strip())
    rows = {}
    for line in lines[start + 2 :]:
        if not line.strip():
            break
        cells = re.split(r"\s{2,}", line.strip())
        rows[cells[0]] = dict(zip(labels[1:], cells[1:]))
    return labels, rows


def legend(text: str) -> list[str]:
    """The lines of the block after the table."""
    blocks = text.split("\n\n")
    return blocks[2].splitlines()


def test_an_open_path_shows_no_end_gap_and_says_why(mrclam: Results) -> None:
    """MRCLAM robot 1 ends 6.8 m from its start: an estimate's end gap would say nothing of its error, so the table
    leaves the column out and says why."""
    closure = path_closure(mrclam)
    assert closure is not None and not closure.closed and closure.gap_m == pytest.approx(6.822, abs=1e-3)
    text = format_results(mrclam)
    labels, rows = table(text)
    assert not any("gap" in label for label in labels)
    assert rows["odometry"]["final RMSE m"] == "1.809" and rows["ekf"]["final RMSE m"] == "0.064"
    (line,) = [line for line in legend(text) if line.startswith("end gap")]
    assert "not shown" in line and "6.822 m" in line and "1%" in line


def test_a_closed_path_shows_the_gap_with_the_truths_own(square: Results) -> None:
    text = format_results(square)
    labels, rows = table(text)
    assert rows["odometry"]["end gap m"] == "1.870" and rows["batch"]["end gap m"] == "0.060"
    assert rows["odometry"]["final RMSE m"] == "1.338" and rows["batch"]["final RMSE m"] == "0.082"
    (line,) = [line for line in legend(text) if line.startswith("end gap")]
    assert "the true path closes" in line and "0.000 m" in line and "16.0 m" in line


def test_without_truth_the_gap_is_shown_with_a_warning(square: Results) -> None:
    blind = replace(square, truth_poses=None)
    assert path_closure(blind) is None
    text = format_results(blind)
    assert "end gap m" in table(text)[0]
    (line,) = [line for line in legend(text) if line.startswith("end gap")]
    assert "without truth" in line


def test_legend_explains_online_final_and_the_nees_band(square: Results, mrclam: Results) -> None:
    lines = legend(format_results(square))
    assert lines[0].startswith("online: ") and "final: " in lines[0]
    (nees,) = [line for line in lines if line.startswith("NEES")]
    assert "3 if consistent" in nees and "correlation counted, a lower bound" in nees
    assert all(len(line) <= 120 for line in lines)
    band = square.estimators["ekf"].nees_band
    assert band is not None and band.steps == int(np.isfinite(square.series["ekf"].nees).sum())
    labels, rows = table(format_results(square))
    assert rows["ekf"]["NEES band"] == f"{band.low:.2f}..{band.high:.2f}" and rows["batch"]["NEES band"] == "-"
    ekf = mrclam.estimators["ekf"]
    assert ekf.nees_band is not None and ekf.nees_band.steps == 1012
    independent = nees_bounds(1012)
    assert ekf.nees_band.high - ekf.nees_band.low > 3 * (independent[1] - independent[0])  # correlated steps
    nis = table(format_results(mrclam))[1]["ekf"]["NIS med/mean"]
    assert nis == f"{ekf.nis_median:.2f}/{ekf.nis_mean:.2f}" and ekf.nis_median < ekf.nis_mean


def test_a_landmark_rmse_that_leaves_landmarks_out_says_which(square: Results) -> None:
    assert not any("landmark RMSE:" in line for line in format_results(square).splitlines())
    truth = {lid: xy for lid, xy in square.truth_landmarks.items() if lid != 3}
    result = square.estimators["ekf"]
    coverage = replace(result.landmarks, scored=result.landmarks.scored - 1, without_truth=(3,), not_estimated=(99,))
    estimators = {name: replace(r, landmarks=coverage) for name, r in square.estimators.items()}
    lines = format_results(replace(square, truth_landmarks=truth, estimators=estimators)).splitlines()
    (note,) = [line for line in lines if line.startswith("landmark RMSE")]
    assert note == "landmark RMSE: over 11 landmarks; left out 1 without truth (3); 1 with truth never mapped (99)"
    assert square.to_json()["estimators"]["ekf"]["landmark_coverage"] == {
        "scored": 12,
        "without_truth": [],
        "not_estimated": [],
    }


@pytest.mark.slow
def test_the_robot_is_in_the_title_and_the_json(mrclam: Results, square: Results, mrclam_head: Path) -> None:
    title = format_results(mrclam).splitlines()[0]
    assert title.endswith("mrclam6_robot1.jsonl.gz, robot 1: 1012 poses, 15 landmarks, 1534 observations")
    assert mrclam.to_json()["robot"] == 1
    assert format_results(square).splitlines()[0] == "square: 25 poses, 12 landmarks, 95 observations"
    assert square.to_json()["robot"] is None
    comparison = compare(str(mrclam_head), CompareConfig(replay=ReplayConfig(estimators=("ekf",)), windows=(5,)))
    assert comparison.to_json()["robot"] == 1


def test_compare_and_replay_print_one_layout(square: Results) -> None:
    comparison = compare("square", CompareConfig(windows=(20,)))
    replayed, compared = table(format_results(square)), table(format_comparison(comparison))
    assert replayed[0] == compared[0]  # the same columns, with the same labels
    assert {"NEES band", "steps in band", "NIS med/mean"} <= set(compared[0])
    assert set(compared[1]) == {"odometry", "ekf", "smoother W=20..120 D=18 K=1 invariant", "batch"}
    for name in ("odometry", "ekf", "batch"):
        same = {k: v for k, v in compared[1][name].items() if not k.startswith(("step", "total"))}
        assert same == {k: v for k, v in replayed[1][name].items() if not k.startswith(("step", "total"))}
    assert legend(format_comparison(comparison)) == legend(format_results(square))


def test_the_readme_shows_the_table_as_replay_prints_it(square: Results) -> None:
    """The README's block is text, not run: its figures, labels, legend and notes must be the real output's."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    block = re.search(r"^```\n(square: 25 poses.*?)^```", readme, re.S | re.M)
    assert block is not None
    shown, printed = block[1].rstrip("\n"), format_results(square)
    timings = ("step ms med/p95/max", "total s")
    untimed = [{n: {k: v for k, v in row.items() if k not in timings} for n, row in table(t)[1].items()}
               for t in (shown, printed)]  # fmt: skip
    assert table(shown)[0] == table(printed)[0] and untimed[0] == untimed[1]
    assert shown.split("\n\n")[0] == printed.split("\n\n")[0]  # the title
    assert shown.split("\n\n")[2:] == printed.split("\n\n")[2:]  # legend and notes


@pytest.mark.slow
def test_compare_says_when_smoother_configurations_ran_identically() -> None:
    same = format_comparison(compare("square", CompareConfig(windows=(10, 20))))
    assert "identical figures: smoother W=10..120 D=18 K=1 invariant, smoother W=20..120 D=18 K=1 invariant" in same
    exact = ReplayConfig(estimators=("ekf",), smoother=SmootherConfig(window=WindowConfig(distance=0.0)))
    distinct = format_comparison(compare("square", CompareConfig(windows=(5, 20), replay=exact)))
    assert "identical figures" not in distinct and "smoother W=5 K=1" in distinct
    # the rows' names are read once, under the legend; without a smoother row there is nothing to read
    assert "\nsmoother W=a..b D=d K=k: at least a poses" in same and "docs/estimators.md#smoother" in same
    no_smoother = ReplayConfig(estimators=("ekf", "batch"))
    assert "W=a..b" not in format_comparison(compare("square", CompareConfig(windows=(), replay=no_smoother)))
