"""Message samples and hypothesis strategies shared by the link-codec tests."""

from __future__ import annotations

from hypothesis import strategies as st

from fleet.piccolo.telemetry import GpsBlock, SensorBlock, Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint


def sample_telemetry(time_ms: int = 1000) -> Telemetry:
    return Telemetry(
        system_time_ms=time_ms,
        gps=GpsBlock(lat=42.36, lon=-71.09, alt=120.5, vel_north=3.0, vel_east=21.5, vel_down=-0.2),
        sensor=SensorBlock(roll=5.0, pitch=1.5, yaw=82.0, indicated_airspeed=22.0),
        agl=120.0,
    )


def sample_waypoint(index: int = 90) -> Waypoint:
    return Waypoint(index=index, next_index=1, lat=42.361, lon=-71.085, alt=150.0)


u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
i16 = st.integers(-0x8000, 0x7FFF)

waypoints = st.builds(
    lambda lat, lon, alt, flags, radius, wind, orbit, index, nxt, user, flags2: Waypoint(
        index=index,
        next_index=nxt,
        lat=lat / 3_600_000,
        lon=lon / 3_600_000,
        alt=float(alt),
        flags=flags,
        orbit_radius=float(radius * (50 if flags2 & 0x08 else 10)),
        wind_finding=wind,
        orbit_time=float(orbit * 10),
        user=user,
        flags2=flags2,
    ),
    st.integers(-90 * 3_600_000, 90 * 3_600_000),
    st.integers(-180 * 3_600_000, 180 * 3_600_000),
    i16,
    u8,
    u8,
    u8,
    u8,
    st.integers(0, 99),
    st.integers(0, 99),
    u8,
    u8,
)
tracks = st.builds(Track, st.integers(0, 99), u8)
