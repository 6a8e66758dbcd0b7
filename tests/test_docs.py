"""The documentation runs as written: every Python example executes and every relative link resolves.

Each page's ```python blocks run in order in one namespace, in a fresh folder. A block may be left out only with
a reason, by an HTML comment on the line before its fence: ``<!-- docs-test: skip: needs a running viewer -->``.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
EXAMPLE_PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
"""Pages whose Python examples must run."""
LINKED_PAGES = [*EXAMPLE_PAGES, *sorted((ROOT / "benchmarks").glob("*.md"))]
"""Pages whose relative links must resolve."""

FENCE = re.compile(r"^```.*?^```[ \t]*$", flags=re.S | re.M)
PYTHON_BLOCK = re.compile(
    r"(?:^<!-- docs-test: skip:(?P<reason>[^>]*)-->\n)?^```python\n(?P<code>.*?)^```", re.S | re.M
)
LINK = re.compile(r"\[[^\]]*\]\((?P<target>[^)\s]+)(?:\s+\"[^\"]*\")?\)")
INLINE_CODE = re.compile(r"`[^`\n]*`")
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def _name(page: Path) -> str:
    return str(page.relative_to(ROOT))


def python_blocks(page: Path) -> list[str]:
    """The page's Python examples in order, without those marked to skip (whose reason must be given)."""
    blocks = []
    for match in PYTHON_BLOCK.finditer(page.read_text()):
        reason = match["reason"]
        if reason is None:
            blocks.append(match["code"])
        else:
            assert reason.strip(), f"{_name(page)}: a skipped example must say why"
    return blocks


def run_page(page: Path, folder: Path) -> tuple[dict, str]:
    """Run a page's examples in ``folder``, in one namespace; return it and what they printed."""
    namespace: dict = {"__name__": "__docs__"}
    out = io.StringIO()
    here = os.getcwd()
    os.chdir(folder)
    try:
        with contextlib.redirect_stdout(out):
            for block in python_blocks(page):
                exec(compile(block, _name(page), "exec"), namespace)
    finally:
        os.chdir(here)
    return namespace, out.getvalue()


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces as hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every heading anchor of a Markdown page, with GitHub's -1, -2 suffixes for repeats."""
    seen: dict[str, int] = {}
    found = set()
    for line in FENCE.sub("", page.read_text()).splitlines():
        heading = re.match(r"^#{1,6}\s+(.*)$", line)
        if heading:
            base = slug(heading[1])
            found.add(base if base not in seen else f"{base}-{seen[base]}")
            seen[base] = seen.get(base, 0) + 1
    return found


def relative_links(page: Path) -> list[str]:
    """Link targets of a page that are not URLs, outside code blocks and inline code."""
    text = INLINE_CODE.sub("", FENCE.sub("", page.read_text()))
    return [m["target"] for m in LINK.finditer(text) if not SCHEME.match(m["target"])]


def broken(page: Path, target: str) -> str | None:
    """Why a relative link does not resolve, or None when it does."""
    path, _, fragment = target.partition("#")
    resolved = (page.parent / path).resolve() if path else page
    if not resolved.is_relative_to(ROOT):
        return "points outside the repository"
    if not resolved.exists():
        return "no such file"
    if fragment and (resolved.suffix != ".md" or fragment not in anchors(resolved)):
        return f"no heading #{fragment} in {_name(resolved)}"
    return None


def test_readme_example_runs(tmp_path: Path) -> None:
    namespace, printed = run_page(README, tmp_path)
    assert "Slam.add_observation: range: expected a range > 0" in printed
    assert (tmp_path / "run.ckpt").is_file()
    assert namespace["estimate"].trajectory.shape == (2, 3)
    assert abs(namespace["results"].estimators["batch"].final_rmse_m - 0.0822) < 1e-4


@pytest.mark.parametrize("page", [p for p in EXAMPLE_PAGES if p != README and python_blocks(p)], ids=_name)
def test_page_examples_run(page: Path, tmp_path: Path) -> None:
    run_page(page, tmp_path)


@pytest.mark.parametrize("page", LINKED_PAGES, ids=_name)
def test_relative_links_resolve(page: Path) -> None:
    failures = [f"{target}: {why}" for target in relative_links(page) if (why := broken(page, target))]
    assert not failures, f"{_name(page)}: " + "; ".join(failures)


def test_the_link_checker_sees_a_broken_link() -> None:
    page = ROOT / "docs" / "formats.md"
    assert broken(page, "#stream-format-v1") is None
    assert broken(page, "#no-such-heading") is not None
    assert broken(page, "missing.md") is not None
    assert slug("Results JSON (`replay --json`)") == "results-json-replay---json"
