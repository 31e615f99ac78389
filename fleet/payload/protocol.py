"""Onboard planning protocol: typed messages <-> payload-stream bytes, the public face.

The protocol rides inside the Piccolo payload stream (thesis 2.9 and 4.2;
docs/protocol.md §6). Every packet is an 8-byte little-endian header

    sync u8 | size u8 | type u8 | user u8 | destination u16 | source u16

followed by `size` payload bytes. The thesis fixes the header and the three packet
types but leaves the sync byte, the `user` codes and every body layout open, and its
one-byte `size` cannot carry a 50-target mission; this package makes those choices
(documented byte by byte in docs/protocol.md, "Onboard planning protocol"):

* sync 0xB5; `user` codes PAYLOAD_TARGETS 1, PAYLOAD_UAVRESULT 2, PAYLOAD_ABORT 3.
* every PAYLOAD_UAV body starts with a 4-byte segment header (seq u16, index u8,
  count u8), so application messages up to 255 x 251 bytes travel as several packets
  and are put back together by `SegmentReassembler`.
* a PAYLOAD_STATUS text longer than 255 UTF-8 bytes is split into several status
  packets at code-point boundaries; each arrives as its own `StatusText`.

The code is split by concern: `framing` (the header, `PlanningPacket`, the errors),
`bodies` (each message's body layout and `user` code), `reassembly` (the segment
header, cutting a message into packets and `SegmentReassembler`), `resync`
(`PlanningStreamDecoder`: packets out of the byte stream) and this module, whole
messages in and out: `encode_packets`, `encode_message` and `PlanningDecoder`.

Pure code: no I/O and no clock. Time enters only as the `now` argument (seconds on any
monotonic clock the caller chooses). Decoders never raise on input bytes; they count
what they drop. Encoders raise `PlanningProtocolError` for what cannot be represented.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from fleet.mission.messages import OpmCommand, StatusText
from fleet.payload.bodies import (
    PlanningMessage,
    UnknownPlanningMessage,
    decode_application,
    decode_opm,
    decode_status,
    encode_application,
    encode_opm,
    encode_status,
)
from fleet.payload.framing import (
    PAYLOAD_OPM,
    PAYLOAD_STATUS,
    Malformed,
    PlanningProtocolError,
    check_uint,
    encode_packet,
)
from fleet.payload.reassembly import MAX_MESSAGE_SIZE, SegmentReassembler, segment
from fleet.payload.resync import PlanningStreamDecoder
from fleet.piccolo.decoder import Chunk, Decoder

# The messages and the error that appear in this API are re-exported with it.
__all__ = [
    "Envelope",
    "PlanningDecoder",
    "PlanningMessage",
    "PlanningProtocolError",
    "UnknownPlanningMessage",
    "encode_message",
    "encode_packets",
]


@dataclass(frozen=True, slots=True)
class Envelope:
    """A decoded message with its planning-protocol endpoints."""

    source: int
    destination: int
    message: PlanningMessage


def encode_packets(
    msg: PlanningMessage, source: int, destination: int, seq: int = 0
) -> list[bytes]:
    """Encode one message as its list of packets (one unless split or segmented).

    `seq` (u16) identifies the message among the sender's PAYLOAD_UAV messages with the
    same `user` code; it only matters when two segmented messages may be in flight at
    once. PAYLOAD_OPM and PAYLOAD_STATUS ignore it.
    """
    check_uint("source", source, 16)
    check_uint("destination", destination, 16)
    if isinstance(msg, OpmCommand):
        return [encode_packet(PAYLOAD_OPM, 0, destination, source, encode_opm(msg))]
    if isinstance(msg, StatusText):
        return [
            encode_packet(PAYLOAD_STATUS, 0, destination, source, piece)
            for piece in encode_status(msg)
        ]
    user, data = encode_application(msg)
    return segment(user, data, source, destination, seq)


def encode_message(msg: PlanningMessage, source: int, destination: int, seq: int = 0) -> bytes:
    """Encode one message as the concatenated bytes of its packets, ready for the stream."""
    return b"".join(encode_packets(msg, source, destination, seq))


class PlanningDecoder(Decoder[Envelope]):
    """Payload byte stream in, typed messages out: stream decoder + reassembler.

    `feed(data, now)` returns an `Envelope` per complete message. Known `user` codes
    decode to the structs of fleet.mission.messages; other codes arrive as
    `UnknownPlanningMessage`. A reassembled message whose bytes do not decode is
    dropped and counted as `bad_message`. `drops` merges every counter.
    """

    def __init__(
        self, max_pending: int = 32, max_bytes: int = 4 * MAX_MESSAGE_SIZE, max_age_s: float = 30.0
    ) -> None:
        self.stream = PlanningStreamDecoder()
        self.reassembler = SegmentReassembler(max_pending, max_bytes, max_age_s)
        self._bad_message = 0

    @property
    def drops(self) -> dict[str, int]:
        return {
            **self.stream.drops,
            **self.reassembler.drops,
            "bad_message": self._bad_message,
        }

    def feed(self, data: Chunk, now: float = 0.0) -> list[Envelope]:
        # Age out stale partial messages even when this chunk carries none of their bytes.
        self.reassembler.expire(now)
        envelopes = []
        for packet in self.stream.feed(data):
            try:
                message: PlanningMessage
                if packet.type == PAYLOAD_OPM:
                    message = decode_opm(packet.body)
                elif packet.type == PAYLOAD_STATUS:
                    message = decode_status(packet.body)
                else:
                    whole = self.reassembler.push(packet, now)
                    if whole is None:
                        continue
                    message = decode_application(whole.user, whole.data)
            except (Malformed, struct.error):
                self._bad_message += 1
                continue
            envelopes.append(Envelope(packet.source, packet.destination, message))
        return envelopes
