"""Planning-protocol packets out of the payload byte stream, resynchronising on 0xB5.

A candidate packet passes when its type is known, its size is one the type allows and
its payload decodes as far as one packet allows; anything else is a false sync (a 0xB5
inside data, or bytes lost with a dropped Piccolo packet) and costs one byte.
"""

from __future__ import annotations

import struct

from fleet.payload.bodies import (
    KNOWN_USER_CODES,
    OPM_BODY_SIZE,
    decode_application,
    decode_opm,
    decode_status,
)
from fleet.payload.framing import (
    HEADER,
    HEADER_SIZE,
    PACKET_TYPES,
    PAYLOAD_OPM,
    PAYLOAD_STATUS,
    PAYLOAD_UAV,
    SYNC,
    Malformed,
    PlanningPacket,
)
from fleet.payload.reassembly import SEGMENT_HEADER_SIZE, split_segment
from fleet.piccolo.decoder import Reject, ResyncDecoder

__all__ = ["PlanningStreamDecoder"]

_BAD_TYPE = Reject("bad_type")
_BAD_SIZE = Reject("bad_size")
_BAD_BODY = Reject("bad_body")


def _check_body(ptype: int, user: int, body: bytes) -> None:
    """Raise Malformed unless the payload decodes as far as one packet allows."""
    if ptype == PAYLOAD_OPM:
        decode_opm(body)
    elif ptype == PAYLOAD_STATUS:
        decode_status(body)
    else:
        _, _, count, fragment = split_segment(body)
        if count == 1 and user in KNOWN_USER_CODES:
            decode_application(user, fragment)


def _size_fits_type(ptype: int, size: int) -> bool:
    if ptype == PAYLOAD_OPM:
        return size == OPM_BODY_SIZE
    if ptype == PAYLOAD_UAV:
        return size >= SEGMENT_HEADER_SIZE
    return True


class PlanningStreamDecoder(ResyncDecoder[PlanningPacket]):
    """Incremental packet decoder for the payload byte stream.

    Fed arbitrary chunks, it hunts for SYNC, checks the header (known type, a size the
    type allows), waits for the payload, then checks the payload decodes. The Piccolo
    layer delivers bytes intact, so a rejected candidate means a false sync (a 0xB5
    inside data, or bytes lost with a dropped Piccolo packet): the decoder skips that one
    byte and rescans from the next, so a real packet overlapping the candidate is still
    found. Between calls it holds at most one partial packet (263 bytes).

    Drop counters: `bad_type`, `bad_size` (header rejected), `bad_body` (payload does
    not decode), and `skipped_bytes`: every byte discarded outside a delivered packet,
    each rejected candidate's sync byte included.
    """

    SYNC = bytes((SYNC,))
    REASONS = ("bad_type", "bad_size", "bad_body")

    def _frame(self, buffer: bytearray, start: int) -> tuple[PlanningPacket, int] | Reject | None:
        if len(buffer) - start < HEADER_SIZE:
            return None
        _, size, ptype, user, destination, source = HEADER.unpack_from(buffer, start)
        if ptype not in PACKET_TYPES:
            return _BAD_TYPE
        if not _size_fits_type(ptype, size):
            return _BAD_SIZE
        stop = start + HEADER_SIZE + size
        if len(buffer) < stop:
            return None
        body = bytes(buffer[start + HEADER_SIZE : stop])
        try:
            _check_body(ptype, user, body)
        except (Malformed, struct.error):
            return _BAD_BODY
        return PlanningPacket(ptype, user, destination, source, body), stop
