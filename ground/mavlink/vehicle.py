"""A UAV as the ground sees it, as the MAVLink messages a ground station expects.

Pure: each function turns the ground's view of one UAV (`UavView`, the latest
`Telemetry`) into pymavlink messages; the gateway sends them from the UAV's system id,
component 1. The mode is the fleet's phase, never a request: a ground station shows
GUIDED while the UAV is on a fleet target, RTL once it confirmed an abort (its own
course resumed), AUTO otherwise (docs/mavlink.md has the table).
"""

from __future__ import annotations

import math
from enum import IntEnum

from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.phase import Phase, Severity
from fleet.piccolo.telemetry import GPS_3D_FIX, GpsBlock, Telemetry
from ground.fleet_view import UavView

#: The length of STATUSTEXT's text field; longer texts go in chunks (MAVLink 2 `id`).
STATUSTEXT_CHARS = 50
#: The firmware version AUTOPILOT_VERSION reports: this gateway's (0.1.0, "official").
FLIGHT_SW_VERSION = (0 << 24) | (1 << 16) | (0 << 8) | 255
#: What AUTOPILOT_VERSION says a vehicle can do: MISSION_INT is all the mission protocol
#: it speaks; COMMAND_INT and MAVLink 2 too.
CAPABILITIES = (
    mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
)


_ZEROS = (0,) * 8


def px4_mode(main: int, sub: int = 0) -> int:
    """A custom mode in PX4's encoding (main mode in byte 2, sub mode in byte 3): what
    MAVSDK decodes for an autopilot that is neither PX4 nor ArduPilot."""
    return (main << 16) | (sub << 24)


class FleetMode(IntEnum):
    """HEARTBEAT.custom_mode: what the UAV is doing for the fleet, from its phase.

    In PX4's encoding, which MAVSDK maps for a generic autopilot (its Telemetry's flight
    mode: OFFBOARD, MISSION, RETURN_TO_LAUNCH, never UNKNOWN); QGroundControl names a
    generic autopilot's mode from the base mode's flags; MAVProxy and Mission Planner,
    which read a fixed-wing's custom mode as ArduPlane's, show the number.
    """

    #: No fleet target: flying its autopilot's own flight plan (PX4 AUTO/MISSION)
    AUTO = px4_mode(4, 4)
    #: The mission was aborted (RTL asked for it): the autopilot's course resumed
    #: (PX4 AUTO/RTL)
    RTL = px4_mode(4, 5)
    #: On a fleet mission: the onboard planning module steers the autopilot from outside
    #: its own plan (PX4 OFFBOARD)
    GUIDED = px4_mode(6)


#: ArduPlane's RTL custom mode: what MAVProxy's `mode RTL` sends a fixed-wing.
ARDUPLANE_RTL = 11
#: Telemetry older than this (s) is a link that is down: its sensors are not vouched for.
LINK_STALE_S = 3.0
#: An indicated airspeed at or above this (m/s) is an aircraft in the air.
FLYING_AIRSPEED = 10.0


_MISSION_PHASES = frozenset({Phase.COMPUTING, Phase.WAITING, Phase.COMMITTED, Phase.FLYING})
_CRITICAL_PHASES = frozenset({Phase.FAILED, Phase.LINK_LOST})


def phase_of(view: UavView) -> Phase:
    """The UAV's phase as it reported it; IDLE before it said."""
    try:
        return Phase(view.phase) if view.phase is not None else Phase.IDLE
    except ValueError:
        return Phase.IDLE


def mode_of(phase: Phase) -> FleetMode:
    if phase in _MISSION_PHASES:
        return FleetMode.GUIDED
    if phase == Phase.ABORTED:
        return FleetMode.RTL
    return FleetMode.AUTO


def state_of(phase: Phase) -> int:
    """HEARTBEAT.system_status."""
    if phase in _CRITICAL_PHASES:
        return int(mavlink2.MAV_STATE_CRITICAL)
    if phase == Phase.OFF:
        return int(mavlink2.MAV_STATE_STANDBY)
    return int(mavlink2.MAV_STATE_ACTIVE)


def link_up(view: UavView) -> bool:
    """Whether the UAV's telemetry is fresh and its autopilot link not reported lost."""
    fresh = view.telemetry_age_s is not None and view.telemetry_age_s < LINK_STALE_S
    return fresh and phase_of(view) != Phase.LINK_LOST


def in_air(telemetry: Telemetry | None) -> bool | None:
    """Whether the telemetry shows the aircraft flying (its airspeed); None unknown."""
    if telemetry is None or telemetry.sensor is None:
        return None
    return telemetry.sensor.indicated_airspeed >= FLYING_AIRSPEED


def heartbeat(
    view: UavView, telemetry: Telemetry | None = None
) -> mavlink2.MAVLink_heartbeat_message:
    phase = phase_of(view)
    mode = mode_of(phase)
    # Armed only while its telemetry shows it flying: the Piccolo link says nothing of
    # arming, and a station must not be told "ARMED" of an aircraft nobody has seen fly.
    base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
    if in_air(telemetry):
        base |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    if mode == FleetMode.GUIDED:
        base |= mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
    else:
        base |= mavlink2.MAV_MODE_FLAG_AUTO_ENABLED
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_FIXED_WING,
        mavlink2.MAV_AUTOPILOT_GENERIC,
        base,
        int(mode),
        state_of(phase),
        3,
    )


def _clamped(value: float, low: int, high: int) -> int:
    """`value` rounded into a field's range; 0 if it is no number. What the bus carries
    is checked by type, not by range: a hostile value must not stop the streams."""
    if not math.isfinite(value):
        return 0
    return max(low, min(high, round(value)))


def _deg_e7(degrees: float) -> int:
    return _clamped(degrees * 1e7, -(2**31), 2**31 - 1)


def _mm(metres: float) -> int:
    return _clamped(metres * 1000, -(2**31), 2**31 - 1)


def global_position(
    telemetry: Telemetry, boot_ms: int
) -> mavlink2.MAVLink_global_position_int_message | None:
    """GLOBAL_POSITION_INT; None without a GPS block. The fleet has no home: relative
    altitude is above 0 m, the same as the altitude."""
    gps = telemetry.gps
    if gps is None:
        return None
    heading = telemetry.sensor.yaw if telemetry.sensor is not None else None
    if heading is None and (gps.vel_north or gps.vel_east):
        heading = math.degrees(math.atan2(gps.vel_east, gps.vel_north))
    hdg = 65535 if heading is None else _clamped((heading % 360) * 100, 0, 35999)
    return mavlink2.MAVLink_global_position_int_message(
        boot_ms & 0xFFFFFFFF,
        _deg_e7(gps.lat),
        _deg_e7(gps.lon),
        _mm(gps.alt),
        _mm(gps.alt),
        _cm_s(gps.vel_north),
        _cm_s(gps.vel_east),
        _cm_s(gps.vel_down),
        hdg,
    )


def _cm_s(metres_s: float) -> int:
    return _clamped(metres_s * 100, -32768, 32767)


def attitude(telemetry: Telemetry, boot_ms: int) -> mavlink2.MAVLink_attitude_message | None:
    """ATTITUDE; None without a sensor block. Rates from the inertial block, 0 without."""
    sensor = telemetry.sensor
    if sensor is None:
        return None
    raw = telemetry.raw
    rates = (raw.p, raw.q, raw.r) if raw is not None else (0.0, 0.0, 0.0)
    yaw = math.radians((sensor.yaw + 180.0) % 360.0 - 180.0)
    return mavlink2.MAVLink_attitude_message(
        boot_ms & 0xFFFFFFFF,
        math.radians(sensor.roll),
        math.radians(sensor.pitch),
        yaw,
        *(math.radians(rate) for rate in rates),
    )


def vfr_hud(view: UavView, telemetry: Telemetry) -> mavlink2.MAVLink_vfr_hud_message | None:
    """VFR_HUD; None without a GPS block. Throttle is not in the telemetry: 0."""
    gps = telemetry.gps
    if gps is None:
        return None
    return mavlink2.MAVLink_vfr_hud_message(
        view.airspeed or 0.0,
        view.ground_speed or 0.0,
        _clamped(view.heading or 0.0, 0, 360) % 360,
        0,
        gps.alt,
        -gps.vel_down,
    )


#: What an autopilot flying the aircraft controls: present and enabled always; healthy
#: only while the link shows it doing so.
_CONTROL = (
    mavlink2.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink2.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink2.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mavlink2.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
)
_INERTIAL = (
    mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink2.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
)


def gps_fix(telemetry: Telemetry | None) -> int:
    """GPS_FIX_TYPE of the telemetry's GPS block (3D only when the Piccolo says so)."""
    if telemetry is None or telemetry.gps is None:
        return int(mavlink2.GPS_FIX_TYPE_NO_GPS)
    if telemetry.gps.gps_status & GPS_3D_FIX == GPS_3D_FIX:
        return int(mavlink2.GPS_FIX_TYPE_3D_FIX)
    return int(mavlink2.GPS_FIX_TYPE_NO_FIX)


def sys_status(
    view: UavView, telemetry: Telemetry | None, errors_comm: int
) -> mavlink2.MAVLink_sys_status_message:
    """SYS_STATUS: the sensors the telemetry shows, healthy only while the link is up
    (fresh telemetry, its autopilot link not lost) and, for the GPS, with a 3D fix; no
    battery figures (not reported by a Piccolo's telemetry); `errors_comm` is the
    gateway's count of dropped input. The geofence bit is healthy, not present: there
    is no breach to report (MAVProxy says "fence breach" when it is clear)."""
    present = _CONTROL if telemetry is not None else 0
    if telemetry is not None and telemetry.gps is not None:
        present |= mavlink2.MAV_SYS_STATUS_SENSOR_GPS
    if telemetry is not None and telemetry.sensor is not None:
        present |= _INERTIAL
    if telemetry is not None and telemetry.magnetometer is not None:
        present |= mavlink2.MAV_SYS_STATUS_SENSOR_3D_MAG
    health = mavlink2.MAV_SYS_STATUS_GEOFENCE
    if link_up(view):
        health |= present
        if gps_fix(telemetry) < mavlink2.GPS_FIX_TYPE_3D_FIX:
            health &= ~mavlink2.MAV_SYS_STATUS_SENSOR_GPS
    return mavlink2.MAVLink_sys_status_message(
        present, present, health, 0, 65535, -1, -1, 0, min(errors_comm, 65535), 0, 0, 0, 0
    )


def gps_raw(telemetry: Telemetry, boot_ms: int) -> mavlink2.MAVLink_gps_raw_int_message | None:
    """GPS_RAW_INT: the GPS block as the receiver gave it, satellites included."""
    gps = telemetry.gps
    if gps is None:
        return None
    speed = math.hypot(gps.vel_north, gps.vel_east)
    course = math.degrees(math.atan2(gps.vel_east, gps.vel_north)) % 360.0
    return mavlink2.MAVLink_gps_raw_int_message(
        boot_ms * 1000,
        gps_fix(telemetry),
        _deg_e7(gps.lat),
        _deg_e7(gps.lon),
        _mm(gps.alt),
        _clamped(gps.dop * 100, 0, 65534) if gps.dop > 0 else 65535,
        65535,
        _clamped(speed * 100, 0, 65534),
        _clamped(course * 100, 0, 35999) if speed > 0.5 else 65535,
        satellites(gps),
        _mm(gps.alt),  # the Piccolo's altitude is above the ellipsoid
    )


def satellites(gps: GpsBlock) -> int:
    """The satellites the receiver sees, as GPS_RAW_INT and GPS_STATUS say it (255 is
    GPS_RAW_INT's "unknown", never said)."""
    return _clamped(max(gps.sats_visible, gps.sats_tracked), 0, 254)


#: GPS_STATUS holds up to 20 satellites one by one.
_GPS_STATUS_SLOTS = 20


def gps_status(telemetry: Telemetry) -> mavlink2.MAVLink_gps_status_message | None:
    """GPS_STATUS: the receiver's count of satellites, the one GPS_RAW_INT carries; None
    without a GPS block. The Piccolo's GPS block names no satellite, so the per-satellite
    arrays are empty (0 in every slot: no satellite), not made up."""
    if telemetry.gps is None:
        return None
    empty = [0] * _GPS_STATUS_SLOTS
    return mavlink2.MAVLink_gps_status_message(
        satellites(telemetry.gps), empty, empty, empty, empty, empty
    )


#: MAVLink's "not measured" in BATTERY_STATUS's fields.
_UNKNOWN_TEMPERATURE = 2**15 - 1  # INT16_MAX
_NO_CELL = 2**16 - 1  # UINT16_MAX: a cell (or the whole battery's voltage) not measured
_NOT_MEASURED = -1  # current, consumption, energy, remaining: "does not measure/estimate"


def battery_status() -> mavlink2.MAVLink_battery_status_message:
    """BATTERY_STATUS with every figure "not measured", as the MAVLink spec marks each:
    neither the Piccolo's telemetry nor the simulated aircraft has a battery reading, so
    a station shows the battery as unknown rather than a voltage or charge nobody read
    (SYS_STATUS's battery fields say the same, and its battery sensor bit is not set)."""
    return mavlink2.MAVLink_battery_status_message(
        0,
        mavlink2.MAV_BATTERY_FUNCTION_UNKNOWN,
        mavlink2.MAV_BATTERY_TYPE_UNKNOWN,
        _UNKNOWN_TEMPERATURE,
        [_NO_CELL] * 10,
        _NOT_MEASURED,
        _NOT_MEASURED,
        _NOT_MEASURED,
        _NOT_MEASURED,
        0,  # time remaining: 0 is "not provided"
        mavlink2.MAV_BATTERY_CHARGE_STATE_UNDEFINED,
        [0] * 4,  # cells 11-14: 0 is "not supported"
        mavlink2.MAV_BATTERY_MODE_UNKNOWN,
        0,
    )


def home_position(lat: float, lon: float) -> mavlink2.MAVLink_home_position_message:
    """HOME_POSITION: where the gateway first heard the UAV, at 0 m, which is what the
    relative altitudes (GLOBAL_POSITION_INT, missions) are measured from: the Piccolo
    link carries no home of its own."""
    return mavlink2.MAVLink_home_position_message(
        _deg_e7(lat), _deg_e7(lon), 0, 0.0, 0.0, 0.0, (1.0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0
    )


def extended_sys_state(telemetry: Telemetry | None) -> mavlink2.MAVLink_extended_sys_state_message:
    """EXTENDED_SYS_STATE: a fixed-wing (no VTOL state), in the air by its airspeed."""
    flying = in_air(telemetry)
    landed = (
        mavlink2.MAV_LANDED_STATE_UNDEFINED
        if flying is None
        else mavlink2.MAV_LANDED_STATE_IN_AIR
        if flying
        else mavlink2.MAV_LANDED_STATE_ON_GROUND
    )
    return mavlink2.MAVLink_extended_sys_state_message(mavlink2.MAV_VTOL_STATE_UNDEFINED, landed)


def autopilot_version(piccolo: int) -> mavlink2.MAVLink_autopilot_version_message:
    """AUTOPILOT_VERSION: the MISSION_INT capability; `uid` is the Piccolo ID, so a client
    can tell which UAV a system id is (MAVSDK's Info.identification.legacy_uid)."""
    return mavlink2.MAVLink_autopilot_version_message(
        CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, _ZEROS, _ZEROS, _ZEROS, 0, 0, piccolo
    )


_SEVERITY = {
    Severity.INFO: mavlink2.MAV_SEVERITY_INFO,
    Severity.WARNING: mavlink2.MAV_SEVERITY_WARNING,
    Severity.ERROR: mavlink2.MAV_SEVERITY_ERROR,
}


def status_texts(
    text: str, severity: Severity, chunk_id: int
) -> list[mavlink2.MAVLink_statustext_message]:
    """STATUSTEXT: `text` in one message, or in chunks sharing `chunk_id` (1-65535) when
    longer than the field (MAVLink 2); text beyond 10 chunks is cut."""
    data = text.encode("utf-8", "replace")[: STATUSTEXT_CHARS * 10]
    level = _SEVERITY[severity]
    if len(data) <= STATUSTEXT_CHARS:
        return [mavlink2.MAVLink_statustext_message(level, data, 0, 0)]
    chunks = [data[i : i + STATUSTEXT_CHARS] for i in range(0, len(data), STATUSTEXT_CHARS)]
    return [
        mavlink2.MAVLink_statustext_message(level, chunk, chunk_id, seq)
        for seq, chunk in enumerate(chunks)
    ]


def mission_current(
    seq: int, total: int, finished: bool
) -> mavlink2.MAVLink_mission_current_message:
    """MISSION_CURRENT: the item the UAV is flying to (its target's index)."""
    state = mavlink2.MISSION_STATE_COMPLETE if finished else mavlink2.MISSION_STATE_ACTIVE
    return mavlink2.MAVLink_mission_current_message(seq, total, state, 0)
