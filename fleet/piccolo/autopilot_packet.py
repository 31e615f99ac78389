"""Autopilot-stream "simple packets" (docs/protocol.md §3): framing only.

0xA0 0x05, packet type, data size N, N data bytes, CRC-16/ARC (high byte first) over
everything before it. Decoded out of the autopilot stream's bytes, whether a packet
spans several stream packets or shares one with others.
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.errors import CodecError
from fleet.piccolo.crc import crc16_arc_bytes, crc16_arc_follows
from fleet.piccolo.decoder import Reject, ResyncDecoder

SYNC = b"\xa0\x05"
HEADER_SIZE = 4
OVERHEAD = HEADER_SIZE + 2
MAX_DATA = 255
_BAD_CRC = Reject("bad_crc")


class AutopilotPacketError(CodecError):
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


class AutopilotPacketDecoder(ResyncDecoder[AutopilotPacket]):
    """Pulls complete autopilot packets out of the autopilot stream's bytes.

    A candidate whose CRC fails (`bad_crc`) costs one byte, then the hunt resumes.
    """

    SYNC = SYNC
    REASONS = ("bad_crc",)

    def _frame(self, buffer: bytearray, start: int) -> tuple[AutopilotPacket, int] | Reject | None:
        end = len(buffer)
        if end - start < HEADER_SIZE:
            return None
        stop = start + HEADER_SIZE + buffer[start + 3]
        if end < stop + 2:
            return None
        if not crc16_arc_follows(buffer, start, stop):
            return _BAD_CRC
        packet = AutopilotPacket(buffer[start + 2], bytes(buffer[start + HEADER_SIZE : stop]))
        return packet, stop + 2
