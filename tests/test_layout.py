"""The repository's root holds only what README names; ``online_slam``'s namespace only the public API."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

import online_slam

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_the_root_holds_only_what_readme_names() -> None:
    tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    entries = {line.split("/")[0] + ("/" if "/" in line else "") for line in tracked.splitlines()}
    named = set(re.findall(r"`([^`\s]+)`", (ROOT / "README.md").read_text(encoding="utf-8")))
    assert sorted(entries - named) == []


def test_the_namespace_is_the_public_api() -> None:
    assert dir(online_slam) == sorted(online_slam.__all__)
    public = {name for name in vars(online_slam) if not name.startswith("_")}
    submodules = {name for name, value in vars(online_slam).items() if type(value).__name__ == "module"}
    assert public - submodules <= set(online_slam.__all__)
    for name in online_slam.__all__:
        assert getattr(online_slam, name) is not None
