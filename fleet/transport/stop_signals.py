"""SIGTERM and SIGINT as a request to stop, for every long-running command."""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

log = logging.getLogger(__name__)


@contextmanager
def stop_on_signals(stop: threading.Event, what: str = "stopping") -> Iterator[None]:
    """While inside, SIGTERM and SIGINT set `stop`; the previous handlers come back after."""
    # Handlers can only be installed from the main thread; elsewhere (a test driving
    # a command from a thread) the caller sets `stop` itself.
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handle(signum: int, frame: FrameType | None) -> None:
        log.info("%s: %s", signal.Signals(signum).name, what)
        stop.set()

    previous = {sig: signal.signal(sig, handle) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
