"""README's library example runs as written."""

from __future__ import annotations

import contextlib
import io
import os
import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_library_example_runs(tmp_path: Path) -> None:
    text = README.read_text()
    section = text[text.index("## Use it as a library") :]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) >= 2
    here = os.getcwd()
    os.chdir(tmp_path)  # the example writes run.ckpt
    try:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            namespace: dict = {}
            for block in blocks[:2]:
                exec(compile(block, str(README), "exec"), namespace)
    finally:
        os.chdir(here)
    printed = out.getvalue()
    assert "Slam.add_observation: range: expected a range > 0" in printed
    assert (tmp_path / "run.ckpt").is_file()
    assert namespace["estimate"].trajectory.shape == (2, 3)
    assert abs(namespace["results"].estimators["batch"].final_rmse_m - 0.0822) < 1e-4
