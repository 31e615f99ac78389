"""TRACK (autopilot packet type 10, 2 data bytes) (docs/protocol.md §3).

Sent to the autopilot it says which waypoint to track; the autopilot reports the
waypoint it tracks with the same packet.
"""

from __future__ import annotations

import msgspec

from fleet.errors import CodecError
from fleet.piccolo.waypoint import MAX_INDEX

PACKET_TYPE = 10
DATA_SIZE = 2


class TrackError(CodecError):
    """Track bytes of the wrong size, or a waypoint index out of range."""


class Track(msgspec.Struct, frozen=True, tag="track"):
    waypoint: int
    go_to: int = 0


def decode_track(data: bytes) -> Track:
    if len(data) != DATA_SIZE:
        raise TrackError(f"track has {len(data)} data bytes; expected {DATA_SIZE}")
    return Track(waypoint=data[0], go_to=data[1])


def encode_track(track: Track) -> bytes:
    if not 0 <= track.waypoint <= MAX_INDEX:
        raise TrackError(f"track waypoint {track.waypoint} outside 0-{MAX_INDEX}")
    if not 0 <= track.go_to <= 0xFF:
        raise TrackError(f"track go_to {track.go_to} does not fit in 8 bits")
    return bytes((track.waypoint, track.go_to))
