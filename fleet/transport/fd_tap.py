"""Reading what this process writes to one of its file descriptors, whoever writes it.

Zenoh's Rust runtime writes its log (tracing's default writer: standard output, file
descriptor 1) out of Python's reach. `FdTap` puts a pipe in the descriptor's place: a
daemon thread reads the pipe, passes every byte on to the real file unchanged (first, so
nothing is held back or lost) and hands each complete line to `on_line`. `on_line` runs
on that thread: it must not block, nor write to the tapped descriptor (the pipe it would
write to is the one the thread drains). Child processes started meanwhile inherit the
pipe: their lines pass through too.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable

#: Zenoh's log goes to standard output.
STDOUT = 1
#: The longest line handed over whole; a longer one is cut (its bytes all pass on).
MAX_LINE = 16_384
_CHUNK = 65_536


class FdTap:
    """Use as start() / stop(); stop() puts the real file back and drains the pipe."""

    def __init__(self, on_line: Callable[[str], None], fd: int = STDOUT) -> None:
        self.on_line = on_line
        self.fd = fd
        self._original: int | None = None
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self._thread is not None:
            return
        original = os.dup(self.fd)
        read_end, write_end = os.pipe()
        os.dup2(write_end, self.fd)
        os.close(write_end)  # `fd` is now the only writer: putting it back ends the pipe
        self._original = original
        self._thread = threading.Thread(
            target=self._pump, args=(read_end, original), name=f"fd-{self.fd}-tap", daemon=True
        )
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        thread, original = self._thread, self._original
        if thread is None or original is None:
            return
        os.dup2(original, self.fd)  # the pipe's last writer goes (children's aside): EOF
        thread.join(timeout_s)  # bounded: a child still holding the pipe keeps it open
        self._thread = None
        if not thread.is_alive():
            os.close(original)
            self._original = None

    def _pump(self, read_end: int, original: int) -> None:
        pending = b""
        try:
            while chunk := os.read(read_end, _CHUNK):
                _write_all(original, chunk)
                pending += chunk
                *lines, pending = pending.split(b"\n")
                if len(pending) > MAX_LINE:
                    lines.append(pending)
                    pending = b""
                for line in lines:
                    self._hand_over(line)
            if pending:
                self._hand_over(pending)
        except OSError:
            pass  # the real file is gone: nothing left to pass on or to read
        finally:
            os.close(read_end)

    def _hand_over(self, line: bytes) -> None:
        # A failing reader must not stop the output flowing; not logged either (the log
        # may be the very output this thread drains).
        with contextlib.suppress(Exception):
            self.on_line(line.decode("utf-8", errors="replace"))


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
