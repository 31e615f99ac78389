"""One shape for every stream decoder, and the sync hunt they share.

The link stacks three decoders: stream packets out of the serial bytes, autopilot
packets out of stream 3, planning-protocol packets out of stream 6. Each is a
`Decoder` (the shape of aiortc's ``codecs/base.py``): fed chunks of any size, it returns
the items they complete, never raises on input bytes, and counts what it drops by
reason.

The three framings differ only in their sync bytes and in how a candidate frame is
checked, so `ResyncDecoder` holds the common part once: find the next sync, hand the
candidate to the framing's `_frame`, on a rejection skip one byte (the sync's first)
and hunt again, so a real frame hidden inside a false one is still found. Every byte
discarded outside a delivered frame is counted in `skipped_bytes`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar, Generic, TypeAlias, TypeVar

__all__ = ["SKIPPED_BYTES", "Chunk", "Decoder", "Reject", "ResyncDecoder"]

Chunk: TypeAlias = bytes | bytearray | memoryview
ItemT = TypeVar("ItemT")
ItemT_co = TypeVar("ItemT_co", covariant=True)

#: The drop counter of the bytes discarded outside any delivered frame.
SKIPPED_BYTES = "skipped_bytes"


class Decoder(ABC, Generic[ItemT_co]):
    """Bytes in, whole items out; never raises on input bytes; counts its drops."""

    @abstractmethod
    def feed(self, data: Chunk, now: float = 0.0) -> list[ItemT_co]:
        """The items `data` completes, in order.

        `now` is the caller's monotonic clock in seconds; it ages time-bounded state
        (partial planning messages). Decoders without such state ignore it.
        """

    @property
    @abstractmethod
    def drops(self) -> dict[str, int]:
        """What was dropped so far, by reason (a copy)."""


@dataclass(frozen=True, slots=True)
class Reject:
    """A candidate frame that is not one; `reason` names the drop counter."""

    reason: str


def _partial_sync_start(buffer: bytearray, position: int, sync: bytes) -> int:
    """Where a trailing proper prefix of `sync` begins (len(buffer) if there is none).

    Such a tail may be the first half of a sync whose rest is still on the wire.
    """
    end = len(buffer)
    for size in range(min(len(sync) - 1, end - position), 0, -1):
        if buffer.endswith(sync[:size]):
            return end - size
    return end


class ResyncDecoder(Decoder[ItemT]):
    """A `Decoder` for a framing that starts every frame with `SYNC`.

    Subclasses set `SYNC` and `REASONS` (their drop counters besides `skipped_bytes`)
    and implement `_frame`. Between calls the decoder holds at most one partial frame.
    """

    SYNC: ClassVar[bytes]
    REASONS: ClassVar[tuple[str, ...]]

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._drops = dict.fromkeys((*self.REASONS, SKIPPED_BYTES), 0)
        #: Packets delivered so far.
        self.packets = 0

    @property
    def drops(self) -> dict[str, int]:
        return dict(self._drops)

    @property
    def buffered(self) -> int:
        """Bytes held for a frame not yet complete."""
        return len(self._buffer)

    @abstractmethod
    def _frame(self, buffer: bytearray, start: int) -> tuple[ItemT, int] | Reject | None:
        """Check the candidate frame whose sync is at `buffer[start]`.

        None if more bytes are needed, a `Reject`, or the item and the offset just past
        its last byte.
        """

    def feed(self, data: Chunk, now: float = 0.0) -> list[ItemT]:
        buffer = self._buffer
        buffer += data
        if buffer.startswith(self.SYNC):
            # What a live link reads nearly every time, one whole frame, is taken without
            # the hunt: exactly what the hunt would deliver (no byte skipped, none left).
            framed = self._frame(buffer, 0)
            if type(framed) is tuple and framed[1] == len(buffer):
                buffer.clear()
                self.packets += 1
                return [framed[0]]
        drops = self._drops
        found: list[ItemT] = []
        position = 0
        while True:
            start = buffer.find(self.SYNC, position)
            if start < 0:
                keep_from = _partial_sync_start(buffer, position, self.SYNC)
                drops[SKIPPED_BYTES] += keep_from - position
                position = keep_from
                break
            drops[SKIPPED_BYTES] += start - position
            position = start
            framed = self._frame(buffer, start)
            if framed is None:
                break
            if isinstance(framed, Reject):
                drops[framed.reason] += 1
                drops[SKIPPED_BYTES] += 1
                position = start + 1
                continue
            item, position = framed
            found.append(item)
        del buffer[:position]
        self.packets += len(found)
        return found
