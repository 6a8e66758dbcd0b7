"""``replay --tum``: evo reads the files and finds the table's RMSEs."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
from inprocess import run_cli

evo_file_interface = pytest.importorskip("evo.tools.file_interface", reason="evo is not installed (dev extra)")
from evo.core import metrics, sync  # noqa: E402


def ape_rmse(reference: Path, estimate: Path) -> float:
    ref = evo_file_interface.read_tum_trajectory_file(str(reference))
    est = evo_file_interface.read_tum_trajectory_file(str(estimate))
    ref, est = sync.associate_trajectories(ref, est)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return float(ape.get_statistic(metrics.StatisticsType.rmse))


@pytest.mark.slow
@pytest.mark.parametrize("alignment", ["anchor", "se2"])
def test_evo_ape_on_the_tum_files_equals_the_tables_rmse(tmp_path: Path, alignment: str) -> None:
    out, folder = tmp_path / "r.json", tmp_path / "tum"
    done = run_cli("replay", "square", "--align", alignment, "--tum", str(folder), "--json", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    results = json.loads(out.read_text())
    truth = folder / "truth.tum"
    assert truth.read_text().startswith("#")
    assert ape_rmse(truth, folder / "odometry.tum") == pytest.approx(results["odometry"]["rmse_m"], abs=1e-6)
    for name, figures in results["estimators"].items():
        assert ape_rmse(truth, folder / f"{name}.tum") == pytest.approx(figures["final_rmse_m"], abs=1e-6)
        if "online_rmse_m" in figures:
            online = ape_rmse(truth, folder / f"{name}_online.tum")
            assert online == pytest.approx(figures["online_rmse_m"], abs=1e-6)
    evo_ape = shutil.which("evo_ape")
    if evo_ape is not None:  # the command a user types prints the same figure
        printed = subprocess.run([evo_ape, "tum", str(truth), str(folder / "batch.tum")], capture_output=True,
                                 text=True, timeout=120).stdout  # fmt: skip
        rmse = float(next(line.split()[1] for line in printed.splitlines() if line.strip().startswith("rmse")))
        assert rmse == pytest.approx(results["estimators"]["batch"]["final_rmse_m"], abs=1e-6)
