"""Reading what this process writes to one of its file descriptors, whoever writes it.

Zenoh's Rust runtime writes its log (tracing's default writer: standard output, file
descriptor 1) out of Python's reach. `FdTap` puts a pipe in the descriptor's place: a
daemon thread reads the pipe, passes every byte on to the real file unchanged (first, so
nothing is held back or lost; but see `keep` below) and hands each complete line to
`on_line`. `on_line` runs
on that thread: it must not block, nor write to the tapped descriptor (the pipe it would
write to is the one the thread drains). Child processes started meanwhile inherit the
pipe: their lines pass through too.

With a `keep` gate, a line may be withheld: a line that starts as one of Zenoh's log
lines does (an escape code or a digit: its coloured time stamp) is held until it ends,
then passed on only if `keep` says so (a program's own line that starts with a digit
only waits for its end); any other line still passes on byte by byte as it comes.
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

    def __init__(
        self,
        on_line: Callable[[str], None],
        fd: int = STDOUT,
        keep: Callable[[str], bool] | None = None,
    ) -> None:
        self.on_line = on_line
        self.fd = fd
        self.keep = keep
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
        lines = _Lines(self.keep)
        try:
            while chunk := os.read(read_end, _CHUNK):
                _write_all(original, lines.feed(chunk))
                for line in lines.ended():
                    self._hand_over(line)
            _write_all(original, lines.finish())
            for line in lines.ended():
                self._hand_over(line)
        except OSError:
            pass  # the real file is gone: nothing left to pass on or to read
        finally:
            os.close(read_end)

    def _hand_over(self, line: bytes) -> None:
        # A failing reader must not stop the output flowing; not logged either (the log
        # may be the very output this thread drains).
        with contextlib.suppress(Exception):
            self.on_line(line.decode("utf-8", errors="replace"))


#: How a line that may be one of Zenoh's log lines starts: its time stamp, coloured or not.
_HELD_STARTS = frozenset(b"\x1b0123456789")


class _Lines:
    """The output cut into lines: what to pass on of each chunk, and the lines ended."""

    def __init__(self, keep: Callable[[str], bool] | None) -> None:
        self.keep = keep
        self._line = bytearray()  #: the line so far
        self._held = False  #: whether it is held until it ends (else passed on as it comes)
        self._ended: list[bytes] = []

    def feed(self, chunk: bytes) -> bytes:
        """What of `chunk` to pass on now."""
        out = bytearray()
        start = 0
        while start < len(chunk):
            end = chunk.find(b"\n", start)
            piece = chunk[start : len(chunk) if end < 0 else end + 1]
            start += len(piece)
            if not self._line:
                self._held = self.keep is not None and piece[0] in _HELD_STARTS
            self._line += piece
            if not self._held:
                out += piece
            if piece.endswith(b"\n"):
                out += self._end(bytes(self._line[:-1]), b"\n")
            elif len(self._line) > MAX_LINE:
                out += self._end(bytes(self._line), b"")  # cut: handed over in parts
        return bytes(out)

    def finish(self) -> bytes:
        """What is left to pass on at the end of the output: a last line with no newline."""
        return self._end(bytes(self._line), b"") if self._line else b""

    def ended(self) -> list[bytes]:
        """The lines ended since last asked."""
        ended, self._ended = self._ended, []
        return ended

    def _end(self, line: bytes, newline: bytes) -> bytes:
        """End the current line; what of it is still to pass on (a held line, kept)."""
        held, self._held = self._held, False
        self._line = bytearray()
        self._ended.append(line)
        if not held:
            return b""
        kept = True
        if self.keep is not None:
            with contextlib.suppress(Exception):  # a failing gate lets the line through
                kept = self.keep(line.decode("utf-8", errors="replace"))
        return line + newline if kept else b""


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
