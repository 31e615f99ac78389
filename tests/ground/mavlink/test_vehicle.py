"""A UAV's view as MAVLink messages: the mode and state follow its phase, the numbers
its telemetry, and commands are carried out or answered unsupported."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.phase import Phase, Severity
from fleet.piccolo.telemetry import GpsBlock, RawBlock, SensorBlock, Telemetry
from ground.fleet_view import UavView
from ground.mavlink import vehicle
from ground.mavlink.commands import Action, decide, is_rtl_mode
from ground.mavlink.vehicle import FleetMode

TELEMETRY = Telemetry(
    system_time_ms=1000,
    gps=GpsBlock(35.7012345, -120.7987654, 612.5, 20.0, -5.0, 1.5),
    sensor=SensorBlock(roll=10.0, pitch=-2.0, yaw=270.0, indicated_airspeed=21.0),
    raw=RawBlock(p=1.0, q=2.0, r=3.0, accel_x=0, accel_y=0, accel_z=-9.8),
)


@pytest.mark.parametrize(
    ("phase", "mode", "state"),
    [
        (Phase.IDLE, FleetMode.AUTO, mavlink2.MAV_STATE_ACTIVE),
        (Phase.COMPUTING, FleetMode.GUIDED, mavlink2.MAV_STATE_ACTIVE),
        (Phase.WAITING, FleetMode.GUIDED, mavlink2.MAV_STATE_ACTIVE),
        (Phase.COMMITTED, FleetMode.GUIDED, mavlink2.MAV_STATE_ACTIVE),
        (Phase.FLYING, FleetMode.GUIDED, mavlink2.MAV_STATE_ACTIVE),
        (Phase.REACHED, FleetMode.AUTO, mavlink2.MAV_STATE_ACTIVE),
        (Phase.PREEMPTED, FleetMode.AUTO, mavlink2.MAV_STATE_ACTIVE),
        (Phase.ABORTED, FleetMode.RTL, mavlink2.MAV_STATE_ACTIVE),
        (Phase.FAILED, FleetMode.AUTO, mavlink2.MAV_STATE_CRITICAL),
        (Phase.LINK_LOST, FleetMode.AUTO, mavlink2.MAV_STATE_CRITICAL),
        (Phase.OFF, FleetMode.AUTO, mavlink2.MAV_STATE_STANDBY),
    ],
)
def test_the_heartbeat_follows_the_phase(phase: Phase, mode: FleetMode, state: int) -> None:
    beat = vehicle.heartbeat(UavView(id=74, phase=str(phase)))
    assert (beat.type, beat.autopilot) == (
        mavlink2.MAV_TYPE_FIXED_WING,
        mavlink2.MAV_AUTOPILOT_GENERIC,
    )
    assert beat.custom_mode == mode
    assert beat.system_status == state
    assert beat.base_mode & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    guided = bool(beat.base_mode & mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED)
    assert guided == (mode == FleetMode.GUIDED)


def test_an_unknown_or_missing_phase_is_idle() -> None:
    assert vehicle.phase_of(UavView(id=1)) == Phase.IDLE
    assert vehicle.phase_of(UavView(id=1, phase="bogus")) == Phase.IDLE


def test_position_attitude_and_hud_carry_the_telemetry() -> None:
    position = vehicle.global_position(TELEMETRY, 1234)
    assert position is not None
    assert (position.lat, position.lon) == (357012345, -1207987654)
    assert position.alt == position.relative_alt == 612500
    assert (position.vx, position.vy, position.vz) == (2000, -500, 150)
    assert position.hdg == 27000
    attitude = vehicle.attitude(TELEMETRY, 1234)
    assert attitude is not None
    assert attitude.roll == pytest.approx(math.radians(10.0))
    assert attitude.yaw == pytest.approx(math.radians(-90.0))
    assert attitude.yawspeed == pytest.approx(math.radians(3.0))
    hud = vehicle.vfr_hud(UavView(id=1, airspeed=21.0, ground_speed=20.6, heading=270.0), TELEMETRY)
    assert hud is not None
    assert (hud.heading, hud.alt, hud.climb) == (270, 612.5, -1.5)


def test_no_gps_no_position_no_sensor_no_attitude() -> None:
    bare = Telemetry(system_time_ms=0)
    assert vehicle.global_position(bare, 0) is None
    assert vehicle.attitude(bare, 0) is None
    assert vehicle.vfr_hud(UavView(id=1), bare) is None
    assert vehicle.sys_status(UavView(id=1), None, 0).onboard_control_sensors_present == 0


def test_sys_status_counts_dropped_input() -> None:
    status = vehicle.sys_status(UavView(id=1), TELEMETRY, 70000)
    assert status.errors_comm == 65535
    assert status.onboard_control_sensors_present & mavlink2.MAV_SYS_STATUS_SENSOR_GPS


def test_autopilot_version_says_mission_int_and_names_the_uav() -> None:
    version = vehicle.autopilot_version(300)
    assert version.capabilities & mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert version.uid == 300


def test_status_text_keeps_its_severity_and_long_texts_come_in_chunks() -> None:
    (short,) = vehicle.status_texts("link lost", Severity.WARNING, 7)
    assert short.severity == mavlink2.MAV_SEVERITY_WARNING
    chunks = vehicle.status_texts("x" * 120, Severity.ERROR, 7)
    assert [c.chunk_seq for c in chunks] == [0, 1, 2]
    assert {c.id for c in chunks} == {7}
    assert all(c.severity == mavlink2.MAV_SEVERITY_ERROR for c in chunks)
    assert len(vehicle.status_texts("y" * 5000, Severity.INFO, 1)) == 10


def test_messages_pack_as_mavlink_2() -> None:
    sender = mavlink2.MAVLink(None, 74, 1)
    parser = mavlink2.MAVLink(None)
    for message in (
        vehicle.heartbeat(UavView(id=74)),
        vehicle.autopilot_version(74),
        vehicle.mission_current(1, 3, False),
        *vehicle.status_texts("hello", Severity.INFO, 1),
    ):
        data = message.pack(sender)
        assert data[0] == mavlink2.PROTOCOL_MARKER_V2
        (decoded,) = parser.parse_buffer(data) or []
        assert decoded.get_type() == message.get_type()
        assert decoded.get_srcSystem() == 74


@pytest.mark.parametrize(
    ("command", "params", "action"),
    [
        (mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, (0, 0, 0), Action.ABORT),
        (mavlink2.MAV_CMD_DO_SET_MODE, (1, int(FleetMode.RTL), 0), Action.ABORT),
        (mavlink2.MAV_CMD_DO_SET_MODE, (129, 4, 5), Action.ABORT),  # PX4's AUTO/RTL (MAVSDK)
        (mavlink2.MAV_CMD_DO_SET_MODE, (1, int(FleetMode.GUIDED), 0), Action.UNSUPPORTED),
        (mavlink2.MAV_CMD_DO_SET_MODE, (0, int(FleetMode.RTL), 0), Action.UNSUPPORTED),
        (mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, (0, 0, 0), Action.UNSUPPORTED),
        (mavlink2.MAV_CMD_NAV_TAKEOFF, (0, 0, 0), Action.UNSUPPORTED),
        (mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, (33, 1e5, 0), Action.UNSUPPORTED),
        (mavlink2.MAV_CMD_REQUEST_MESSAGE, (148, 0, 0), Action.SEND_MESSAGE),
        (mavlink2.MAV_CMD_REQUEST_MESSAGE, (242, 0, 0), Action.SEND_MESSAGE),  # home
        (mavlink2.MAV_CMD_REQUEST_MESSAGE, (147, 0, 0), Action.SEND_MESSAGE),  # battery
        (mavlink2.MAV_CMD_REQUEST_MESSAGE, (25, 0, 0), Action.SEND_MESSAGE),  # GPS_STATUS
        (mavlink2.MAV_CMD_REQUEST_MESSAGE, (241, 0, 0), Action.UNSUPPORTED),  # VIBRATION
        (mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, (1, 0, 0), Action.SEND_MESSAGE),
    ],
)
def test_commands(command: int, params: tuple[float, float, float], action: Action) -> None:
    assert decide(command, *params).action is action


def test_autopilot_capabilities_answer_with_autopilot_version() -> None:
    decision = decide(mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1, 0)
    assert decision.message_id == mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION


def test_set_mode_to_rtl() -> None:
    flag = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert is_rtl_mode(flag, FleetMode.RTL)
    assert not is_rtl_mode(flag, FleetMode.AUTO)


def test_values_no_field_can_hold_are_clamped_not_raised() -> None:
    hostile = Telemetry(
        system_time_ms=0,
        gps=GpsBlock(1e9, -1e12, 1e300, math.inf, -math.inf, math.nan),
        sensor=SensorBlock(roll=0.0, pitch=0.0, yaw=math.nan, indicated_airspeed=1.0),
    )
    position = vehicle.global_position(hostile, 0)
    assert position is not None
    assert (position.lat, position.lon) == (2**31 - 1, -(2**31))
    assert (position.vx, position.vy, position.vz) == (0, 0, 0)
    assert position.hdg == 0
    sender = mavlink2.MAVLink(None, 1, 1)
    position.pack(sender)
    view = UavView(id=1, heading=359.7, airspeed=math.nan)
    hud = vehicle.vfr_hud(view, TELEMETRY)
    assert hud is not None and hud.heading == 0


# ---- what QGroundControl and MAVSDK read at connect --------------------------------------
LIVE = UavView(id=74, telemetry_age_s=0.2, phase="idle")


def test_health_reflects_the_link_and_the_gps_fix() -> None:
    status = vehicle.sys_status(LIVE, TELEMETRY, 0)
    gps = mavlink2.MAV_SYS_STATUS_SENSOR_GPS
    gyro = mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    assert status.onboard_control_sensors_health & (gps | gyro) == gps | gyro
    assert status.onboard_control_sensors_health & mavlink2.MAV_SYS_STATUS_GEOFENCE  # no breach
    assert not status.onboard_control_sensors_present & mavlink2.MAV_SYS_STATUS_GEOFENCE
    for down in (
        UavView(id=74, telemetry_age_s=10.0, phase="idle"),  # stale telemetry
        UavView(id=74, telemetry_age_s=0.2, phase="link_lost"),
    ):
        stale = vehicle.sys_status(down, TELEMETRY, 0)
        assert stale.onboard_control_sensors_present & (gps | gyro) == gps | gyro
        assert not stale.onboard_control_sensors_health & (gps | gyro)
    no_fix = Telemetry(
        system_time_ms=0, gps=GpsBlock(35.7, -120.8, 600.0, 0, 0, 0, gps_status=0), sensor=None
    )
    assert not vehicle.sys_status(LIVE, no_fix, 0).onboard_control_sensors_health & gps


def test_armed_only_while_the_telemetry_shows_it_flying() -> None:
    armed = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    assert vehicle.heartbeat(LIVE, TELEMETRY).base_mode & armed
    assert not vehicle.heartbeat(LIVE, None).base_mode & armed
    parked = Telemetry(
        system_time_ms=0, sensor=SensorBlock(roll=0, pitch=0, yaw=0, indicated_airspeed=0.0)
    )
    assert not vehicle.heartbeat(LIVE, parked).base_mode & armed
    assert vehicle.extended_sys_state(TELEMETRY).landed_state == mavlink2.MAV_LANDED_STATE_IN_AIR
    assert vehicle.extended_sys_state(parked).landed_state == mavlink2.MAV_LANDED_STATE_ON_GROUND
    assert vehicle.extended_sys_state(None).landed_state == mavlink2.MAV_LANDED_STATE_UNDEFINED


def test_gps_raw_carries_the_satellites_and_the_fix() -> None:
    telemetry = Telemetry(
        system_time_ms=0, gps=GpsBlock(35.7, -120.8, 600.0, 3.0, 4.0, 0.0, 1.2, 9, 8)
    )
    raw = vehicle.gps_raw(telemetry, 1000)
    assert raw is not None
    assert (raw.satellites_visible, raw.fix_type) == (9, mavlink2.GPS_FIX_TYPE_3D_FIX)
    assert (raw.lat, raw.vel, raw.eph) == (357000000, 500, 120)


def test_gps_status_carries_gps_raws_satellite_count_and_names_none() -> None:
    telemetry = Telemetry(
        system_time_ms=0, gps=GpsBlock(35.7, -120.8, 600.0, 3.0, 4.0, 0.0, 1.2, 9, 8)
    )
    status = vehicle.gps_status(telemetry)
    raw = vehicle.gps_raw(telemetry, 0)
    assert status is not None and raw is not None
    assert status.satellites_visible == raw.satellites_visible == 9
    for per_satellite in ("prn", "used", "elevation", "azimuth", "snr"):
        assert list(getattr(status, f"satellite_{per_satellite}")) == [0] * 20
    assert vehicle.gps_status(Telemetry(system_time_ms=0)) is None  # no GPS block
    packed = status.pack(mavlink2.MAVLink(None, 74, 1))
    (decoded,) = mavlink2.MAVLink(None).parse_buffer(bytes(packed)) or []
    assert decoded.satellites_visible == 9


def test_the_battery_is_every_field_mavlink_marks_not_measured() -> None:
    packed = vehicle.battery_status().pack(mavlink2.MAVLink(None, 74, 1))
    (battery,) = mavlink2.MAVLink(None).parse_buffer(bytes(packed)) or []
    assert list(battery.voltages) == [2**16 - 1] * 10  # UINT16_MAX: not measured
    assert (battery.current_battery, battery.current_consumed, battery.energy_consumed) == (
        -1,
        -1,
        -1,
    )
    assert battery.battery_remaining == -1  # "autopilot does not estimate"
    assert battery.temperature == 2**15 - 1  # INT16_MAX: unknown
    assert (battery.time_remaining, battery.charge_state, battery.fault_bitmask) == (
        0,
        mavlink2.MAV_BATTERY_CHARGE_STATE_UNDEFINED,
        0,
    )
    assert list(battery.voltages_ext) == [0] * 4  # "not supported"
    # SYS_STATUS says the same: no battery sensor, its figures unknown.
    status = vehicle.sys_status(LIVE, TELEMETRY, 0)
    assert not status.onboard_control_sensors_present & mavlink2.MAV_SYS_STATUS_SENSOR_BATTERY
    assert (status.voltage_battery, status.current_battery, status.battery_remaining) == (
        2**16 - 1,
        -1,
        -1,
    )


def test_modes_are_in_px4s_encoding_and_mavproxys_rtl_still_aborts() -> None:
    assert FleetMode.GUIDED == 6 << 16  # OFFBOARD
    assert FleetMode.RTL == (4 << 16) | (5 << 24)  # AUTO/RTL
    flag = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert is_rtl_mode(flag, vehicle.ARDUPLANE_RTL)  # `mode RTL` in MAVProxy
