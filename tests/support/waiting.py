"""Waiting for something observable, instead of sleeping for a guessed time."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Literal

#: How often a condition is polled, seconds.
POLL_S = 0.05


def wait_until(
    predicate: Callable[..., object], timeout: float = 5.0, what: str = "the condition"
) -> Literal[True]:
    """Poll `predicate` until it is true; AssertionError naming `what` after `timeout` s.

    Returns True so that `assert wait_until(...)` reads as the check it is.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(POLL_S)
    if predicate():  # one last look: the deadline may have passed during a slow poll
        return True
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")
