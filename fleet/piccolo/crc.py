"""CRC-16/ARC, the checksum of Piccolo stream and autopilot packets (docs/protocol.md §1).

Polynomial 0x8005 reflected, initial value 0, no final XOR; check value 0xBB3D for
b"123456789". Python's `binascii.crc_hqx` is CRC-16/CCITT, a different CRC, so the
compiled `fastcrc` implementation is used instead: the decoder checks every byte twice
(stream packet and autopilot packet), and a pure-Python table loop would dominate it.
"""

from __future__ import annotations

from fastcrc import crc16


def crc16_arc(data: bytes | bytearray | memoryview) -> int:
    """Return the CRC-16/ARC of `data`."""
    return int(crc16.arc(bytes(data)))


def crc16_arc_bytes(data: bytes | bytearray | memoryview) -> bytes:
    """Return the CRC-16/ARC of `data` as the link sends it: high byte first."""
    return crc16_arc(data).to_bytes(2, "big")


def crc16_arc_follows(buffer: bytes | bytearray, start: int, stop: int) -> bool:
    """True if `buffer[stop:stop + 2]` is the CRC-16/ARC of `buffer[start:stop]`, high
    byte first: the trailer of a stream or autopilot packet spanning `start` to `stop`."""
    return crc16_arc(buffer[start:stop]) == (buffer[stop] << 8 | buffer[stop + 1])
