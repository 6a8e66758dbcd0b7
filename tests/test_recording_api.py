"""``online_slam.read_recording``: a recording's per-step series back as arrays and as a DataFrame."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from inprocess import run_cli

pytest.importorskip("rerun", reason="rerun-sdk is not installed")
pytest.importorskip("datafusion", reason="rerun-sdk[catalog] is not installed")

import online_slam  # noqa: E402
from online_slam import OnlineSlamError, RecordingSeries  # noqa: E402


@pytest.fixture(scope="module")
def square(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, RecordingSeries]:
    folder = tmp_path_factory.mktemp("rrd")
    rrd, out = folder / "square.rrd", folder / "square.json"
    done = run_cli("replay", "square", "--rrd", str(rrd), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    return rrd, json.loads(out.read_text()), online_slam.read_recording(rrd)


@pytest.mark.slow
def test_series_are_the_tables_figures(square: tuple[Path, dict, RecordingSeries]) -> None:
    _, results, series = square
    assert series.source == "square" and series.results["poses"] == 25
    np.testing.assert_array_equal(series.step, np.arange(25))
    np.testing.assert_array_equal(series.t, np.arange(25, dtype=float))
    assert set(series.metrics) == {"ekf", "smoother"}
    assert set(series.poses) == {"odometry", "ekf", "smoother", "truth"}
    for name in ("ekf", "smoother"):
        figures = series.metrics[name]
        assert {"position_error_m", "nees", "step_ms"} <= set(figures)
        assert all(values.shape == (25,) for values in figures.values())
        expected = results["estimators"][name]
        rmse = np.sqrt(np.mean(np.square(figures["position_error_m"])))
        assert rmse == pytest.approx(expected["online_rmse_m"], rel=1e-9)
        assert np.median(figures["step_ms"]) == pytest.approx(expected["step_ms"]["median"])
        assert np.nanmean(figures["nees"]) == pytest.approx(expected["nees_mean"], rel=1e-9)
    assert "nis" in series.metrics["ekf"] and "iterations" in series.metrics["smoother"]
    truth, ekf = series.poses["truth"], series.poses["ekf"]
    assert truth.shape == ekf.shape == (25, 3)
    errors = np.hypot(*(ekf[:, :2] - truth[:, :2]).T)
    np.testing.assert_allclose(errors, series.metrics["ekf"]["position_error_m"], atol=1e-5)  # poses are float32


def test_to_pandas_has_one_row_per_step_and_estimator(square: tuple[Path, dict, RecordingSeries]) -> None:
    pytest.importorskip("pandas")
    _, _, series = square
    frame = series.to_pandas()
    assert len(frame) == 4 * 25
    assert list(frame.columns[:6]) == ["step", "t", "estimator", "x", "y", "theta"]
    ekf = frame[frame["estimator"] == "ekf"]
    np.testing.assert_array_equal(ekf["position_error_m"], series.metrics["ekf"]["position_error_m"])
    np.testing.assert_array_equal(ekf["x"], series.poses["ekf"][:, 0])
    assert frame[frame["estimator"] == "truth"]["nees"].isna().all()


def test_to_pandas_without_pandas_says_how_to_get_it(
    square: tuple[Path, dict, RecordingSeries], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="pip install pandas"):
        square[2].to_pandas()


def test_a_file_that_is_no_recording_is_one_clear_error(tmp_path: Path) -> None:
    with pytest.raises(OnlineSlamError, match="no such file"):
        online_slam.read_recording(tmp_path / "missing.rrd")
    (tmp_path / "text.rrd").write_text("hello")
    with pytest.raises(OnlineSlamError, match="not a Rerun recording"):
        online_slam.read_recording(tmp_path / "text.rrd")
