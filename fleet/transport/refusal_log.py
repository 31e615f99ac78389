"""Logging what a process refused without letting a flood fill its log.

A hostile or broken peer can send refusable input (messages, connections, requests) as
fast as it likes; one log line each would fill the disk and drown everything else.
`RefusalLog` writes up to `burst` refusals at once in each period of `every_s` seconds,
then only counts them, and the first line of the next period says how many it left out.
The counts themselves are kept by each process's counters (`bus_codec.DROPPED`, the
page's `refused`), not here.
"""

from __future__ import annotations

import logging
import threading
import time

#: The period of the rate limit, seconds, and how many lines each period may have.
LOG_EVERY_S = 10.0
LOG_BURST = 10


class RefusalLog:
    """A rate-limited warning log of refusals (thread-safe: bus callbacks call it)."""

    def __init__(
        self, logger: logging.Logger, every_s: float = LOG_EVERY_S, burst: int = LOG_BURST
    ) -> None:
        self.logger = logger
        self.every_s = every_s
        self.burst = burst
        self._lock = threading.Lock()
        self._period_start = float("-inf")
        self._logged = 0  #: lines in this period
        self._left_out = 0  #: refusals not logged since the last line

    def warn(self, text: str) -> bool:
        """Log `text` unless this period's lines are used up; True if it was logged."""
        now = time.monotonic()
        with self._lock:
            if now - self._period_start >= self.every_s:
                self._period_start, self._logged = now, 0
            if self._logged >= self.burst:
                self._left_out += 1
                return False
            self._logged += 1
            left_out, self._left_out = self._left_out, 0
        more = f" ({left_out} more refused and not logged before this)" if left_out else ""
        self.logger.warning("%s%s", text, more)
        return True
