"""The generic state serializer: any nested dataclass survives to_tree -> file -> from_tree bit for bit."""

from __future__ import annotations

import dataclasses
import math
import struct
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.typing import NDArray

from online_slam.checkpoint import Checkpointed, from_tree, read_checkpoint, to_tree, write_checkpoint
from online_slam.estimators.dead_reckoning import DeadReckoning
from online_slam.estimators.history import PoseHistory
from online_slam.estimators.smoother import GlobalConfig, SmootherConfig, WindowConfig
from online_slam.frontend.steps import FrontEndConfig, KeyframeConfig
from online_slam.pipeline import Checkpointing, ReplayConfig, replay, run
from online_slam.pipeline.config import build_estimators
from online_slam.sources.worlds import Contamination, GridConfig, contaminate, grid_world, without_ids

DTYPES = (np.float64, np.float32, np.int64, np.int32, np.uint8, np.bool_, np.complex128)


def arrays() -> st.SearchStrategy[np.ndarray]:
    """Arrays of several dtypes and shapes, empty ones and 0-d ones included."""
    shapes = hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=3)
    return st.sampled_from(DTYPES).flatmap(lambda dtype: hnp.arrays(np.dtype(dtype), shapes))


LEAVES: list[tuple[Any, st.SearchStrategy]] = [
    (int, st.integers(-(2**62), 2**62)),
    (float, st.floats(allow_nan=True, allow_infinity=True)),
    (str, st.text(max_size=5)),
    (bool, st.booleans()),
    (NDArray[np.float64], arrays()),
    (int | str, st.one_of(st.integers(-5, 5), st.text(max_size=3))),  # a landmark id
]
KEYS: list[tuple[Any, st.SearchStrategy]] = [
    (int, st.integers(-5, 5)),
    (str, st.text(max_size=4)),  # "__x" keys too
    (int | str, st.one_of(st.integers(-5, 5), st.text(max_size=3))),
    (tuple[int, str], st.tuples(st.integers(-5, 5), st.text(max_size=2))),
]


def lists_of(item: st.SearchStrategy) -> st.SearchStrategy:
    return st.lists(item, max_size=4)


def same_shape_arrays() -> st.SearchStrategy[list[np.ndarray]]:
    """Arrays of one dtype that differ only in their first dimension (stored as one array)."""

    def build(dtype: Any, rest: tuple[int, ...]) -> st.SearchStrategy:
        one = st.integers(0, 3).flatmap(lambda n: hnp.arrays(np.dtype(dtype), (n, *rest)))
        return st.lists(one, min_size=1, max_size=4)

    rest = hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=3)
    return st.tuples(st.sampled_from(DTYPES), rest).flatmap(lambda pair: build(*pair))


@st.composite
def typed(draw: st.DrawFn, depth: int = 0) -> tuple[Any, st.SearchStrategy]:
    """A type hint and a strategy for its values: leaves, containers, optionals and nested dataclasses."""
    kinds = ["leaf"] if depth >= 3 else ["leaf", "list", "tuple", "fixed", "dict", "set", "optional", "dataclass"]
    kind = draw(st.sampled_from(kinds))
    if kind == "leaf":
        return draw(st.sampled_from(LEAVES))
    if kind == "set":
        return set[int], st.sets(st.integers(-9, 9), max_size=4)
    if kind == "dataclass":
        return draw(dataclasses_of(depth + 1))
    hint, values = draw(typed(depth + 1))
    if kind == "list":
        return list[hint], lists_of(values)  # type: ignore[valid-type]
    if kind == "tuple":
        return tuple[hint, ...], lists_of(values).map(tuple)  # type: ignore[valid-type]
    if kind == "fixed":
        other, more = draw(typed(depth + 1))
        return tuple[hint, other], st.tuples(values, more)  # type: ignore[valid-type]
    if kind == "dict":
        key, keys = draw(st.sampled_from(KEYS))
        return dict[key, hint], st.dictionaries(keys, values, max_size=4)  # type: ignore[valid-type]
    return hint | None, st.one_of(st.none(), values)


@st.composite
def dataclasses_of(draw: st.DrawFn, depth: int = 0) -> tuple[type, st.SearchStrategy]:
    """A fresh dataclass (frozen or not) with random fields, one derived (``init=False``), and its values."""
    fields = [(f"f{k}", *draw(typed(depth))) for k in range(draw(st.integers(0, 4)))]
    fields.append(("ragged", list[NDArray[np.float64]], same_shape_arrays()))
    frozen = draw(st.booleans())
    cls = dataclasses.make_dataclass(
        f"State{depth}",
        [(name, hint) for name, hint, _ in fields] + [("derived", int, dataclasses.field(init=False, default=7))],
        frozen=frozen,
        eq=False,
    )
    return cls, st.builds(cls, **{name: values for name, _, values in fields})


def assert_identical(a: Any, b: Any, where: str = "state") -> None:
    """Same types, same structure, arrays of the same dtype and shape, floats with the same bits."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), where
    elif isinstance(a, float):
        assert struct.pack("<d", a) == struct.pack("<d", b), f"{where}: {a!r} != {b!r}"
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            assert_identical(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            assert_identical(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            assert_identical(x, y, f"{where}[{k}]")
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


@pytest.mark.slow
@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
)
@given(st.data())
def test_random_nested_dataclasses_survive_a_checkpoint_file_bit_for_bit(tmp_path: Path, data: st.DataObject) -> None:
    cls, values = data.draw(dataclasses_of())
    state = data.draw(values)
    assert_identical(from_tree(cls, to_tree(state)), state)
    path = tmp_path / "state.ckpt"  # overwritten by each example
    write_checkpoint(path, "test", state)
    back = read_checkpoint(path, "test", cls)
    assert_identical(back, state)
    assert back.derived == 7  # derived fields are rebuilt, not read


def test_floats_keep_their_bits_alone_and_in_lists(tmp_path: Path) -> None:
    odd_nan = struct.unpack("<d", bytes.fromhex("0100000000f8ffff"))[0]  # a negative NaN with a payload
    values = [odd_nan, -0.0, math.inf, -math.inf, 5e-324, 0.1]
    write_checkpoint(tmp_path / "f.ckpt", "test", {"one": odd_nan, "many": values, "pair": (odd_nan, 1.0)})
    back = read_checkpoint(tmp_path / "f.ckpt", "test", dict[str, Any])
    assert_identical(back, {"one": odd_nan, "many": values, "pair": (odd_nan, 1.0)})


def test_lists_of_arrays_are_one_member_and_come_back_as_separate_arrays(tmp_path: Path) -> None:
    rows = [np.full((k, 2), float(k)) for k in range(500)]
    write_checkpoint(tmp_path / "r.ckpt", "test", {"rows": rows})
    with zipfile.ZipFile(tmp_path / "r.ckpt") as archive:
        assert sum(name.endswith(".npy") for name in archive.namelist()) == 2  # the rows and their lengths
    back = read_checkpoint(tmp_path / "r.ckpt", "test", dict[str, list[NDArray[np.float64]]])["rows"]
    assert_identical(back, rows)
    back[3][0, 0] = -1.0
    assert back[4][0, 0] == 4.0  # one array each


def test_lists_of_rows_are_stored_by_columns(tmp_path: Path) -> None:
    """A list of equal-length tuples (a smoother's outlier decisions: (pose, mask) per pose) is its columns: the
    ints in JSON and the arrays one member; a list of one array is that array alone."""
    rows = [(k, np.arange(k) % 3 == 0) for k in range(300)]
    write_checkpoint(tmp_path / "t.ckpt", "test", {"rows": rows, "one": [np.ones(2)]})
    with zipfile.ZipFile(tmp_path / "t.ckpt") as archive:
        assert sum(name.endswith(".npy") for name in archive.namelist()) == 3  # the masks, their lengths, the one
    back = read_checkpoint(tmp_path / "t.ckpt", "test")
    assert_identical(from_tree(list[tuple[int, NDArray[np.bool_]]], back["rows"]), rows)
    assert_identical(back["one"], [np.ones(2)])


@dataclasses.dataclass(eq=False)
class _Book(Checkpointed):
    inside: bool
    seen: set[int | str] = dataclasses.field(default_factory=set)
    history: PoseHistory = dataclasses.field(default_factory=PoseHistory)
    index: dict[int, int] = dataclasses.field(init=False)

    def __post_init__(self) -> None:
        self.index = {k: 2 * k for k in range(len(self.history))}


def test_checkpointed_loads_in_place_and_classes_with_their_own_tree_take_part() -> None:
    book = _Book(True, {1, "a"})
    for k in range(70):  # past the history's first buffer
        book.history.append(np.array([k, 0.5 * k, -k]))
    other = _Book(False)
    other.load_state(book.state_dict())
    assert other.inside and other.seen == {1, "a"} and other.index[69] == 138
    np.testing.assert_array_equal(other.history.view(), book.history.view())


@pytest.mark.parametrize(
    ("hint", "tree", "error"),
    [
        (_Book, {"inside": True, "seen": [], "history": np.zeros((0, 3)), "extra": 1}, ValueError),
        (_Book, {"inside": True, "seen": []}, ValueError),
        (int, 1.5, TypeError),
        (int, True, TypeError),
        (float, "1", TypeError),
        (NDArray[np.float64], [1.0], TypeError),
        (tuple[int, int], [1, 2, 3], ValueError),
        (int | None, "x", TypeError),
    ],
)
def test_trees_that_do_not_fit_the_type_are_refused(hint: Any, tree: Any, error: type) -> None:
    with pytest.raises(error):
        from_tree(hint, tree)


@pytest.mark.parametrize("value", [np.array([object()]), object(), lambda: 1])
def test_values_that_are_not_data_are_refused(value: Any, tmp_path: Path) -> None:
    for state in ({"x": value}, {"x": [1, value]}, {"x": [value, value]}):
        with pytest.raises(TypeError):
            write_checkpoint(tmp_path / "x.ckpt", "test", state)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("world", "config"),
    [
        ("ids", ReplayConfig()),
        ("ids", ReplayConfig(frontend=FrontEndConfig(KeyframeConfig(1.0, 0.5), first_observation_only=True))),
        (
            "contaminated",
            ReplayConfig(
                extra_smoothers=(
                    SmootherConfig(window=WindowConfig(size=5), global_solve=GlobalConfig(every=20, delay=10)),
                )
            ),
        ),
        ("without ids", ReplayConfig(association="jcbb")),
    ],
)
@pytest.mark.slow
def test_every_state_a_replay_saves_is_rebuilt_by_its_types(
    world: str, config: ReplayConfig, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Checkpoints every 7 steps of varied runs read back as their dataclasses, and every estimator's state as its
    own (a wrong type hint fails here; the extra smoother has a background global solve pending at some)."""
    events: Any = grid_world(GridConfig(poses=80, seed=4))  # marginalization begins at pose 21
    if world == "contaminated":
        events = contaminate(events, Contamination(wrong_ids=0.1, clutter=0.2, seed=2))
    if world == "without ids":
        events = without_ids(events)
    read: list[int] = []
    estimators = {e.name: e for e in [DeadReckoning(), *build_estimators(config)]}

    def write_and_read(target: Path, kind: str, state: Any) -> None:
        write_checkpoint(target, kind, state)
        back = read_checkpoint(target, kind, run.ReplayCheckpoint)
        read.append(back.engine.state.steps)
        assert_identical(to_tree(back), to_tree(state))
        assert sorted(back.engine.estimators) == sorted(estimators)
        for name, tree in back.engine.estimators.items():  # rebuilt from its tree by its state's types
            estimators[name].load_state(tree)
            assert_identical(to_tree(estimators[name].state_dict()), state.engine.estimators[name], name)

    monkeypatch.setattr(run, "write_checkpoint", write_and_read)
    replay(list(events), config, checkpoint=Checkpointing(tmp_path, 7), validate=False)
    assert read == list(range(7, 81, 7))
