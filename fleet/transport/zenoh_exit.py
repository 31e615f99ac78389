"""Close every Zenoh session still open before the interpreter finalizes.

Why: a Python process that exits with a Zenoh session open can crash on its way out.
Zenoh's threads go on delivering samples to the session's Python callbacks while
CPython 3.11 finalizes. A thread that wants the interpreter back then (a callback on a
Zenoh thread, or a Python thread returning from a Zenoh call that let the interpreter
go: `put`, `recv`) is ended by CPython with `pthread_exit`, whose unwinding the
binding's Rust code catches: glibc aborts ("FATAL: exception not rethrown", SIGABRT).
Once the interpreter is gone, a callback's `PyGILState_Ensure` dereferences it: SIGSEGV
(in `new_threadstate`), with no traceback, faulthandler being off by then.
`bench/zenoh_exit_crash.py` reproduces both with Zenoh alone; docs/benchmarks.md has
the figures.

So each session's owner (`ZenohBus`, `Router`) registers its close here, and one
`atexit` handler closes what is still open: `atexit` runs before the interpreter starts
finalizing, and a closed session calls back no more. Owners are held weakly: a bus
that was dropped (and with it its session) is not kept alive for the exit.
Processes that end with `os._exit` (the fork server's children) skip finalization and
this with it.
"""

from __future__ import annotations

import atexit
import logging
import threading
import weakref
from collections.abc import Callable

log = logging.getLogger(__name__)


class ExitClosers:
    """Closes, once, what is registered and still alive (bound methods, held weakly)."""

    def __init__(self) -> None:
        self._closers: list[weakref.WeakMethod[Callable[[], None]]] = []
        self._lock = threading.Lock()

    def add(self, close: Callable[[], None]) -> None:
        with self._lock:
            self._closers[:] = [ref for ref in self._closers if ref() is not None]
            self._closers.append(weakref.WeakMethod(close))

    def __len__(self) -> int:
        with self._lock:
            return sum(ref() is not None for ref in self._closers)

    def close_all(self) -> None:
        with self._lock:
            closers = [close for ref in self._closers if (close := ref()) is not None]
            self._closers.clear()
        for close in reversed(closers):  # the last opened first: clients before their router
            try:
                close()
            except Exception:  # one that fails leaves the others to close
                log.debug("closing a Zenoh session at exit failed", exc_info=True)


#: The process's, closed by `atexit`.
AT_EXIT = ExitClosers()
atexit.register(AT_EXIT.close_all)


def close_at_exit(close: Callable[[], None]) -> None:
    """Call `close` (a bound method: its object is held weakly) at exit if its object
    is still alive then. `close` must be idempotent: the owner may have closed already."""
    AT_EXIT.add(close)
