"""Counting the links this process's secure router refused, and saying so in its log.

Zenoh logs each TLS link it refuses (fleet/transport/router.py turns that log on); the
watch taps the output Zenoh logs to (`FdTap`), counts the refusals by kind (`classify`,
`RefusedLinks`) and logs the totals, `refused links so far: no_certificate=2
unknown_ca=1`, at most once every `REPORT_EVERY_S` however fast refusals come, and once
more when it stops. Zenoh's lines themselves are not passed on as written but logged
through Python's logging, each refusal at DEBUG (`fleet.transport.zenoh_log`). One
watch per process (its output is one per process): `acquire` starts it with the first
secure router, `release` stops it with the last. The totals go to the process's log
(stderr), not through the tap.
"""

from __future__ import annotations

import logging
import threading

from fleet.transport.fd_tap import STDOUT, FdTap
from fleet.transport.link_refusal import LinkRefusal, RefusedLinks, classify
from fleet.transport.zenoh_log import ZenohLog

log = logging.getLogger(__name__)

#: The shortest time between two lines of totals, seconds.
REPORT_EVERY_S = 1.0


class RefusalWatch:
    def __init__(self, report_every_s: float = REPORT_EVERY_S, fd: int = STDOUT) -> None:
        self.links = RefusedLinks()
        self.report_every_s = report_every_s
        self._changed = threading.Event()
        self._stop = threading.Event()
        # Zenoh's lines go to the log, cut to what an operator can act on (`ZenohLog`).
        self._tap = FdTap(self._on_line, fd, keep=ZenohLog().keep)
        self._reporter: threading.Thread | None = None

    def start(self) -> None:
        """Start counting; with no output to tap (a closed descriptor), say so and go on
        uncounted rather than keep the router from starting."""
        try:
            self._tap.start()
        except OSError as error:
            log.warning("refused links will not be counted: cannot read Zenoh's log: %s", error)
            return
        self._reporter = threading.Thread(target=self._report, name="refusal-report", daemon=True)
        self._reporter.start()

    def stop(self) -> None:
        self._stop.set()
        self._changed.set()
        if self._reporter is not None:
            self._reporter.join(5.0)
        self._tap.stop()

    def count(self, kind: LinkRefusal) -> None:
        """Count a refusal this process made itself (not read from Zenoh's log), reported
        with the others."""
        self.links.count(kind)
        self._changed.set()

    def _on_line(self, line: str) -> None:
        # On the tap's thread: count only; the reporter writes.
        kind = classify(line)
        if kind is not None:
            self.links.count(kind)
            self._changed.set()

    def _report(self) -> None:
        reported = ""
        while not self._stop.is_set():
            self._changed.wait()
            self._changed.clear()
            summary = self.links.summary()
            if summary != reported and self.links.counts():
                log.warning("refused links so far: %s", summary)
                reported = summary
            self._stop.wait(self.report_every_s)  # the rate limit
        if self.links.counts():
            log.info("refused links in all: %s", self.links.summary())


_lock = threading.Lock()
_watch: RefusalWatch | None = None
_users = 0


def acquire() -> RefusalWatch:
    """This process's watch, started if it was not."""
    global _watch, _users
    with _lock:
        if _watch is None:
            _watch = RefusalWatch()
            _watch.start()
        _users += 1
        return _watch


def release() -> None:
    """One user fewer; the last one stops the watch and puts the output back."""
    global _watch, _users
    with _lock:
        _users -= 1
        if _users > 0 or _watch is None:
            return
        watch, _watch, _users = _watch, None, 0
    watch.stop()
