"""A crash or an interrupt at a chosen point, for the tests of crash safety: no race with the machine's speed.

``ONLINE_SLAM_CRASH_AFTER=steps:N`` kills a replay with SIGKILL once it has recorded N steps (checkpoint due at N
written first); ``cells:N`` kills a sweep once N cells are in its output. A third part names another signal, sent
once, at N exactly: ``steps:N:INT`` is a Ctrl-C after step N. Unset, :func:`crash_point` does nothing.
"""

from __future__ import annotations

import os
import signal

CRASH_VARIABLE = "ONLINE_SLAM_CRASH_AFTER"


def crash_point(counter: str, count: int) -> None:
    """Signal this process if ``$ONLINE_SLAM_CRASH_AFTER`` is ``counter:N[:SIGNAL]``: SIGKILL (no handler, no flush)
    once N <= count, or the named signal (``INT``, ``TERM``) when N == count."""
    spec = os.environ.get(CRASH_VARIABLE)
    if not spec:
        return
    name, limit, *sent = spec.split(":")
    if name != counter:
        return
    if not sent and count >= int(limit):
        os.kill(os.getpid(), signal.SIGKILL)
    elif sent and count == int(limit):
        os.kill(os.getpid(), getattr(signal, f"SIG{sent[0]}"))
