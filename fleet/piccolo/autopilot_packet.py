"""Autopilot-stream "simple packets" (piccolo-link.md 3): framing only.

0xA0 0x05, packet type, data size N, N data bytes, CRC-16/ARC (high byte first) over
everything before it. Parsed out of the autopilot stream queue, whether a packet spans
several stream packets or shares one with others.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fleet.piccolo.crc import crc16_arc, crc16_arc_bytes
from fleet.piccolo.stream_queue import StreamQueue

SYNC = b"\xa0\x05"
HEADER_SIZE = 4
OVERHEAD = HEADER_SIZE + 2
MAX_DATA = 255


class AutopilotPacketError(ValueError):
    """An autopilot packet that cannot be encoded."""


@dataclass(frozen=True, slots=True)
class AutopilotPacket:
    """A framed autopilot packet: its type and its raw data bytes."""

    packet_type: int
    data: bytes


def encode_autopilot_packet(packet_type: int, data: bytes) -> bytes:
    if not 0 <= packet_type <= 0xFF:
        raise AutopilotPacketError(f"packet type {packet_type} does not fit in 8 bits")
    if len(data) > MAX_DATA:
        raise AutopilotPacketError(
            f"autopilot packet type {packet_type} has {len(data)} data bytes; at most {MAX_DATA}"
        )
    body = SYNC + bytes((packet_type, len(data))) + data
    return body + crc16_arc_bytes(body)


@dataclass(slots=True)
class AutopilotDropCounters:
    bad_crc: int = 0
    skipped_bytes: int = 0

    def as_dict(self) -> dict[str, int]:
        return {"bad_crc": self.bad_crc, "skipped_bytes": self.skipped_bytes}


@dataclass
class AutopilotPacketParser:
    """Pulls complete autopilot packets out of the autopilot stream queue."""

    drops: AutopilotDropCounters = field(default_factory=AutopilotDropCounters)

    def parse(self, queue: StreamQueue) -> list[AutopilotPacket]:
        buffer = queue.view()
        found: list[AutopilotPacket] = []
        position = 0
        end = len(buffer)
        while True:
            start = buffer.find(SYNC, position)
            if start < 0:
                keep_from = end - 1 if end > position and buffer[end - 1] == 0xA0 else end
                self.drops.skipped_bytes += keep_from - position
                position = keep_from
                break
            self.drops.skipped_bytes += start - position
            position = start
            if end - start < HEADER_SIZE:
                break
            stop = start + HEADER_SIZE + buffer[start + 3]
            if end < stop + 2:
                break
            if crc16_arc(buffer[start:stop]) != (buffer[stop] << 8 | buffer[stop + 1]):
                self.drops.bad_crc += 1
                self.drops.skipped_bytes += 1
                position = start + 1
                continue
            found.append(
                AutopilotPacket(buffer[start + 2], bytes(buffer[start + HEADER_SIZE : stop]))
            )
            position = stop + 2
        queue.consume(position)
        return found
