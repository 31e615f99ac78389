"""Planning-protocol message bodies: typed messages <-> payload bytes (docs/protocol.md 6).

The thesis fixes the three packet types but leaves every body layout and the `user`
codes open; this module makes those choices. PAYLOAD_OPM and PAYLOAD_STATUS bodies fit
one packet; a PAYLOAD_UAV application message (targets, result, abort, or an unknown
`user` code passed through) may span several, and is cut and put back together by
`fleet.payload.reassembly`.
"""

from __future__ import annotations

import math
import struct
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
from fleet.mission.status_kind import StatusKind
from fleet.payload.framing import (
    MAX_PAYLOAD_SIZE,
    PAYLOAD_UAV,
    Malformed,
    PlanningProtocolError,
    check_finite,
    check_uint,
)

__all__ = [
    "KNOWN_USER_CODES",
    "OPM_BODY_SIZE",
    "PAYLOAD_ABORT",
    "PAYLOAD_TARGETS",
    "PAYLOAD_UAVRESULT",
    "TARGET_SIZE",
    "PlanningMessage",
    "UnknownPlanningMessage",
    "decode_application",
    "decode_opm",
    "decode_status",
    "encode_application",
    "encode_opm",
    "encode_status",
]

#: `user` codes of the PAYLOAD_UAV application messages (project's choice). 0 is
#: reserved, never assigned: a zero-filled user byte is never taken for a real message.
PAYLOAD_TARGETS: Final = 1
PAYLOAD_UAVRESULT: Final = 2
PAYLOAD_ABORT: Final = 3
KNOWN_USER_CODES: Final = frozenset({PAYLOAD_TARGETS, PAYLOAD_UAVRESULT, PAYLOAD_ABORT})

OPM_BODY_SIZE: Final = 9
TARGET_SIZE: Final = 20

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


# ---------------------------------------------------------------------------- encoding


def encode_opm(msg: OpmCommand) -> bytes:
    check_finite("status_rate_hz", msg.status_rate_hz, nonnegative=True)
    return _OPM.pack(1 if msg.enabled else 0, msg.status_rate_hz)


def _encode_targets(msg: MissionTargets) -> bytes:
    check_uint("mission", msg.mission, 32)
    check_finite("deadline_s", msg.deadline_s, nonnegative=True)
    if msg.zones:
        # Sent without them, the mission would have its aircraft fly straight through.
        raise PlanningProtocolError(
            f"mission has {len(msg.zones)} no-fly zones; the binary targets message has no "
            "room for them (send the mission over Zenoh)"
        )
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
        check_uint("team Piccolo ID", uav, 16)
    parts = [
        _TARGETS_HEAD.pack(msg.mission, msg.deadline_s, len(msg.team)),
        struct.pack(f"<{len(msg.team)}H", *msg.team),
        _U16.pack(len(msg.targets)),
    ]
    for target in msg.targets:
        check_finite("target lat", target.lat)
        check_finite("target lon", target.lon)
        check_finite("target alt", target.alt)
        try:
            parts.append(_TARGET.pack(target.lat, target.lon, target.alt))
        except OverflowError:
            raise PlanningProtocolError(
                f"target alt {target.alt!r} m is beyond the f32 range of the altitude field"
            ) from None
    return b"".join(parts)


def _encode_result(msg: UavResult) -> bytes:
    check_uint("mission", msg.mission, 32)
    check_uint("uav", msg.uav, 16)
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


def encode_application(msg: PlanningMessage) -> tuple[int, bytes]:
    if isinstance(msg, MissionTargets):
        return PAYLOAD_TARGETS, _encode_targets(msg)
    if isinstance(msg, UavResult):
        return PAYLOAD_UAVRESULT, _encode_result(msg)
    if isinstance(msg, MissionAbort):
        check_uint("mission", msg.mission, 32)
        if msg.uav is not None:
            # The body has room for the mission id alone: sent, it would abort the team.
            raise PlanningProtocolError(
                f"PAYLOAD_ABORT cannot carry one UAV ({msg.uav}): it would abort the whole team"
            )
        return PAYLOAD_ABORT, _ABORT.pack(msg.mission)
    if isinstance(msg, UnknownPlanningMessage):
        if msg.type != PAYLOAD_UAV:
            raise PlanningProtocolError(
                f"an unknown message must be PAYLOAD_UAV ({PAYLOAD_UAV}), not type {msg.type}"
            )
        check_uint("user", msg.user, 8)
        if msg.user in KNOWN_USER_CODES:
            # A raw body under a known code could be undecodable; send the typed message.
            raise PlanningProtocolError(
                f"user code {msg.user} is a known message; encode the typed struct instead"
            )
        return msg.user, bytes(msg.body)
    raise PlanningProtocolError(f"{type(msg).__name__} is not a planning-protocol message")


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


def encode_status(msg: StatusText) -> list[bytes]:
    """The bodies of the status packets carrying `msg`: one unless the text is long."""
    try:
        text = msg.text.encode("utf-8")
    except UnicodeEncodeError as error:
        raise PlanningProtocolError(f"status text is not encodable as UTF-8: {error}") from None
    return _split_utf8(text, MAX_PAYLOAD_SIZE)


# ---------------------------------------------------------------------------- decoding


def decode_opm(body: bytes) -> OpmCommand:
    if len(body) != OPM_BODY_SIZE:
        raise Malformed("OPM body size")
    enabled, rate = _OPM.unpack(body)
    if enabled not in (0, 1) or not math.isfinite(rate) or rate < 0:
        raise Malformed("OPM field value")
    return OpmCommand(enabled=enabled == 1, status_rate_hz=rate)


def decode_status(body: bytes) -> StatusText:
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError:
        raise Malformed("status text is not UTF-8") from None
    return StatusText(text, status_kind_of_text(text))


def status_kind_of_text(text: str) -> StatusKind:
    """The kind of a status text that arrived without one: the payload link carries the
    text alone, and its `error:` / `warning:` prefix (the onboard convention) says which
    generic kind it is. The only place a status text's prefix is read."""
    if text.startswith("error"):
        return StatusKind.ERROR
    if text.startswith("warning"):
        return StatusKind.WARNING
    return StatusKind.INFO


def _decode_targets(data: bytes) -> MissionTargets:
    if len(data) < _TARGETS_HEAD.size + _U16.size:
        raise Malformed("targets too short")
    mission, deadline, team_count = _TARGETS_HEAD.unpack_from(data, 0)
    offset = _TARGETS_HEAD.size
    if not math.isfinite(deadline) or deadline < 0:
        raise Malformed("targets deadline")
    if len(data) < offset + 2 * team_count + _U16.size:
        raise Malformed("targets team truncated")
    team = struct.unpack_from(f"<{team_count}H", data, offset)
    offset += 2 * team_count
    (target_count,) = _U16.unpack_from(data, offset)
    offset += _U16.size
    if len(data) != offset + TARGET_SIZE * target_count:
        raise Malformed("targets length")
    targets = []
    for lat, lon, alt in _TARGET.iter_unpack(data[offset:]):
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(alt)):
            raise Malformed("target coordinate")
        targets.append(Target(lat=lat, lon=lon, alt=alt))
    return MissionTargets(
        mission=mission, team=tuple(team), targets=tuple(targets), deadline_s=deadline
    )


def _decode_result(data: bytes) -> UavResult:
    if len(data) < _RESULT_HEAD.size:
        raise Malformed("result too short")
    mission, uav, count = _RESULT_HEAD.unpack_from(data, 0)
    if len(data) != _RESULT_HEAD.size + 8 * count:
        raise Malformed("result length")
    raw = struct.unpack_from(f"<{count}d", data, _RESULT_HEAD.size)
    return UavResult(
        mission=mission, uav=uav, times=tuple(None if math.isnan(t) else t for t in raw)
    )


def decode_application(user: int, data: bytes) -> PlanningMessage:
    if user == PAYLOAD_TARGETS:
        return _decode_targets(data)
    if user == PAYLOAD_UAVRESULT:
        return _decode_result(data)
    if user == PAYLOAD_ABORT:
        if len(data) != _ABORT.size:
            raise Malformed("abort length")
        return MissionAbort(mission=_ABORT.unpack(data)[0])
    return UnknownPlanningMessage(type=PAYLOAD_UAV, user=user, body=data)
