"""Onboard planning protocol: codec, stream decoder and segment reassembler.

The protocol rides inside the Piccolo payload stream (thesis 2.9 and 4.2;
piccolo-link.md 4). Every packet is an 8-byte little-endian header

    sync u8 | size u8 | type u8 | user u8 | destination u16 | source u16

followed by `size` payload bytes. The thesis fixes the header and the three packet
types but leaves the sync byte, the `user` codes and every body layout open, and its
one-byte `size` cannot carry a 50-target mission; this module makes those choices
(documented byte by byte in docs/protocol.md, "Onboard planning protocol"):

* sync 0xB5; `user` codes PAYLOAD_TARGETS 1, PAYLOAD_UAVRESULT 2, PAYLOAD_ABORT 3.
* every PAYLOAD_UAV body starts with a 4-byte segment header (seq u16, index u8,
  count u8), so application messages up to 255 x 251 bytes travel as several packets
  and are put back together by `SegmentReassembler`.
* a PAYLOAD_STATUS text longer than 255 UTF-8 bytes is split into several status
  packets at code-point boundaries; each arrives as its own `StatusText`.

Pure code: no I/O and no clock. Time enters only as the `now` argument (seconds on any
monotonic clock the caller chooses). Decoders never raise on input bytes; they count
what they drop. Encoders raise `PlanningProtocolError` for what cannot be represented.
"""

from __future__ import annotations

import math
import struct
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Final, TypeAlias

import msgspec

from fleet.mission.messages import (
    MissionAbort,
    MissionTargets,
    OpmCommand,
    StatusText,
    Target,
    UavResult,
)
from fleet.piccolo.decoder import Chunk, Decoder, Reject, ResyncDecoder

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

#: `user` codes of the PAYLOAD_UAV application messages (project's choice). 0 is
#: reserved, never assigned: a zero-filled user byte is never taken for a real message.
PAYLOAD_TARGETS: Final = 1
PAYLOAD_UAVRESULT: Final = 2
PAYLOAD_ABORT: Final = 3
KNOWN_USER_CODES: Final = frozenset({PAYLOAD_TARGETS, PAYLOAD_UAVRESULT, PAYLOAD_ABORT})

#: Segment header carried at the start of every PAYLOAD_UAV body.
SEGMENT_HEADER_SIZE: Final = 4
MAX_FRAGMENT_SIZE: Final = MAX_PAYLOAD_SIZE - SEGMENT_HEADER_SIZE
MAX_SEGMENTS: Final = 255
#: Largest PAYLOAD_UAV application message: 255 segments of 251 bytes.
MAX_MESSAGE_SIZE: Final = MAX_SEGMENTS * MAX_FRAGMENT_SIZE

OPM_BODY_SIZE: Final = 9
TARGET_SIZE: Final = 20

_HEADER = struct.Struct("<BBBBHH")
_SEGMENT = struct.Struct("<HBB")
_OPM = struct.Struct("<Bd")
_TARGETS_HEAD = struct.Struct("<IdH")
_U16 = struct.Struct("<H")
_TARGET = struct.Struct("<ddf")
_RESULT_HEAD = struct.Struct("<IHH")
_F64 = struct.Struct("<d")
_ABORT = struct.Struct("<I")
#: The one NaN an encoder writes for a missing time; any NaN decodes as None.
_NONE_TIME: Final = bytes.fromhex("000000000000f87f")

assert _OPM.size == OPM_BODY_SIZE
assert _TARGET.size == TARGET_SIZE
assert _SEGMENT.size == SEGMENT_HEADER_SIZE

_BAD_TYPE = Reject("bad_type")
_BAD_SIZE = Reject("bad_size")
_BAD_BODY = Reject("bad_body")


class PlanningProtocolError(ValueError):
    """A message that the planning protocol cannot represent; the text names the limit."""


class UnknownPlanningMessage(msgspec.Struct, frozen=True):
    """A PAYLOAD_UAV application message whose `user` code this build does not know.

    Passed through rather than dropped: the Mission Manager relays inter-UAV traffic
    (thesis 2.9.1), so it must forward application messages newer than itself.
    `body` is the reassembled application bytes (segment headers removed).
    """

    type: int
    user: int
    body: bytes


PlanningMessage: TypeAlias = (
    OpmCommand | StatusText | MissionTargets | UavResult | MissionAbort | UnknownPlanningMessage
)


@dataclass(frozen=True, slots=True)
class PlanningPacket:
    """One planning-protocol packet as it travels: header fields and raw payload."""

    type: int
    user: int
    destination: int
    source: int
    body: bytes


@dataclass(frozen=True, slots=True)
class Envelope:
    """A decoded message with its planning-protocol endpoints."""

    source: int
    destination: int
    message: PlanningMessage


@dataclass(frozen=True, slots=True)
class ReassembledMessage:
    """A whole PAYLOAD_UAV application message, put back together from its segments."""

    source: int
    destination: int
    user: int
    seq: int
    data: bytes


class _Malformed(Exception):
    """Internal: bytes that do not decode. Never escapes a public decoder."""


# ---------------------------------------------------------------------------- encoding


def _check_uint(name: str, value: int, bits: int) -> None:
    limit = (1 << bits) - 1
    if not 0 <= value <= limit:
        raise PlanningProtocolError(f"{name} {value} does not fit in u{bits} (0..{limit})")


def _check_finite(name: str, value: float, *, nonnegative: bool = False) -> None:
    if not math.isfinite(value) or (nonnegative and value < 0):
        need = "a finite, non-negative" if nonnegative else "a finite"
        raise PlanningProtocolError(f"{name} must be {need} number, got {value!r}")


def encode_packet(ptype: int, user: int, destination: int, source: int, body: bytes) -> bytes:
    """Frame one packet. Low level: the body is not checked against the type's layout."""
    _check_uint("packet type", ptype, 8)
    _check_uint("user", user, 8)
    _check_uint("destination", destination, 16)
    _check_uint("source", source, 16)
    if len(body) > MAX_PAYLOAD_SIZE:
        raise PlanningProtocolError(
            f"packet payload is {len(body)} bytes; the u8 size field allows {MAX_PAYLOAD_SIZE}"
        )
    return _HEADER.pack(SYNC, len(body), ptype, user, destination, source) + body


def _encode_opm(msg: OpmCommand) -> bytes:
    _check_finite("status_rate_hz", msg.status_rate_hz, nonnegative=True)
    return _OPM.pack(1 if msg.enabled else 0, msg.status_rate_hz)


def _encode_targets(msg: MissionTargets) -> bytes:
    _check_uint("mission", msg.mission, 32)
    _check_finite("deadline_s", msg.deadline_s, nonnegative=True)
    # Counts first: they name the limit a caller hit before any per-item complaint.
    if len(msg.team) > 0xFFFF:
        raise PlanningProtocolError(
            f"team has {len(msg.team)} Piccolo IDs; the u16 team count allows 65535"
        )
    if len(msg.targets) > 0xFFFF:
        raise PlanningProtocolError(
            f"mission has {len(msg.targets)} targets; the u16 target count allows 65535"
        )
    for uav in msg.team:
        _check_uint("team Piccolo ID", uav, 16)
    parts = [
        _TARGETS_HEAD.pack(msg.mission, msg.deadline_s, len(msg.team)),
        struct.pack(f"<{len(msg.team)}H", *msg.team),
        _U16.pack(len(msg.targets)),
    ]
    for target in msg.targets:
        _check_finite("target lat", target.lat)
        _check_finite("target lon", target.lon)
        _check_finite("target alt", target.alt)
        try:
            parts.append(_TARGET.pack(target.lat, target.lon, target.alt))
        except OverflowError:
            raise PlanningProtocolError(
                f"target alt {target.alt!r} m is beyond the f32 range of the altitude field"
            ) from None
    return b"".join(parts)


def _encode_result(msg: UavResult) -> bytes:
    _check_uint("mission", msg.mission, 32)
    _check_uint("uav", msg.uav, 16)
    if len(msg.times) > 0xFFFF:
        raise PlanningProtocolError(
            f"result has {len(msg.times)} times; the u16 count allows 65535"
        )
    parts = [_RESULT_HEAD.pack(msg.mission, msg.uav, len(msg.times))]
    for time in msg.times:
        if time is None:
            parts.append(_NONE_TIME)
        elif math.isnan(time):
            # NaN on the wire means None; a NaN time would come back as None.
            raise PlanningProtocolError("a time of NaN cannot travel (NaN encodes None)")
        else:
            parts.append(_F64.pack(time))
    return b"".join(parts)


def _encode_application(msg: PlanningMessage) -> tuple[int, bytes]:
    if isinstance(msg, MissionTargets):
        return PAYLOAD_TARGETS, _encode_targets(msg)
    if isinstance(msg, UavResult):
        return PAYLOAD_UAVRESULT, _encode_result(msg)
    if isinstance(msg, MissionAbort):
        _check_uint("mission", msg.mission, 32)
        return PAYLOAD_ABORT, _ABORT.pack(msg.mission)
    if isinstance(msg, UnknownPlanningMessage):
        if msg.type != PAYLOAD_UAV:
            raise PlanningProtocolError(
                f"an unknown message must be PAYLOAD_UAV ({PAYLOAD_UAV}), not type {msg.type}"
            )
        _check_uint("user", msg.user, 8)
        if msg.user in KNOWN_USER_CODES:
            # A raw body under a known code could be undecodable; send the typed message.
            raise PlanningProtocolError(
                f"user code {msg.user} is a known message; encode the typed struct instead"
            )
        return msg.user, bytes(msg.body)
    raise PlanningProtocolError(f"{type(msg).__name__} is not a planning-protocol message")


def _segment(user: int, data: bytes, source: int, destination: int, seq: int) -> list[bytes]:
    _check_uint("seq", seq, 16)
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


def _split_utf8(data: bytes, limit: int) -> list[bytes]:
    """Cut UTF-8 bytes into pieces of at most `limit` bytes, never inside a code point."""
    if not data:
        return [b""]
    pieces = []
    start = 0
    while start < len(data):
        stop = min(start + limit, len(data))
        # Back off continuation bytes (10xxxxxx) so each piece is valid UTF-8 alone;
        # a code point is at most 4 bytes, so this never reaches `start`.
        while stop < len(data) and (data[stop] & 0xC0) == 0x80:
            stop -= 1
        pieces.append(data[start:stop])
        start = stop
    return pieces


def encode_packets(
    msg: PlanningMessage, source: int, destination: int, seq: int = 0
) -> list[bytes]:
    """Encode one message as its list of packets (one unless split or segmented).

    `seq` (u16) identifies the message among the sender's PAYLOAD_UAV messages with the
    same `user` code; it only matters when two segmented messages may be in flight at
    once. PAYLOAD_OPM and PAYLOAD_STATUS ignore it.
    """
    _check_uint("source", source, 16)
    _check_uint("destination", destination, 16)
    if isinstance(msg, OpmCommand):
        return [encode_packet(PAYLOAD_OPM, 0, destination, source, _encode_opm(msg))]
    if isinstance(msg, StatusText):
        try:
            text = msg.text.encode("utf-8")
        except UnicodeEncodeError as error:
            raise PlanningProtocolError(f"status text is not encodable as UTF-8: {error}") from None
        return [
            encode_packet(PAYLOAD_STATUS, 0, destination, source, piece)
            for piece in _split_utf8(text, MAX_PAYLOAD_SIZE)
        ]
    user, data = _encode_application(msg)
    return _segment(user, data, source, destination, seq)


def encode_message(msg: PlanningMessage, source: int, destination: int, seq: int = 0) -> bytes:
    """Encode one message as the concatenated bytes of its packets, ready for the stream."""
    return b"".join(encode_packets(msg, source, destination, seq))


# ---------------------------------------------------------------------------- decoding


def _decode_opm(body: bytes) -> OpmCommand:
    if len(body) != OPM_BODY_SIZE:
        raise _Malformed("OPM body size")
    enabled, rate = _OPM.unpack(body)
    if enabled not in (0, 1) or not math.isfinite(rate) or rate < 0:
        raise _Malformed("OPM field value")
    return OpmCommand(enabled=enabled == 1, status_rate_hz=rate)


def _decode_status(body: bytes) -> StatusText:
    try:
        return StatusText(text=body.decode("utf-8"))
    except UnicodeDecodeError:
        raise _Malformed("status text is not UTF-8") from None


def _decode_targets(data: bytes) -> MissionTargets:
    if len(data) < _TARGETS_HEAD.size + _U16.size:
        raise _Malformed("targets too short")
    mission, deadline, team_count = _TARGETS_HEAD.unpack_from(data, 0)
    offset = _TARGETS_HEAD.size
    if not math.isfinite(deadline) or deadline < 0:
        raise _Malformed("targets deadline")
    if len(data) < offset + 2 * team_count + _U16.size:
        raise _Malformed("targets team truncated")
    team = struct.unpack_from(f"<{team_count}H", data, offset)
    offset += 2 * team_count
    (target_count,) = _U16.unpack_from(data, offset)
    offset += _U16.size
    if len(data) != offset + TARGET_SIZE * target_count:
        raise _Malformed("targets length")
    targets = []
    for lat, lon, alt in _TARGET.iter_unpack(data[offset:]):
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(alt)):
            raise _Malformed("target coordinate")
        targets.append(Target(lat=lat, lon=lon, alt=alt))
    return MissionTargets(
        mission=mission, team=tuple(team), targets=tuple(targets), deadline_s=deadline
    )


def _decode_result(data: bytes) -> UavResult:
    if len(data) < _RESULT_HEAD.size:
        raise _Malformed("result too short")
    mission, uav, count = _RESULT_HEAD.unpack_from(data, 0)
    if len(data) != _RESULT_HEAD.size + 8 * count:
        raise _Malformed("result length")
    raw = struct.unpack_from(f"<{count}d", data, _RESULT_HEAD.size)
    return UavResult(
        mission=mission, uav=uav, times=tuple(None if math.isnan(t) else t for t in raw)
    )


def _decode_application(user: int, data: bytes) -> PlanningMessage:
    if user == PAYLOAD_TARGETS:
        return _decode_targets(data)
    if user == PAYLOAD_UAVRESULT:
        return _decode_result(data)
    if user == PAYLOAD_ABORT:
        if len(data) != _ABORT.size:
            raise _Malformed("abort length")
        return MissionAbort(mission=_ABORT.unpack(data)[0])
    return UnknownPlanningMessage(type=PAYLOAD_UAV, user=user, body=data)


def _split_segment(body: bytes) -> tuple[int, int, int, bytes]:
    """(seq, index, count, fragment) of a PAYLOAD_UAV body, checked against the rule."""
    if len(body) < SEGMENT_HEADER_SIZE:
        raise _Malformed("segment header truncated")
    seq, index, count = _SEGMENT.unpack_from(body, 0)
    fragment = body[SEGMENT_HEADER_SIZE:]
    if count == 0 or index >= count:
        raise _Malformed("segment index/count")
    # Every segment but the last is full, and a multi-segment message has no empty
    # last segment: so offsets follow from the index, and a false sync rarely passes.
    if index < count - 1:
        if len(fragment) != MAX_FRAGMENT_SIZE:
            raise _Malformed("non-final segment not full")
    elif count > 1 and not fragment:
        raise _Malformed("empty final segment")
    return seq, index, count, fragment


def _check_body(ptype: int, user: int, body: bytes) -> None:
    """Raise _Malformed unless the payload decodes as far as one packet allows."""
    if ptype == PAYLOAD_OPM:
        _decode_opm(body)
    elif ptype == PAYLOAD_STATUS:
        _decode_status(body)
    else:
        _, _, count, fragment = _split_segment(body)
        if count == 1 and user in KNOWN_USER_CODES:
            _decode_application(user, fragment)


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
        _, size, ptype, user, destination, source = _HEADER.unpack_from(buffer, start)
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
        except (_Malformed, struct.error):
            return _BAD_BODY
        return PlanningPacket(ptype, user, destination, source, body), stop


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
            seq, index, count, fragment = _split_segment(packet.body)
        except _Malformed:
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
                    message = _decode_opm(packet.body)
                elif packet.type == PAYLOAD_STATUS:
                    message = _decode_status(packet.body)
                else:
                    whole = self.reassembler.push(packet, now)
                    if whole is None:
                        continue
                    message = _decode_application(whole.user, whole.data)
            except (_Malformed, struct.error):
                self._bad_message += 1
                continue
            envelopes.append(Envelope(packet.source, packet.destination, message))
        return envelopes
