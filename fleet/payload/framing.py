"""Planning-protocol packets: the 8-byte header and its framing (docs/protocol.md 6).

Every packet is an 8-byte little-endian header

    sync u8 | size u8 | type u8 | user u8 | destination u16 | source u16

followed by `size` payload bytes. This module holds the header's constants, the packet
as it travels (`PlanningPacket`), the encoder of one packet and the protocol's errors.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Final

from fleet.errors import CodecError

__all__ = [
    "HEADER",
    "HEADER_SIZE",
    "MAX_PACKET_SIZE",
    "MAX_PAYLOAD_SIZE",
    "PACKET_TYPES",
    "PAYLOAD_OPM",
    "PAYLOAD_STATUS",
    "PAYLOAD_UAV",
    "SYNC",
    "Malformed",
    "PlanningPacket",
    "PlanningProtocolError",
    "check_finite",
    "check_uint",
    "encode_packet",
]

#: First byte of every packet. 0xB5 is not ASCII (so it never occurs in an English
#: status text), is neither byte of the common addresses 0xFFFF/0xFFFE/0x0000, and is
#: a UTF-8 continuation byte, so a status body never *starts* a code point with it.
SYNC: Final = 0xB5
HEADER_SIZE: Final = 8
#: The one-byte `size` field bounds every packet's payload.
MAX_PAYLOAD_SIZE: Final = 255
MAX_PACKET_SIZE: Final = HEADER_SIZE + MAX_PAYLOAD_SIZE

#: Packet types (thesis table 2.1).
PAYLOAD_OPM: Final = 0
PAYLOAD_STATUS: Final = 1
PAYLOAD_UAV: Final = 2
PACKET_TYPES: Final = frozenset({PAYLOAD_OPM, PAYLOAD_STATUS, PAYLOAD_UAV})

HEADER: Final = struct.Struct("<BBBBHH")
assert HEADER.size == HEADER_SIZE


class PlanningProtocolError(CodecError):
    """A message that the planning protocol cannot represent; the text names the limit."""


class Malformed(CodecError):
    """Bytes that do not decode. Internal to the decoders: never escapes a public one."""


@dataclass(frozen=True, slots=True)
class PlanningPacket:
    """One planning-protocol packet as it travels: header fields and raw payload."""

    type: int
    user: int
    destination: int
    source: int
    body: bytes


def check_uint(name: str, value: int, bits: int) -> None:
    """Raise PlanningProtocolError unless `value` fits an unsigned field of `bits`."""
    limit = (1 << bits) - 1
    if not 0 <= value <= limit:
        raise PlanningProtocolError(f"{name} {value} does not fit in u{bits} (0..{limit})")


def check_finite(name: str, value: float, *, nonnegative: bool = False) -> None:
    """Raise PlanningProtocolError unless `value` is finite (and >= 0 if asked)."""
    if not math.isfinite(value) or (nonnegative and value < 0):
        need = "a finite, non-negative" if nonnegative else "a finite"
        raise PlanningProtocolError(f"{name} must be {need} number, got {value!r}")


def encode_packet(ptype: int, user: int, destination: int, source: int, body: bytes) -> bytes:
    """Frame one packet. Low level: the body is not checked against the type's layout."""
    check_uint("packet type", ptype, 8)
    check_uint("user", user, 8)
    check_uint("destination", destination, 16)
    check_uint("source", source, 16)
    if len(body) > MAX_PAYLOAD_SIZE:
        raise PlanningProtocolError(
            f"packet payload is {len(body)} bytes; the u8 size field allows {MAX_PAYLOAD_SIZE}"
        )
    return HEADER.pack(SYNC, len(body), ptype, user, destination, source) + body
