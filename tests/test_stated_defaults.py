"""Every default the docs and the docstrings state is the one the code has.

Three ways a default is stated, each checked: in a page, a flag and its default (```--window` W poses (default
20)``, ```--ekf-update joint` (default)``); in any docstring, an option's value named as the default
(``By default (``linearization="standard"``)``, ``smoother_linearization="fej"`` (default)); in a configuration
field's own docstring, ``Default X`` or ``X (default)`` against that field's default.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import re
from pathlib import Path

import pytest

from online_slam.options import OPTIONS

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SOURCES = sorted((ROOT / "online_slam").rglob("*.py"))
VALUE = r"([A-Za-z0-9_.+-]+)"

FLAG_THEN_DEFAULT = re.compile(r"`(--[a-z][a-z0-9-]*)`[^.;`\n]{0,40}?\(?default:? `{0,2}" + VALUE)
"""```--window` W poses (default 20)``, ``(`--relinearize-every`, default 1)``."""
FLAG_VALUE_DEFAULT = re.compile(r"`(--[a-z][a-z0-9-]*) " + VALUE + r"`,? \((?:the )?default\)")
"""```--ekf-update joint` (default)``."""
NAMED_DEFAULT = [
    re.compile(r"[Dd]efault[^.;\n]{0,12}?``([a-z_]+)=\"?" + VALUE + r"\"?``"),
    re.compile(r"``([a-z_]+)=\"?" + VALUE + r"\"?`` \((?:the )?default\)"),
]
"""In docstrings: ``By default (``name="value"``)``, ````name="value"`` (default)``."""
FIELD_DEFAULT = [
    re.compile(r"\b[Dd]efault:? (?:``([^`]+)``|(-?[0-9][0-9.e+-]*[0-9]|[0-9]))"),
    re.compile(r"``" + VALUE + r"`` \((?:the )?default\)"),
]
"""In a field's own docstring: ``Default 18 m``, ````auto`` (default)``."""


def _same(stated: str, actual: object) -> bool:
    stated = stated.rstrip(".,")
    if isinstance(actual, bool):
        return stated.lower() in (str(actual).lower(), "on" if actual else "off")
    if isinstance(actual, (int, float)):
        try:
            return float(stated) == float(actual)
        except ValueError:
            return False
    return stated == str(actual)


def _options_by_flag() -> dict[str, object]:
    return {o.flag: o.value for o in OPTIONS.values() if o.value is not None}


def _options_by_name() -> dict[str, list[object]]:
    """An option's value under its name and under its field's name (``linearization``: the EKF's and the
    smoother's)."""
    out: dict[str, list[object]] = {}
    for o in OPTIONS.values():
        if o.value is None:
            continue
        out.setdefault(o.name, []).append(o.value)
        if o.field is not None:
            out.setdefault(o.field[1], []).append(o.value)
    return out


def stated_in_pages(text: str) -> list[tuple[str, str]]:
    """(flag, stated default) pairs of a page."""
    return [m.groups() for p in (FLAG_THEN_DEFAULT, FLAG_VALUE_DEFAULT) for m in p.finditer(text)]


def stated_in_docstring(text: str) -> list[tuple[str, str]]:
    """(name, stated default) pairs of a docstring."""
    return [m.groups() for p in NAMED_DEFAULT for m in p.finditer(text)]


def field_docstrings(path: Path) -> list[tuple[str, str, str]]:
    """(class, field, docstring) of every annotated class attribute followed by a string, in a module."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.ClassDef):
            continue
        for a, b in zip(node.body, node.body[1:]):
            field = isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name) and a.value is not None
            text = isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant) and isinstance(b.value.value, str)
            if field and text:
                out.append((node.name, a.target.id, b.value.value))
    return out


def docstrings(path: Path) -> list[str]:
    """Every docstring of a module (module, classes, functions, attributes)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [
        node.value.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)
    ]


def _module(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def stale_defaults() -> list[str]:
    """Every stated default that is not the code's, as ``where: stated -> actual``."""
    stale = []
    by_flag, by_name = _options_by_flag(), _options_by_name()
    for page in PAGES:
        for flag, stated in stated_in_pages(page.read_text(encoding="utf-8")):
            if flag in by_flag and not _same(stated, by_flag[flag]):
                stale.append(f"{page.name}: {flag} default {stated} -> {by_flag[flag]}")
    for path in SOURCES:
        for text in docstrings(path):
            for name, stated in stated_in_docstring(text):
                if name in by_name and not any(_same(stated, v) for v in by_name[name]):
                    stale.append(f"{_module(path)}: {name}={stated} default -> {' or '.join(map(str, by_name[name]))}")
        fields = field_docstrings(path)
        if not fields:
            continue
        module = importlib.import_module(_module(path))
        for cls, name, text in fields:
            owner = getattr(module, cls, None)
            if owner is None or not dataclasses.is_dataclass(owner):
                continue
            field = {f.name: f for f in dataclasses.fields(owner)}.get(name)
            if field is None or field.default is dataclasses.MISSING:
                continue
            for pattern in FIELD_DEFAULT:
                for m in pattern.finditer(text):
                    stated = next(g for g in m.groups() if g is not None)
                    if not _same(stated, field.default):
                        stale.append(f"{_module(path)}.{cls}.{name}: default {stated} -> {field.default}")
    return stale


def test_every_stated_default_is_the_codes() -> None:
    assert stale_defaults() == []


@pytest.mark.parametrize(
    ("text", "finds"),
    [
        ("Every K steps (`--relinearize-every`, default 1) and", [("--relinearize-every", "1")]),
        ("beyond `--window` W poses (default 20) it keeps", [("--window", "20")]),
        ("`--ekf-update joint` (default) uses one update", [("--ekf-update", "joint")]),
    ],
)
def test_the_page_patterns_find_what_pages_write(text: str, finds: list) -> None:
    assert stated_in_pages(text) == finds


def test_a_stale_default_is_caught() -> None:
    """The smoother's docstring once said ``By default (``linearization="standard"``)`` after the default moved."""
    (pair,) = stated_in_docstring('By default (``linearization="standard"``) it is re-centred')
    by_name = _options_by_name()
    assert pair == ("linearization", "standard")
    assert not any(_same(pair[1], v) for v in by_name["smoother_linearization"])
    assert stated_in_pages("at most `--window-max` poses (default 12).") == [("--window-max", "12")]
    assert not _same("12", _options_by_flag()["--window-max"])
