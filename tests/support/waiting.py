"""Waiting for something observable, instead of sleeping for a guessed time.

A test's bound on a wait says how long the awaited progress may take on a machine that
is not busy; it is a hang detector, never the thing tested. On a loaded machine every
process gets a fraction of a core (at a load average of 20 on 2 cores, a tenth: a
`ground-cli` then took 30-60 s to start), so each bound is `stretched` by how loaded the
machine is when the wait starts: the same progress, more wall-clock time. On a machine
that is not busy the bounds are as written. pytest-timeout's per-test limit still ends
a test that hangs.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Literal

#: How often a condition is polled, seconds.
POLL_S = 0.05
#: A bound is stretched at most this many times.
MAX_STRETCH = 4.0


def load_per_core() -> float:
    """The last minute's load average per core (runnable processes per core)."""
    try:
        return os.getloadavg()[0] / (os.cpu_count() or 1)
    except OSError:  # not available on this system
        return 0.0


def stretched(seconds: float) -> float:
    """`seconds` of progress on a machine that is not busy, in wall-clock seconds on this
    one now: times the load average per core, from 1 to `MAX_STRETCH` times."""
    return seconds * min(MAX_STRETCH, max(1.0, load_per_core()))


def wait_until(
    predicate: Callable[..., object], timeout: float = 5.0, what: str = "the condition"
) -> Literal[True]:
    """Poll `predicate` until it is true; AssertionError naming `what` after `timeout` s
    (`stretched` on a loaded machine).

    Returns True so that `assert wait_until(...)` reads as the check it is.
    """
    bound = stretched(timeout)
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(POLL_S)
    if predicate():  # one last look: the deadline may have passed during a slow poll
        return True
    raise AssertionError(f"timed out after {bound:.0f} s waiting for {what}")
