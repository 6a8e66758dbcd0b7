"""The command line run inside the test's own process: exit code, stdout and stderr as a shell would see them.

A new interpreter spends 1.5-2 s importing scipy.stats, filterpy and rerun before a command starts; the suite runs
about 140 commands, so most tests call :func:`main` here instead. Real processes remain where the process is the
point: README's two replays, kill and Ctrl-C with resume, sweeps on a scheduler, the viewer, the import-laziness
checks and the benchmarks.
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

from online_slam.cli.main import main
from online_slam.faults import CRASH_VARIABLE


def _text_stream(data: bytes = b"") -> io.TextIOWrapper:
    """A text stream with a ``.buffer`` (the package reads stdin's bytes), as a pipe gives."""
    return io.TextIOWrapper(io.BytesIO(data), encoding="utf-8", write_through=True)


@contextlib.contextmanager
def _folder(cwd: Path | str | None) -> Iterator[None]:
    """The working folder ``cwd`` for the block (None: unchanged), restored after (``contextlib.chdir`` is 3.11+)."""
    saved = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        yield
    finally:
        os.chdir(saved)


def run_cli(*args: str, stdin: str | None = None, cwd: Path | str | None = None) -> subprocess.CompletedProcess:
    """``online-slam *args`` in this process (in the folder ``cwd`` when given): its exit code (``SystemExit``
    included) and what it printed.

    Python warnings raised during the command are printed to its stderr as an interpreter would print them, so a
    test that reads stderr sees them. A crash point (``$ONLINE_SLAM_CRASH_AFTER``) would kill this process: refused.
    """
    if CRASH_VARIABLE in os.environ:
        raise RuntimeError(f"${CRASH_VARIABLE} kills the process: start the executable for that test")
    out, err, source = _text_stream(), _text_stream(), _text_stream((stdin or "").encode())
    saved = sys.stdin, sys.stdout, sys.stderr
    sys.stdin, sys.stdout, sys.stderr = source, out, err
    try:
        with _folder(cwd), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                code = main(list(args))
            except SystemExit as stop:  # argparse's usage errors, --help and --version
                if isinstance(stop.code, str):
                    print(stop.code, file=sys.stderr)
                code = 1 if isinstance(stop.code, str) else int(stop.code or 0)
        for w in caught:
            err.write(warnings.formatwarning(w.message, w.category, w.filename, w.lineno, w.line))
    finally:
        sys.stdin, sys.stdout, sys.stderr = saved
    texts = [stream.buffer.getvalue().decode("utf-8") for stream in (out, err)]  # type: ignore[attr-defined]
    return subprocess.CompletedProcess(["online-slam", *args], code, *texts)
