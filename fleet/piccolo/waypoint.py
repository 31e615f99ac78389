"""Legacy WAYPOINT (autopilot packet type 8, 18 data bytes), typed (docs/protocol.md §3).

Sent to the autopilot it creates or moves waypoint `index`; the autopilot echoes what it
stored. A flight plan is the closed chain of waypoints linked by `next_index`.
"""

from __future__ import annotations

import struct

import msgspec

from fleet.errors import CodecError
from fleet.piccolo.telemetry import MAS_PER_DEGREE

PACKET_TYPE = 8
DATA_SIZE = 18
MAX_INDEX = 99

FLAG2_RADIUS_X50 = 0x08

_WAYPOINT = struct.Struct(">iiBBhBBBBBB")


class WaypointError(CodecError):
    """Waypoint bytes of the wrong size, or a value that does not fit."""


class Waypoint(msgspec.Struct, frozen=True, tag="waypoint"):
    index: int
    next_index: int
    lat: float  #: degrees
    lon: float  #: degrees
    alt: float  #: metres (whole metres on the wire)
    flags: int = 0
    orbit_radius: float = 0.0  #: metres: units of 10 m, or 50 m with flags2 0x08
    wind_finding: int = 0
    orbit_time: float = 0.0  #: seconds, units of 10 s
    user: int = 0
    flags2: int = 0


def _radius_unit(flags2: int) -> int:
    return 50 if flags2 & FLAG2_RADIUS_X50 else 10


def decode_waypoint(data: bytes) -> Waypoint:
    if len(data) != DATA_SIZE:
        raise WaypointError(f"waypoint has {len(data)} data bytes; expected {DATA_SIZE}")
    lat, lon, flags, radius, alt, wind, orbit, index, next_index, user, flags2 = _WAYPOINT.unpack(
        data
    )
    return Waypoint(
        index=index,
        next_index=next_index,
        lat=lat / MAS_PER_DEGREE,
        lon=lon / MAS_PER_DEGREE,
        alt=float(alt),
        flags=flags,
        orbit_radius=float(radius * _radius_unit(flags2)),
        wind_finding=wind,
        orbit_time=float(orbit * 10),
        user=user,
        flags2=flags2,
    )


def encode_waypoint(waypoint: Waypoint) -> bytes:
    for name in ("index", "next_index"):
        value = getattr(waypoint, name)
        if not 0 <= value <= MAX_INDEX:
            raise WaypointError(f"waypoint {name} {value} outside 0-{MAX_INDEX}")
    try:
        return _WAYPOINT.pack(
            round(waypoint.lat * MAS_PER_DEGREE),
            round(waypoint.lon * MAS_PER_DEGREE),
            waypoint.flags,
            round(waypoint.orbit_radius / _radius_unit(waypoint.flags2)),
            round(waypoint.alt),
            waypoint.wind_finding,
            round(waypoint.orbit_time / 10),
            waypoint.index,
            waypoint.next_index,
            waypoint.user,
            waypoint.flags2,
        )
    except struct.error as error:
        raise WaypointError(f"waypoint {waypoint.index}: value out of range: {error}") from error
