"""Per-stream byte queues, bounded like the thesis's 4096-byte buffers (thesis 2.7.4).

Each Piccolo stream is a byte stream: stream packets append their data to the stream's
queue and higher-level packets are parsed out of it. A queue never grows past its
capacity: on overflow the oldest bytes go, and the loss is counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

QUEUE_CAPACITY = 4096


@dataclass
class StreamQueue:
    """A bounded FIFO of bytes that drops its oldest bytes on overflow."""

    capacity: int = QUEUE_CAPACITY
    overflow_bytes: int = 0
    _data: bytearray = field(default_factory=bytearray)

    def append(self, data: bytes | bytearray | memoryview) -> None:
        self._data += data
        excess = len(self._data) - self.capacity
        if excess > 0:
            del self._data[:excess]
            self.overflow_bytes += excess

    def view(self) -> bytearray:
        """The queued bytes, for a parser to read in place before `consume`."""
        return self._data

    def consume(self, count: int) -> None:
        del self._data[:count]

    def take(self) -> bytes:
        """Remove and return everything queued."""
        data = bytes(self._data)
        self._data.clear()
        return data

    def __len__(self) -> int:
        return len(self._data)
