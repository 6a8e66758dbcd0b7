"""Checkpoint files: a state tree of numbers, strings, lists, dicts and numpy arrays, saved as data only.

A checkpoint is a zip archive holding ``manifest.json`` (kind, format version, package version, and the
SHA-256 of every other member), ``state.json`` (the tree, with arrays replaced by references) and one ``.npy``
file per array (read back with ``allow_pickle=False``). Nothing in it executes on load. A truncated, damaged or
altered file, a file of another kind or of another format version raises
:class:`~online_slam.errors.InputError`. Floats survive exactly (arrays in binary, JSON floats by shortest
round-trip repr), so a run continued from a checkpoint equals the run that never stopped.

Writing is atomic: the archive is written to a temporary file beside the target, flushed to disk, and renamed
over it, so a crash mid-write leaves the previous checkpoint intact. A file that cannot be written (a folder in
the way, no permission, a full disk) raises :class:`~online_slam.errors.OnlineSlamError` naming it, and leaves the
previous checkpoint as it was.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from online_slam.errors import InputError, OnlineSlamError
from online_slam.version import __version__

FORMAT_VERSION = 1
"""Version of the checkpoint layout; files of another version are refused."""

_ARRAY, _TUPLE, _PAIRS = "__array__", "__tuple__", "__pairs__"


def _pack(value: Any, arrays: list[np.ndarray]) -> Any:
    """The JSON-ready form of a state tree; arrays are appended to ``arrays`` and referenced by index."""
    if isinstance(value, np.ndarray):
        if value.dtype == object:
            raise TypeError("object arrays cannot be checkpointed")
        arrays.append(np.ascontiguousarray(value))
        return {_ARRAY: len(arrays) - 1}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        if all(isinstance(k, str) and not k.startswith("__") for k in value):
            return {k: _pack(v, arrays) for k, v in value.items()}
        return {_PAIRS: [[_pack(k, arrays), _pack(v, arrays)] for k, v in value.items()]}
    if isinstance(value, tuple):
        return {_TUPLE: [_pack(v, arrays) for v in value]}
    if isinstance(value, list):
        return [_pack(v, arrays) for v in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot checkpoint a {type(value).__name__}")


def _unpack(value: Any, arrays: dict[int, np.ndarray]) -> Any:
    if isinstance(value, list):
        return [_unpack(v, arrays) for v in value]
    if isinstance(value, dict):
        if set(value) == {_ARRAY}:
            return arrays[int(value[_ARRAY])].copy()
        if set(value) == {_TUPLE}:
            return tuple(_unpack(v, arrays) for v in value[_TUPLE])
        if set(value) == {_PAIRS}:
            return {_hashable(_unpack(k, arrays)): _unpack(v, arrays) for k, v in value[_PAIRS]}
        return {k: _unpack(v, arrays) for k, v in value.items()}
    return value


def _hashable(value: Any) -> Any:
    return tuple(_hashable(v) for v in value) if isinstance(value, list) else value


def write_checkpoint(path: str | Path, kind: str, state: Any) -> None:
    """Write a state tree atomically.

    Args:
        path: The checkpoint file.
        kind: What the state is (e.g. ``slam``, ``replay``); :func:`read_checkpoint` checks it.
        state: Nested dicts, lists, tuples, numbers, strings, None and numpy arrays (no object dtype).
    """
    arrays: list[np.ndarray] = []
    tree = _pack(state, arrays)
    members: dict[str, bytes] = {"state.json": json.dumps(tree, allow_nan=True, separators=(",", ":")).encode()}
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


def read_checkpoint(path: str | Path, kind: str) -> Any:
    """Read a checkpoint written by :func:`write_checkpoint`.

    Args:
        path: The checkpoint file.
        kind: The kind it must be.

    Returns:
        The state tree (arrays are fresh, writable copies).

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
        return _unpack(tree, arrays)
    except (ValueError, KeyError, TypeError, EOFError) as exc:
        raise bad(f"damaged state ({exc})") from None
