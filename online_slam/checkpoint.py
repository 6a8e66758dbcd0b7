"""Checkpoints: state held in dataclasses, written as data only and read back bit for bit.

Every object whose state a checkpoint keeps is a dataclass (or holds its state in one). :func:`to_tree` walks
its fields into a tree of numbers, strings, lists, tuples, dicts and numpy arrays; :func:`from_tree` rebuilds
the object from such a tree, guided by the dataclass's type hints (nested dataclasses, ``X | None``, tuples,
lists, dicts keyed by ints, strings or tuples, sets, arrays). A field declared with ``init=False`` is derived
(a cache, an index): it is not saved, and ``__post_init__`` rebuilds it. A class takes part by its own
``to_tree(self)`` and classmethod ``from_tree(cls, tree)`` where it defines them (a dataclass too: a hashable
form for an id that keys a dict), else by its fields. So adding a state field is one
edit: the field, with its default.

A checkpoint file is a zip archive holding ``manifest.json`` (kind, format version, package version, and the
SHA-256 of every other member), ``state.json`` (the tree, with arrays replaced by references) and one ``.npy``
file per array (read back with ``allow_pickle=False``); a list of arrays that differ only in their first
dimension is one ``.npy`` file (their concatenation) and its lengths, a list of floats one float64 ``.npy``, a
list of tuples of one length its columns (so a list of ``(int, array)`` pairs is a list of ints and one array).
Nothing in it executes on load. A truncated, damaged or altered file, a file of another kind or of another
format version raises :class:`~online_slam.errors.InputError`. Floats survive bit for bit (arrays in binary,
finite JSON floats by shortest round-trip repr, NaN and infinities by their bits), so a run continued from a
checkpoint equals the run that never stopped.

Writing is atomic: the archive is written to a temporary file beside the target, flushed to disk, and renamed
over it, so a crash mid-write leaves the previous checkpoint intact. A file that cannot be written (a folder in
the way, no permission, a full disk) raises :class:`~online_slam.errors.OnlineSlamError` naming it, and leaves the
previous checkpoint as it was.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import math
import os
import struct
import tempfile
import types
import typing
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from online_slam.errors import InputError, OnlineSlamError
from online_slam.version import __version__

FORMAT_VERSION = 12
"""Version of the checkpoint layout; files of another version are refused."""


# -- objects <-> trees ---------------------------------------------------------------------------------------
def to_tree(value: Any) -> Any:
    """The state tree of a value: dataclasses become dicts of their saved fields, sets sorted lists.

    The tree shares the value's arrays: write it (:func:`write_checkpoint`) before the value changes.

    Raises:
        TypeError: A value that cannot be saved (an object array, a function, an object without ``to_tree``).
    """
    if callable(getattr(type(value), "to_tree", None)):
        return to_tree(value.to_tree())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_tree(getattr(value, f.name)) for f in dataclasses.fields(value) if f.init}
    if isinstance(value, np.ndarray):
        if value.dtype == object:
            raise TypeError("object arrays cannot be checkpointed")
        return value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {to_tree(k): to_tree(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(to_tree(v) for v in value)
    if isinstance(value, (list, set, frozenset)):
        items = list(value) if isinstance(value, list) else sorted(value, key=repr)  # same state, same file
        kinds = {type(v) for v in items}
        if kinds <= _LEAVES:  # nothing to convert (the common case: a long list of numbers, ids or arrays)
            return items
        return [to_tree(v) for v in items]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot checkpoint a {type(value).__name__}")


_LEAVES = {bool, int, float, str, type(None), np.ndarray}
"""Types that are their own tree."""


def from_tree(hint: Any, tree: Any) -> Any:
    """Rebuild a value of type ``hint`` (a class or a type hint such as ``dict[int, list[Array]]``) from its tree.

    Arrays are the tree's own (not copied).

    Raises:
        TypeError, ValueError, KeyError: The tree does not fit the type.
    """
    if hint is Any or hint is object:
        return tree
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Union or origin is types.UnionType:
        return _from_union(args, tree)
    if hint is type(None):
        if tree is not None:
            raise TypeError(f"expected None, got {type(tree).__name__}")
        return None
    if hint is np.ndarray or origin is np.ndarray:
        if not isinstance(tree, np.ndarray):
            raise TypeError(f"expected an array, got {type(tree).__name__}")
        return tree
    rebuild = getattr(hint, "from_tree", None) if isinstance(hint, type) else None
    if callable(rebuild):
        return rebuild(tree)
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return _from_dataclass(hint, tree)
    if hint in _SCALARS:
        return _from_scalar(hint, tree)
    container = origin or hint
    if container in (list, tuple, dict, set, frozenset):
        return _from_container(container, args, tree)
    raise TypeError(f"cannot rebuild a {hint!r}")


_SCALARS = (bool, int, float, str)


def _from_scalar(hint: type, tree: Any) -> Any:
    is_bool = isinstance(tree, bool)
    if hint is bool and is_bool or hint is str and isinstance(tree, str) or hint is int and type(tree) is int:
        return tree
    if hint is float and not is_bool and isinstance(tree, (int, float)):
        return float(tree)
    raise TypeError(f"expected {hint.__name__}, got {type(tree).__name__}")


def _from_union(args: tuple, tree: Any) -> Any:
    if tree is None and type(None) in args:
        return None
    errors = []
    for arg in args:
        if arg is type(None):
            continue
        try:
            return from_tree(arg, tree)
        except (TypeError, ValueError, KeyError) as exc:
            errors.append(f"not {getattr(arg, '__name__', arg)}: {exc}")
    raise TypeError("; ".join(errors) or f"expected None, got {type(tree).__name__}")


def _from_container(container: type, args: tuple, tree: Any) -> Any:
    if container is dict:
        if not isinstance(tree, dict):
            raise TypeError(f"expected a dict, got {type(tree).__name__}")
        key, value = args or (Any, Any)
        return {from_tree(key, k): from_tree(value, v) for k, v in tree.items()}
    if not isinstance(tree, (list, tuple)):
        raise TypeError(f"expected a sequence, got {type(tree).__name__}")
    if container is tuple and args and args[-1] is not Ellipsis:
        if len(args) != len(tree):
            raise ValueError(f"expected {len(args)} items, got {len(tree)}")
        return tuple(from_tree(a, v) for a, v in zip(args, tree))
    item = args[0] if args else Any
    return container(from_tree(item, v) for v in tree)


@functools.cache
def _saved_fields(cls: type) -> tuple[tuple[str, Any], ...]:
    """Names and type hints of the fields a dataclass saves (those set by ``__init__``)."""
    hints = typing.get_type_hints(cls)
    return tuple((f.name, hints[f.name]) for f in dataclasses.fields(cls) if f.init)


def _from_dataclass(cls: type, tree: Any) -> Any:
    if not isinstance(tree, dict):
        raise TypeError(f"expected the fields of {cls.__name__}, got {type(tree).__name__}")
    saved = _saved_fields(cls)
    if set(tree) != {name for name, _ in saved}:
        raise ValueError(f"{cls.__name__} has fields {sorted(n for n, _ in saved)}, the state {sorted(tree)}")
    return cls(**{name: from_tree(hint, tree[name]) for name, hint in saved})


class Checkpointed:
    """For a dataclass whose fields are its whole state: ``state_dict`` and an in-place ``load_state``."""

    def state_dict(self) -> Any:
        """The state tree of every field (see :func:`to_tree`)."""
        return to_tree(self)

    def load_state(self, tree: Any) -> None:
        """Take the state of a :meth:`state_dict` (derived fields rebuilt; the tree's arrays become its own)."""
        loaded = from_tree(type(self), tree)
        for f in dataclasses.fields(loaded):
            setattr(self, f.name, getattr(loaded, f.name))


# -- trees <-> JSON and arrays -------------------------------------------------------------------------------
_ARRAY, _ARRAYS, _FLOATS, _FLOAT, _TUPLE, _PAIRS, _COLUMNS = (
    "__array__",
    "__arrays__",
    "__floats__",
    "__float__",
    "__tuple__",
    "__pairs__",
    "__columns__",
)


_JSON = {bool, int, str, type(None)}
"""Types JSON holds as they are (floats aside: NaN and infinities are not JSON)."""


def _one_array(items: list) -> str | None:
    """How a list is stored as one array: ``floats``, ``arrays`` (of one dtype, differing only in their first
    dimension), or None (it is not, or it has fewer than two items: as it is, it takes no more members)."""
    if len(items) < 2:
        return None
    kinds = {type(v) for v in items}
    if kinds == {float}:
        return _FLOATS
    if kinds != {np.ndarray}:
        return None
    layouts = {(a.dtype.kind, a.dtype, a.ndim, a.shape[1:]) for a in items}
    kind, _, ndim, _ = layouts.pop()
    return _ARRAYS if not layouts and ndim > 0 and kind != "O" else None


def _is_table(items: list) -> bool:
    """Whether a list is rows of one length (tuples, not empty), stored column by column."""
    return bool(items) and {type(v) for v in items} == {tuple} and len({len(v) for v in items}) == 1 and bool(items[0])


def _pack(value: Any, arrays: list[np.ndarray]) -> Any:
    """The JSON-ready form of a state tree; arrays are appended to ``arrays`` and referenced by index."""
    if isinstance(value, np.ndarray):
        if value.dtype == object:
            raise TypeError("object arrays cannot be checkpointed")
        arrays.append(np.asarray(value, order="C"))  # (ascontiguousarray would make a 0-d array 1-d)
        return {_ARRAY: len(arrays) - 1}
    if isinstance(value, np.generic):
        return _pack(value.item(), arrays)
    if isinstance(value, float):
        return value if math.isfinite(value) else {_FLOAT: struct.pack("<d", value).hex()}
    if isinstance(value, dict):
        keys, values = list(value), list(value.values())
        if all(isinstance(k, str) and not k.startswith("__") for k in keys) and not _one_array(values):
            return {k: _pack(v, arrays) for k, v in value.items()}
        return {_PAIRS: [_pack(keys, arrays), _pack(values, arrays)]}
    if isinstance(value, tuple):
        return {_TUPLE: [_pack(v, arrays) for v in value]}
    if isinstance(value, list):
        stored = _one_array(value)
        if stored == _FLOATS:
            arrays.append(np.array(value, dtype=np.float64))
            return {_FLOATS: len(arrays) - 1}
        if stored == _ARRAYS:
            arrays.append(np.concatenate(value))
            arrays.append(np.array([len(a) for a in value], dtype=np.int64))
            return {_ARRAYS: [len(arrays) - 2, len(arrays) - 1]}
        if {type(v) for v in value} <= _JSON:
            return value
        if _is_table(value):
            return {_COLUMNS: [_pack(list(column), arrays) for column in zip(*value)]}
        return [_pack(v, arrays) for v in value]
    if value is None or isinstance(value, (bool, int, str)):
        return value
    raise TypeError(f"cannot checkpoint a {type(value).__name__}")


def _unpack(value: Any, arrays: dict[int, np.ndarray]) -> Any:
    if isinstance(value, list):
        return [_unpack(v, arrays) for v in value]
    if not isinstance(value, dict):
        return value
    if len(value) == 1:
        ((tag, body),) = value.items()
        if tag == _ARRAY:
            return arrays[int(body)]
        if tag == _FLOATS:
            return arrays[int(body)].astype(np.float64).tolist()
        if tag == _ARRAYS:
            joined, lengths = arrays[int(body[0])], arrays[int(body[1])].astype(np.int64)
            return np.split(joined, np.cumsum(lengths)[:-1]) if len(lengths) else []
        if tag == _FLOAT:
            return struct.unpack("<d", bytes.fromhex(body))[0]
        if tag == _TUPLE:
            return tuple(_unpack(v, arrays) for v in body)
        if tag == _PAIRS:
            return dict(zip(_unpack(body[0], arrays), _unpack(body[1], arrays), strict=True))
        if tag == _COLUMNS:
            return list(zip(*(_unpack(column, arrays) for column in body), strict=True))
    return {k: _unpack(v, arrays) for k, v in value.items()}


def write_checkpoint(path: str | Path, kind: str, state: Any) -> None:
    """Write a state tree atomically.

    Args:
        path: The checkpoint file.
        kind: What the state is (e.g. ``slam``, ``replay``); :func:`read_checkpoint` checks it.
        state: A dataclass, or a tree (nested dicts, lists, tuples, numbers, strings, None, numpy arrays (no
            object dtype) and dataclasses); see :func:`to_tree`.
    """
    arrays: list[np.ndarray] = []
    tree = _pack(to_tree(state), arrays)
    members: dict[str, bytes] = {"state.json": json.dumps(tree, allow_nan=False, separators=(",", ":")).encode()}
    for k, array in enumerate(arrays):
        buffer = io.BytesIO()
        np.lib.format.write_array(buffer, array, allow_pickle=False)
        members[f"arrays/{k}.npy"] = buffer.getvalue()
    manifest = {
        "format": "online-slam-checkpoint",
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "kind": kind,
        "sha256": {name: hashlib.sha256(data).hexdigest() for name, data in members.items()},
    }
    target = Path(path)
    temporary: str | None = None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        with os.fdopen(handle, "wb") as raw:
            with zipfile.ZipFile(raw, "w", compression=zipfile.ZIP_STORED) as archive:
                archive.writestr("manifest.json", json.dumps(manifest, indent=1))
                for name, data in members.items():
                    archive.writestr(name, data)
            raw.flush()
            os.fsync(raw.fileno())
        os.chmod(temporary, 0o644)
        os.replace(temporary, target)  # onto a folder: IsADirectoryError
    except BaseException as exc:
        if temporary is not None:
            Path(temporary).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise OnlineSlamError(f"cannot write checkpoint {path}: {exc.strerror or exc}") from None
        raise


def read_checkpoint(path: str | Path, kind: str, hint: Any = Any) -> Any:
    """Read a checkpoint written by :func:`write_checkpoint`.

    Args:
        path: The checkpoint file.
        kind: The kind it must be.
        hint: The type of the state (e.g. a dataclass), rebuilt by :func:`from_tree`; by default the tree.

    Returns:
        The state (arrays are fresh and writable).

    Raises:
        InputError: Missing, truncated, damaged or altered file; another kind; another format version.
    """
    name = str(path)

    def bad(message: str) -> InputError:
        return InputError(name, 0, "", f"not a usable checkpoint: {message}")

    try:
        with zipfile.ZipFile(name) as archive:
            manifest = json.loads(archive.read("manifest.json"))
            if not isinstance(manifest, dict) or manifest.get("format") != "online-slam-checkpoint":
                raise bad("not an online-slam checkpoint")
            if manifest.get("format_version") != FORMAT_VERSION:
                raise bad(f"format version {manifest.get('format_version')!r}; this version reads {FORMAT_VERSION}")
            if manifest.get("kind") != kind:
                raise bad(f"it holds a {manifest.get('kind')!r} state, not a {kind!r} state")
            digests = manifest.get("sha256")
            if not isinstance(digests, dict) or "state.json" not in digests:
                raise bad("manifest lists no state")
            if set(archive.namelist()) != {"manifest.json", *digests}:
                raise bad("members differ from the manifest")
            data = {}
            for member, digest in digests.items():
                content = archive.read(member)
                if hashlib.sha256(content).hexdigest() != digest:
                    raise bad(f"{member} was altered (checksum mismatch)")
                data[member] = content
    except InputError:
        raise
    except (FileNotFoundError, NotADirectoryError):
        raise InputError(name, 0, "", "no such checkpoint file") from None
    except (IsADirectoryError, PermissionError) as exc:
        raise InputError(name, 0, "", f"cannot read the checkpoint ({exc.strerror})") from None
    except (zipfile.BadZipFile, zipfile.LargeZipFile, KeyError, EOFError, OSError, ValueError) as exc:
        raise bad(f"damaged or truncated ({exc})") from None
    arrays: dict[int, np.ndarray] = {}
    try:
        for member, content in data.items():
            if member.startswith("arrays/"):
                k = int(member[len("arrays/") : -len(".npy")])
                arrays[k] = np.lib.format.read_array(io.BytesIO(content), allow_pickle=False)
        tree = json.loads(data["state.json"])
        return from_tree(hint, _unpack(tree, arrays))
    except (ValueError, KeyError, TypeError, IndexError, EOFError, struct.error) as exc:
        raise bad(f"damaged state ({exc})") from None
