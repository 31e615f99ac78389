"""Planning-protocol segments: one PAYLOAD_UAV message cut into packets and put back.

Every PAYLOAD_UAV body starts with a 4-byte segment header (seq u16, index u8,
count u8), so application messages up to 255 x 251 bytes travel as several packets.
Every segment but the last is full, and a multi-segment message has no empty last
segment. `SegmentReassembler` puts the segments back together within fixed bounds.
"""

from __future__ import annotations

import struct
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Final

from fleet.payload.framing import (
    MAX_PAYLOAD_SIZE,
    PAYLOAD_UAV,
    Malformed,
    PlanningPacket,
    PlanningProtocolError,
    check_uint,
    encode_packet,
)

__all__ = [
    "MAX_FRAGMENT_SIZE",
    "MAX_MESSAGE_SIZE",
    "MAX_SEGMENTS",
    "SEGMENT_HEADER_SIZE",
    "ReassembledMessage",
    "SegmentReassembler",
    "segment",
    "split_segment",
]

#: Segment header carried at the start of every PAYLOAD_UAV body.
SEGMENT_HEADER_SIZE: Final = 4
MAX_FRAGMENT_SIZE: Final = MAX_PAYLOAD_SIZE - SEGMENT_HEADER_SIZE
MAX_SEGMENTS: Final = 255
#: Largest PAYLOAD_UAV application message: 255 segments of 251 bytes.
MAX_MESSAGE_SIZE: Final = MAX_SEGMENTS * MAX_FRAGMENT_SIZE

_SEGMENT = struct.Struct("<HBB")
assert _SEGMENT.size == SEGMENT_HEADER_SIZE


@dataclass(frozen=True, slots=True)
class ReassembledMessage:
    """A whole PAYLOAD_UAV application message, put back together from its segments."""

    source: int
    destination: int
    user: int
    seq: int
    data: bytes


def segment(user: int, data: bytes, source: int, destination: int, seq: int) -> list[bytes]:
    check_uint("seq", seq, 16)
    if len(data) > MAX_MESSAGE_SIZE:
        raise PlanningProtocolError(
            f"application message is {len(data)} bytes; PAYLOAD_UAV carries at most "
            f"{MAX_SEGMENTS} segments of {MAX_FRAGMENT_SIZE} bytes = {MAX_MESSAGE_SIZE} bytes"
        )
    count = max(1, -(-len(data) // MAX_FRAGMENT_SIZE))
    return [
        encode_packet(
            PAYLOAD_UAV,
            user,
            destination,
            source,
            _SEGMENT.pack(seq, index, count)
            + data[index * MAX_FRAGMENT_SIZE : (index + 1) * MAX_FRAGMENT_SIZE],
        )
        for index in range(count)
    ]


def split_segment(body: bytes) -> tuple[int, int, int, bytes]:
    """(seq, index, count, fragment) of a PAYLOAD_UAV body, checked against the rule."""
    if len(body) < SEGMENT_HEADER_SIZE:
        raise Malformed("segment header truncated")
    seq, index, count = _SEGMENT.unpack_from(body, 0)
    fragment = body[SEGMENT_HEADER_SIZE:]
    if count == 0 or index >= count:
        raise Malformed("segment index/count")
    # Every segment but the last is full, and a multi-segment message has no empty
    # last segment: so offsets follow from the index, and a false sync rarely passes.
    if index < count - 1:
        if len(fragment) != MAX_FRAGMENT_SIZE:
            raise Malformed("non-final segment not full")
    elif count > 1 and not fragment:
        raise Malformed("empty final segment")
    return seq, index, count, fragment


@dataclass
class _Pending:
    destination: int
    count: int
    first_seen: float
    fragments: dict[int, bytes] = field(default_factory=dict)
    size: int = 0


class SegmentReassembler:
    """Puts segmented PAYLOAD_UAV messages back together, within fixed bounds.

    Pending messages are keyed by (source, user, seq). A message is delivered once every
    index 0..count-1 has arrived, in any order; nothing incomplete is ever delivered.
    Bounds: at most `max_pending` messages and `max_bytes` fragment bytes are held (the
    oldest pending message is evicted first), and a message not complete within
    `max_age_s` of its first segment is dropped. `now` is the caller's clock in seconds.

    Drop counters: `bad_segment` (segment header breaks the rule), `duplicate_segment`
    (an index already held, same bytes: dropped, the message continues),
    `inconsistent_message` (a segment contradicts the pending message: different count,
    destination, or different bytes for a held index; the old partial message is dropped
    and the new segment starts afresh, as a sender reusing a seq after a loss would),
    `expired_message`, `evicted_message`.
    """

    def __init__(
        self, max_pending: int = 32, max_bytes: int = 4 * MAX_MESSAGE_SIZE, max_age_s: float = 30.0
    ) -> None:
        self.max_pending = max_pending
        self.max_bytes = max_bytes
        self.max_age_s = max_age_s
        self._pending: OrderedDict[tuple[int, int, int], _Pending] = OrderedDict()
        self._bytes = 0
        self._drops = {
            "bad_segment": 0,
            "duplicate_segment": 0,
            "inconsistent_message": 0,
            "expired_message": 0,
            "evicted_message": 0,
        }

    @property
    def drops(self) -> dict[str, int]:
        return dict(self._drops)

    @property
    def pending(self) -> int:
        """How many incomplete messages are held."""
        return len(self._pending)

    @property
    def pending_bytes(self) -> int:
        return self._bytes

    def _discard(self, key: tuple[int, int, int], reason: str) -> None:
        entry = self._pending.pop(key)
        self._bytes -= entry.size
        self._drops[reason] += 1

    def expire(self, now: float) -> None:
        """Drop pending messages whose first segment is older than `max_age_s`."""
        stale = [
            key for key, entry in self._pending.items() if now - entry.first_seen > self.max_age_s
        ]
        for key in stale:
            self._discard(key, "expired_message")

    def push(self, packet: PlanningPacket, now: float) -> ReassembledMessage | None:
        """Add one PAYLOAD_UAV packet; return the message it completes, if any."""
        self.expire(now)
        if packet.type != PAYLOAD_UAV:
            self._drops["bad_segment"] += 1
            return None
        try:
            seq, index, count, fragment = split_segment(packet.body)
        except Malformed:
            self._drops["bad_segment"] += 1
            return None
        if count == 1:
            # Whole in one packet: nothing to hold, and no pending entry to disturb.
            return ReassembledMessage(packet.source, packet.destination, packet.user, seq, fragment)
        key = (packet.source, packet.user, seq)
        entry = self._pending.get(key)
        if entry is not None:
            held = entry.fragments.get(index)
            if (
                entry.count != count
                or entry.destination != packet.destination
                or (held is not None and held != fragment)
            ):
                self._discard(key, "inconsistent_message")
                entry = None
            elif held is not None:
                self._drops["duplicate_segment"] += 1
                return None
        if entry is None:
            entry = _Pending(destination=packet.destination, count=count, first_seen=now)
            self._pending[key] = entry
        entry.fragments[index] = fragment
        entry.size += len(fragment)
        self._bytes += len(fragment)
        if len(entry.fragments) == count:
            self._pending.pop(key)
            self._bytes -= entry.size
            data = b"".join(entry.fragments[i] for i in range(count))
            return ReassembledMessage(packet.source, packet.destination, packet.user, seq, data)
        while self._pending and (
            len(self._pending) > self.max_pending or self._bytes > self.max_bytes
        ):
            self._discard(next(iter(self._pending)), "evicted_message")
        return None
