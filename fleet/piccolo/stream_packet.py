"""Piccolo stream (transport) packets: encoder and incremental decoder (docs/protocol.md §1).

A stream packet is 0x5A 0xA5, a 12-byte big-endian header closed by the XOR of bytes
0-12, up to 255 data bytes, and a CRC-16/ARC (high byte first) over everything before
it. The decoder is fed arbitrary chunks and resynchronises on the next 0x5A 0xA5 after
anything it rejects; it never raises on input bytes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from fleet.errors import CodecError
from fleet.piccolo.crc import crc16_arc_bytes, crc16_arc_follows
from fleet.piccolo.decoder import Reject, ResyncDecoder

SYNC = b"\x5a\xa5"
HEADER_SIZE = 14
OVERHEAD = HEADER_SIZE + 2
MAX_DATA = 255
MAX_PACKET = OVERHEAD + MAX_DATA

#: Addresses (docs/protocol.md §1).
BROADCAST_AVIONICS = 0xFFFF
ALL_OPERATOR_INTERFACES = 0xFFFE
ALL_GROUND_STATIONS = 0x0000
#: The addresses an aircraft's avionics (its Piccolo ID) may take.
MIN_PICCOLO_ID = 0x0001
MAX_PICCOLO_ID = 0xFFF0

#: Stream ids (docs/protocol.md §1).
STREAM_AUTOPILOT = 3
STREAM_PAYLOAD = 6

_HEADER = struct.Struct(">2sHHHHBBB")
_BAD_HEADER_CHECKSUM = Reject("bad_header_checksum")
_BAD_CRC = Reject("bad_crc")


class StreamPacketError(CodecError):
    """A stream packet that cannot be encoded (a field out of range)."""


@dataclass(frozen=True, slots=True)
class StreamPacket:
    """One stream packet as it travels on the link."""

    destination: int
    source: int
    sequence: int
    acknowledge: int
    stream: int
    data: bytes
    flags: int = 0


def _xor(data: bytes | bytearray) -> int:
    checksum = 0
    for byte in data:
        checksum ^= byte
    return checksum


def _refuse_fields(packet: StreamPacket) -> None:
    for name in ("destination", "source", "sequence", "acknowledge"):
        value = getattr(packet, name)
        if not 0 <= value <= 0xFFFF:
            raise StreamPacketError(f"{name} {value} does not fit in 16 bits")
    for name in ("stream", "flags"):
        value = getattr(packet, name)
        if not 0 <= value <= 0xFF:
            raise StreamPacketError(f"{name} {value} does not fit in 8 bits")


def encode_stream_packet(packet: StreamPacket) -> bytes:
    """Encode one stream packet; its data must fit in 255 bytes."""
    if len(packet.data) > MAX_DATA:
        raise StreamPacketError(
            f"stream packet data is {len(packet.data)} bytes; at most {MAX_DATA} fit"
        )
    if not (
        0 <= packet.destination <= 0xFFFF
        and 0 <= packet.source <= 0xFFFF
        and 0 <= packet.sequence <= 0xFFFF
        and 0 <= packet.acknowledge <= 0xFFFF
        and 0 <= packet.stream <= 0xFF
        and 0 <= packet.flags <= 0xFF
    ):
        _refuse_fields(packet)  # which field, said by name (the simulator's hot path)
    head = _HEADER.pack(
        SYNC,
        packet.destination,
        packet.source,
        packet.sequence,
        packet.acknowledge,
        packet.stream,
        packet.flags,
        len(packet.data),
    )
    body = head + bytes((_xor(head),)) + packet.data
    return body + crc16_arc_bytes(body)


class StreamDecoder(ResyncDecoder[StreamPacket]):
    """Incremental stream-packet decoder.

    Keeps at most one partial packet (271 bytes) between calls: garbage before a sync
    is discarded at once and counted in `skipped_bytes`. A candidate rejected for its
    header checksum (`bad_header_checksum`) or CRC (`bad_crc`) costs one byte (its
    0x5A), then the hunt resumes, so a real packet hidden inside a corrupt one is still
    found.
    """

    SYNC = SYNC
    REASONS = ("bad_header_checksum", "bad_crc")

    def _frame(self, buffer: bytearray, start: int) -> tuple[StreamPacket, int] | Reject | None:
        end = len(buffer)
        if end - start < HEADER_SIZE:
            return None
        if _xor(buffer[start : start + 13]) != buffer[start + 13]:
            return _BAD_HEADER_CHECKSUM
        stop = start + HEADER_SIZE + buffer[start + 12]
        if end < stop + 2:
            return None
        if not crc16_arc_follows(buffer, start, stop):
            return _BAD_CRC
        _, destination, source, sequence, acknowledge, stream, flags, _ = _HEADER.unpack_from(
            buffer, start
        )
        packet = StreamPacket(
            destination=destination,
            source=source,
            sequence=sequence,
            acknowledge=acknowledge,
            stream=stream,
            flags=flags,
            data=bytes(buffer[start + HEADER_SIZE : stop]),
        )
        return packet, stop + 2
