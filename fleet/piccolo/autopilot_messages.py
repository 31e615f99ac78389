"""Typed autopilot messages: dispatch between packet types and their structs.

Known types decode to Telemetry, Waypoint or Track; any other type, or a known type
whose bytes do not decode, passes through as UnknownAutopilotMessage (never dropped:
a user with a capture still sees it).
"""

from __future__ import annotations

from collections.abc import Callable

import msgspec

from fleet.piccolo import telemetry, track, waypoint
from fleet.piccolo.autopilot_packet import AutopilotPacket, encode_autopilot_packet
from fleet.piccolo.telemetry import Telemetry, TelemetryError
from fleet.piccolo.track import Track, TrackError
from fleet.piccolo.waypoint import Waypoint, WaypointError


class UnknownAutopilotMessage(msgspec.Struct, frozen=True, tag="unknown"):
    packet_type: int
    data: bytes
    error: str | None = None  #: why a known type did not decode, if it is one


AutopilotMessage = Telemetry | Waypoint | Track | UnknownAutopilotMessage

_DECODERS: dict[int, Callable[[bytes], AutopilotMessage]] = {
    telemetry.PACKET_TYPE: telemetry.decode_telemetry,
    waypoint.PACKET_TYPE: waypoint.decode_waypoint,
    track.PACKET_TYPE: track.decode_track,
}


def decode_autopilot_message(packet: AutopilotPacket) -> AutopilotMessage:
    decoder = _DECODERS.get(packet.packet_type)
    if decoder is None:
        return UnknownAutopilotMessage(packet.packet_type, packet.data)
    try:
        return decoder(packet.data)
    except (TelemetryError, WaypointError, TrackError) as error:
        return UnknownAutopilotMessage(packet.packet_type, packet.data, str(error))


def encode_autopilot_message(message: AutopilotMessage) -> bytes:
    """The whole framed autopilot packet (sync, type, size, data, CRC)."""
    if isinstance(message, Telemetry):
        return encode_autopilot_packet(telemetry.PACKET_TYPE, telemetry.encode_telemetry(message))
    if isinstance(message, Waypoint):
        return encode_autopilot_packet(waypoint.PACKET_TYPE, waypoint.encode_waypoint(message))
    if isinstance(message, Track):
        return encode_autopilot_packet(track.PACKET_TYPE, track.encode_track(message))
    return encode_autopilot_packet(message.packet_type, message.data)
