"""A crash at a chosen point, for the tests of crash safety: no race with the machine's speed.

``ONLINE_SLAM_CRASH_AFTER=steps:N`` kills a replay with SIGKILL once it has recorded N steps (checkpoint due at N
written first); ``cells:N`` kills a sweep once N cells are in its output. Unset, :func:`crash_point` does nothing.
"""

from __future__ import annotations

import os
import signal

CRASH_VARIABLE = "ONLINE_SLAM_CRASH_AFTER"


def crash_point(counter: str, count: int) -> None:
    """SIGKILL this process (no handler, no flush) if ``$ONLINE_SLAM_CRASH_AFTER`` is ``counter:N`` with N <= count."""
    spec = os.environ.get(CRASH_VARIABLE)
    if not spec:
        return
    name, _, limit = spec.partition(":")
    if name == counter and count >= int(limit):
        os.kill(os.getpid(), signal.SIGKILL)
