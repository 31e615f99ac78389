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
from fleet.piccolo.telemetry import Telemetry
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


class FleetMode(IntEnum):
    """HEARTBEAT.custom_mode: what the UAV is doing for the fleet, from its phase.

    The numbers are ArduPlane's for the nearest mode, so that MAVProxy and Mission
    Planner, which read a fixed-wing's custom mode as ArduPlane's, show a fitting name.
    """

    AUTO = 10  #: no fleet target: flying its autopilot's own flight plan
    RTL = 11  #: the mission was aborted (RTL asked for it): the autopilot's course resumed
    GUIDED = 15  #: on a fleet mission: planning, committed or flying to its target


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


def heartbeat(view: UavView) -> mavlink2.MAVLink_heartbeat_message:
    phase = phase_of(view)
    mode = mode_of(phase)
    # An aircraft in the air: armed, stabilised by its autopilot, in the fleet's modes.
    base = (
        mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
        | mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
    )
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


def sys_status(
    telemetry: Telemetry | None, errors_comm: int
) -> mavlink2.MAVLink_sys_status_message:
    """SYS_STATUS: the sensors the telemetry shows, no battery figures (not reported by a
    Piccolo's telemetry); `errors_comm` is the gateway's count of dropped input."""
    sensors = 0
    if telemetry is not None and telemetry.gps is not None:
        sensors |= mavlink2.MAV_SYS_STATUS_SENSOR_GPS
    if telemetry is not None and telemetry.sensor is not None:
        sensors |= (
            mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
            | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | mavlink2.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
        )
    return mavlink2.MAVLink_sys_status_message(
        sensors, sensors, sensors, 0, 65535, -1, -1, 0, min(errors_comm, 65535), 0, 0, 0, 0
    )


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
