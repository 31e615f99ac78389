"""TELEMETRY_HI_RES (autopilot packet type 69), typed in SI units and degrees.

Layout and units: docs/protocol.md §3. Blocks after offset 8 are present only when their
bit in `data_flags` is set; a clear block is omitted and later blocks move up
(ASSUMPTION, docs/protocol.md §3). Order: GPS, sensor, raw (inertial), magnetometer
(with the compass heading: ASSUMPTION, docs/protocol.md), AGL, actuators (u16 each,
count in data_flags & 0x3F), fuel (IEEE half: ASSUMPTION). Bytes past what this
decoder knows are kept verbatim in `tail`, so nothing is misread or lost.
"""

from __future__ import annotations

import math
import struct

import msgspec

from fleet.errors import CodecError

PACKET_TYPE = 69

FLAG_GPS = 0x8000
FLAG_SENSOR = 0x4000
FLAG_RAW = 0x2000
FLAG_MAGNETOMETER = 0x1000
FLAG_AGL = 0x0800
FLAG_FUEL = 0x0400
ACTUATOR_COUNT_MASK = 0x003F

MAS_PER_DEGREE = 3_600_000.0
HEIGHT_OFFSET_M = 1000.0
IAS_OFFSET = 2000
ACCEL_PER_COUNT = 0.005
GPS_3D_FIX = 0xE000

_HEAD = struct.Struct(">HHI")
_GPS = struct.Struct(">ii3sBHhhhHHI")
_SENSOR = struct.Struct(">hhhhhhHHBbHH")
_RAW = struct.Struct(">hhhhhh")
_MAGNETOMETER = struct.Struct(">hhhH")
_AGL = struct.Struct(">H")
_FUEL = struct.Struct(">e")


class TelemetryError(CodecError):
    """Telemetry bytes too short for their flags, or a value that does not fit."""


class GpsBlock(msgspec.Struct, frozen=True):
    lat: float  #: degrees
    lon: float  #: degrees
    alt: float  #: metres (height above the ellipsoid)
    vel_north: float  #: m/s
    vel_east: float  #: m/s
    vel_down: float  #: m/s
    dop: float = 0.0
    sats_visible: int = 0
    sats_tracked: int = 0
    gps_status: int = GPS_3D_FIX
    gps_week: int = 0
    gps_time_of_week_ms: int = 0
    reserved: int = 0


class SensorBlock(msgspec.Struct, frozen=True):
    roll: float  #: degrees
    pitch: float  #: degrees
    yaw: float  #: degrees true
    indicated_airspeed: float  #: m/s
    wind_south: float = 0.0  #: m/s
    wind_west: float = 0.0  #: m/s
    baro_altitude_raw: int = 0  #: legacy field of unknown unit, kept raw
    rpm_left: int = 0
    rpm_right: int = 0
    density_ratio: float = 1.0
    outside_air_temp: int = 15  #: deg C
    static_pressure: float = 101324.0  #: Pa

    def true_airspeed(self) -> float | None:
        """The true airspeed (m/s): the indicated one over the square root of the density
        ratio; None where the block says nothing usable (no density, no airspeed)."""
        ias, density = self.indicated_airspeed, self.density_ratio
        if not (math.isfinite(ias) and ias > 0.0 and math.isfinite(density) and density > 0.0):
            return None
        return ias / math.sqrt(density)


class RawBlock(msgspec.Struct, frozen=True):
    p: float  #: deg/s
    q: float  #: deg/s
    r: float  #: deg/s
    accel_x: float  #: m/s^2
    accel_y: float  #: m/s^2
    accel_z: float  #: m/s^2


class MagnetometerBlock(msgspec.Struct, frozen=True):
    x: float  #: gauss
    y: float  #: gauss
    z: float  #: gauss
    compass_heading_raw: int = 0


class Telemetry(msgspec.Struct, frozen=True, tag="telemetry"):
    """One TELEMETRY_HI_RES packet."""

    system_time_ms: int
    gps: GpsBlock | None = None
    sensor: SensorBlock | None = None
    raw: RawBlock | None = None
    magnetometer: MagnetometerBlock | None = None
    agl: float | None = None  #: metres
    actuators: tuple[int, ...] = ()
    fuel: float | None = None
    limit_flags: int = 0
    tail: bytes = b""


def _angle_raw(degrees: float) -> int:
    return round(math.radians(degrees) * 1e4)


def _heading_raw(degrees: float) -> int:
    """A heading in 1e-4 rad: i16 spans only +-187 degrees, so 0-360 wraps to +-180."""
    raw = _angle_raw(degrees)
    if -0x8000 <= raw <= 0x7FFF:
        return raw
    return _angle_raw((degrees + 180.0) % 360.0 - 180.0)


def decode_telemetry(data: bytes) -> Telemetry:
    """Decode the data bytes of a type-69 packet; raises TelemetryError if too short."""
    try:
        return _decode(data)
    except struct.error as error:
        raise TelemetryError(
            f"telemetry of {len(data)} bytes is too short for its flags"
        ) from error


def _decode(data: bytes) -> Telemetry:
    flags, limit_flags, system_time = _HEAD.unpack_from(data, 0)
    offset = _HEAD.size
    gps = sensor = raw = magnetometer = None
    agl = fuel = None
    if flags & FLAG_GPS:
        gps = _decode_gps(data, offset)
        offset += _GPS.size
    if flags & FLAG_SENSOR:
        sensor = _decode_sensor(data, offset)
        offset += _SENSOR.size
    if flags & FLAG_RAW:
        raw = _decode_raw(data, offset)
        offset += _RAW.size
    if flags & FLAG_MAGNETOMETER:
        mx, my, mz, compass = _MAGNETOMETER.unpack_from(data, offset)
        offset += _MAGNETOMETER.size
        magnetometer = MagnetometerBlock(mx * 1e-4, my * 1e-4, mz * 1e-4, compass)
    if flags & FLAG_AGL:
        (agl_cm,) = _AGL.unpack_from(data, offset)
        offset += _AGL.size
        agl = agl_cm / 100
    count = flags & ACTUATOR_COUNT_MASK
    actuators = struct.unpack_from(f">{count}H", data, offset) if count else ()
    offset += 2 * count
    if flags & FLAG_FUEL:
        (fuel,) = _FUEL.unpack_from(data, offset)
        offset += _FUEL.size
    return Telemetry(
        system_time_ms=system_time,
        gps=gps,
        sensor=sensor,
        raw=raw,
        magnetometer=magnetometer,
        agl=agl,
        actuators=actuators,
        fuel=fuel,
        limit_flags=limit_flags,
        tail=bytes(data[offset:]),
    )


def _decode_gps(data: bytes, offset: int) -> GpsBlock:
    lat, lon, height, reserved, sats, vn, ve, vd, status, week, tow = _GPS.unpack_from(data, offset)
    return GpsBlock(
        lat=lat / MAS_PER_DEGREE,
        lon=lon / MAS_PER_DEGREE,
        alt=int.from_bytes(height, "big") / 100 - HEIGHT_OFFSET_M,
        vel_north=vn / 100,
        vel_east=ve / 100,
        vel_down=vd / 100,
        dop=(sats >> 10) * 0.2,
        sats_visible=(sats >> 5) & 0x1F,
        sats_tracked=sats & 0x1F,
        gps_status=status,
        gps_week=week,
        gps_time_of_week_ms=tow,
        reserved=reserved,
    )


def _decode_sensor(data: bytes, offset: int) -> SensorBlock:
    roll, pitch, yaw, baro, ws, ww, rpm_l, rpm_r, density, oat, ias, static = _SENSOR.unpack_from(
        data, offset
    )
    degrees = math.degrees  # a local: every telemetry packet decodes six angles
    return SensorBlock(
        roll=degrees(roll * 1e-4),
        pitch=degrees(pitch * 1e-4),
        yaw=degrees(yaw * 1e-4),
        indicated_airspeed=(ias - IAS_OFFSET) / 100,
        wind_south=ws / 100,
        wind_west=ww / 100,
        baro_altitude_raw=baro,
        rpm_left=rpm_l,
        rpm_right=rpm_r,
        density_ratio=density / 200,
        outside_air_temp=oat,
        static_pressure=static * 2.0,
    )


def _decode_raw(data: bytes, offset: int) -> RawBlock:
    p, q, r, ax, ay, az = _RAW.unpack_from(data, offset)
    degrees = math.degrees
    return RawBlock(
        p=degrees(p * 1e-4),
        q=degrees(q * 1e-4),
        r=degrees(r * 1e-4),
        accel_x=ax * ACCEL_PER_COUNT,
        accel_y=ay * ACCEL_PER_COUNT,
        accel_z=az * ACCEL_PER_COUNT,
    )


def encode_telemetry(message: Telemetry) -> bytes:
    """Encode a Telemetry to type-69 data bytes; raises TelemetryError if a value doesn't fit."""
    try:
        return _encode(message)
    except (struct.error, OverflowError) as error:
        raise TelemetryError(f"telemetry value out of range: {error}") from error


def _encode(message: Telemetry) -> bytes:
    if len(message.actuators) > ACTUATOR_COUNT_MASK:
        raise TelemetryError(f"{len(message.actuators)} actuators; at most {ACTUATOR_COUNT_MASK}")
    flags = len(message.actuators)
    parts: list[bytes] = []
    if message.gps is not None:
        flags |= FLAG_GPS
        parts.append(_encode_gps(message.gps))
    if message.sensor is not None:
        flags |= FLAG_SENSOR
        parts.append(_encode_sensor(message.sensor))
    if message.raw is not None:
        flags |= FLAG_RAW
        parts.append(_encode_raw(message.raw))
    if (mag := message.magnetometer) is not None:
        flags |= FLAG_MAGNETOMETER
        parts.append(
            _MAGNETOMETER.pack(
                round(mag.x * 1e4), round(mag.y * 1e4), round(mag.z * 1e4), mag.compass_heading_raw
            )
        )
    if message.agl is not None:
        flags |= FLAG_AGL
        parts.append(_AGL.pack(round(message.agl * 100)))
    if message.actuators:
        parts.append(struct.pack(f">{len(message.actuators)}H", *message.actuators))
    if message.fuel is not None:
        flags |= FLAG_FUEL
        parts.append(_FUEL.pack(message.fuel))
    parts.append(message.tail)
    return _HEAD.pack(flags, message.limit_flags, message.system_time_ms) + b"".join(parts)


def _encode_gps(gps: GpsBlock) -> bytes:
    height = round((gps.alt + HEIGHT_OFFSET_M) * 100)
    sats = (round(gps.dop / 0.2) << 10) | (gps.sats_visible << 5) | gps.sats_tracked
    return _GPS.pack(
        round(gps.lat * MAS_PER_DEGREE),
        round(gps.lon * MAS_PER_DEGREE),
        height.to_bytes(3, "big"),
        gps.reserved,
        sats,
        round(gps.vel_north * 100),
        round(gps.vel_east * 100),
        round(gps.vel_down * 100),
        gps.gps_status,
        gps.gps_week,
        gps.gps_time_of_week_ms,
    )


def _encode_sensor(sensor: SensorBlock) -> bytes:
    radians = math.radians  # `_angle_raw` inline: the simulator encodes 20 a second per UAV
    return _SENSOR.pack(
        round(radians(sensor.roll) * 1e4),
        round(radians(sensor.pitch) * 1e4),
        _heading_raw(sensor.yaw),
        sensor.baro_altitude_raw,
        round(sensor.wind_south * 100),
        round(sensor.wind_west * 100),
        sensor.rpm_left,
        sensor.rpm_right,
        round(sensor.density_ratio * 200),
        sensor.outside_air_temp,
        round(sensor.indicated_airspeed * 100) + IAS_OFFSET,
        round(sensor.static_pressure / 2),
    )


def _encode_raw(raw: RawBlock) -> bytes:
    radians = math.radians
    return _RAW.pack(
        round(radians(raw.p) * 1e4),
        round(radians(raw.q) * 1e4),
        round(radians(raw.r) * 1e4),
        round(raw.accel_x / ACCEL_PER_COUNT),
        round(raw.accel_y / ACCEL_PER_COUNT),
        round(raw.accel_z / ACCEL_PER_COUNT),
    )
