"""Importers are plug-ins: a new format is one module and one line of the registry (docs/architecture.md)."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import pytest

import online_slam
from online_slam.errors import InputError
from online_slam.importers import registry
from online_slam.importers.resolve import open_source
from online_slam.options import _dataset_options

TOY = '''
"""A toy format: ``odo dx dy dth`` and ``see ID RANGE BEARING`` lines (``.toy``), ranges scaled by ``--toy-scale``."""

from dataclasses import dataclass

from online_slam.importers.registry import option
from online_slam.sources.events import Observation, Odometry


@dataclass(frozen=True)
class ToyOptions:
    toy_scale: float = option(1.0, "TOY: multiply every range by S", kind=float, metavar="S", positive=True)
    """Range scale."""


class Toy:
    name = "toy"
    summary = "toy file (.toy)"
    options = ToyOptions

    def detect(self, path):
        return path.suffix == ".toy"

    def refuse(self, path):
        return None

    def open(self, path, options):
        t = 0.0
        for line in path.read_text().splitlines():
            word, *rest = line.split()
            if word == "odo":
                t += 1.0
                yield Odometry(t, tuple(map(float, rest)), sigma=(0.05, 0.05, 0.01))
            else:
                yield Observation(t, rest[0], range=options.toy_scale * float(rest[1]), bearing=float(rest[2]),
                                  sigma=(0.1, 0.01))


IMPORTER = Toy()
'''


@pytest.fixture
def toy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The toy importer's module on sys.path and its line in the registry; a toy file."""
    (tmp_path / "toy_importer.py").write_text(textwrap.dedent(TOY))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "REGISTRY", (*registry.REGISTRY, "toy_importer"))
    registry.importers.cache_clear()
    yield tmp_path / "run.toy"
    registry.importers.cache_clear()
    sys.modules.pop("toy_importer", None)


def test_a_toy_importer_is_one_module_and_one_registry_line(toy: Path) -> None:
    toy.write_text("see a 2.0 0.1\nodo 1 0 0\nsee a 1.0 0.2\nodo 1 0 0.1\nsee a 0.5 0.4\n")
    assert "toy" in registry.names() and registry.detect(toy) == "toy"
    assert any(o.name == "toy_scale" and "TOY" in o.help for o in _dataset_options())  # its flag
    name, events = open_source(toy, toy_scale=2.0)
    assert [e.range for e in events if hasattr(e, "range")] == [4.0, 2.0, 1.0]
    results = online_slam.replay(toy, online_slam.ReplayConfig(estimators=("ekf",), dataset={"toy_scale": 2.0}))
    assert results.poses == 3 and results.observations == 3
    with pytest.raises(InputError, match="--robot applies to mrclam data, not to toy data"):
        open_source(toy, robot=1)
    with pytest.raises(InputError, match="--toy-scale applies to toy data, not to a built-in world"):
        open_source("square", toy_scale=2.0)


def test_every_registered_importer_follows_the_protocol() -> None:
    for name, importer in registry.importers().items():
        assert importer.name == name and importer.summary
        assert callable(importer.detect) and callable(importer.open) and callable(importer.refuse)
        for field in registry.fields(name).values():
            assert field.metadata["help"], f"{name}.{field.name} has no help"
