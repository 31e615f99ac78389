"""`fleet mavlink` as QGroundControl, MAVSDK and MAVProxy meet it at connect, and as an
attacker on its port meets it: real `fleet up` with two simulated UAVs, the gateway as
its own process, and pymavlink, MAVSDK or MAVProxy on the other side.

QGroundControl's connect sequence is replayed with pymavlink (HEARTBEAT as a GCS,
AUTOPILOT_VERSION by MAV_CMD_REQUEST_MESSAGE, every parameter, TIMESYNC, HOME_POSITION,
GPS_STATUS and BATTERY_STATUS asked for, the mission, fence and rally downloads). The
attacks are the ones the gateway obeyed before: a byte answered with the fleet's
streams (reflection), one-byte datagrams or idle TCP connections locking honest stations
out, unsigned or wrongly signed commands obeyed, a second station taking over or
joining an upload.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from ground.mavlink.signing import passphrase_secret, timestamp_now
from tests.ground.mavlink.mavlink_fleet import (
    FleetUp,
    mavsdk_systems,
    running_fleet,
    said,
    served_port,
    stop,
)
from tests.ground.mavlink.stations import WAIT_S, receiver
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

UAVS = (101, 102)
PASSPHRASE = "correct horse battery staple"


@pytest.fixture(scope="module")
def fleet_up(tmp_path_factory: pytest.TempPathFactory) -> Iterator[FleetUp]:
    with running_fleet(len(UAVS), tmp_path_factory.mktemp("mavlink-stations")) as running:
        yield running


def exit_drops(lines: list[str]) -> str:
    found = [line for line in lines if "dropped" in line and "MAVLink input" in line]
    return found[0] if found else ""


class Station:
    """A pymavlink ground station on UDP (system 255, component 190), signing if given
    a secret."""

    def __init__(self, port: int, secret: bytes | None = None, component: int = 190) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect(("127.0.0.1", port))
        self.sock.settimeout(0.2)
        self.mav = mavlink2.MAVLink(None, 255, component)
        parser = mavlink2.MAVLink(None)
        if secret is not None:
            for side in (self.mav, parser):
                side.signing.secret_key = secret
                side.signing.timestamp = timestamp_now()
            self.mav.signing.sign_outgoing = True
        self.parser = parser
        self.heard = receiver(self.sock, parser)

    def send(self, message: mavlink2.MAVLink_message) -> None:
        self.sock.send(bytes(message.pack(self.mav)))
        self.mav.seq = (self.mav.seq + 1) % 256

    def heartbeat(self) -> None:
        self.send(
            mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3
            )
        )

    def expect(self, kind: str, sysid: int, test: Callable[[Any], bool] = lambda m: True) -> Any:
        return self.heard(lambda m: m.get_type() == kind and m.get_srcSystem() == sysid and test(m))

    def nothing_waiting(self) -> bool:
        self.sock.setblocking(False)
        try:
            self.sock.recv(65535)
        except BlockingIOError:
            return True
        finally:
            self.sock.settimeout(0.2)
        return False

    def close(self) -> None:
        self.sock.close()


def request_message(sysid: int, message_id: int) -> mavlink2.MAVLink_command_long_message:
    return mavlink2.MAVLink_command_long_message(
        sysid, 1, mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, message_id, 0, 0, 0, 0, 0, 0
    )


# ---- QGroundControl's connect sequence ---------------------------------------------------------
def test_qgroundcontrols_connect_sequence_is_answered(fleet_up: FleetUp) -> None:
    gateway = fleet_up.gateway("udpin:127.0.0.1:0")
    port = served_port(gateway)
    qgc = Station(port)
    uav = UAVS[0]
    try:
        qgc.heartbeat()
        beat = qgc.expect("HEARTBEAT", uav)
        assert beat.autopilot == mavlink2.MAV_AUTOPILOT_GENERIC
        # AUTOPILOT_VERSION, as QGC asks it first.
        qgc.send(request_message(uav, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION))
        assert qgc.expect("COMMAND_ACK", uav).result == mavlink2.MAV_RESULT_ACCEPTED
        assert qgc.expect("AUTOPILOT_VERSION", uav).uid == uav
        # Every parameter, until QGC has them all.
        qgc.send(mavlink2.MAVLink_param_request_list_message(uav, 1))
        params: dict[int, Any] = {}
        while not params or len(params) < next(iter(params.values())).param_count:
            value = qgc.expect("PARAM_VALUE", uav)
            params[value.param_index] = value
        named = {p.param_id: p.param_value for p in params.values()}
        assert named == {
            "FLT_PICCOLO_ID": uav,
            "FLT_AIRSPD_MIN": 15.0,
            "FLT_AIRSPD_MAX": 30.0,
            "FLT_BANK_LIM": 30.0,
            "FLT_ACCEPT_RAD": 75.0,
        }
        qgc.send(
            mavlink2.MAVLink_param_set_message(
                uav, 1, b"FLT_BANK_LIM", 45.0, mavlink2.MAV_PARAM_TYPE_REAL32
            )
        )
        assert qgc.expect("PARAM_VALUE", uav).param_value == 30.0  # read-only: unchanged
        # TIMESYNC.
        qgc.send(mavlink2.MAVLink_timesync_message(0, 42))
        assert qgc.expect("TIMESYNC", uav, lambda m: m.ts1 == 42).tc1 > 0
        # The mission, the fence and the rally points (none of the last two).
        for kind in (
            mavlink2.MAV_MISSION_TYPE_MISSION,
            mavlink2.MAV_MISSION_TYPE_FENCE,
            mavlink2.MAV_MISSION_TYPE_RALLY,
        ):
            qgc.send(mavlink2.MAVLink_mission_request_list_message(uav, 1, kind))
            count = qgc.expect("MISSION_COUNT", uav, lambda m: m.mission_type == kind)  # noqa: B023
            assert count.count == 0
        # Home, the landed state, the GPS with its satellites, health.
        # Home not known yet (no telemetry heard) is TEMPORARILY_REJECTED: asked again, as
        # QGroundControl does, until it is answered (bounded).
        for _ in range(30):
            qgc.send(mavlink2.MAVLink_command_long_message(
                uav, 1, mavlink2.MAV_CMD_GET_HOME_POSITION, 0, 0, 0, 0, 0, 0, 0, 0))  # fmt: skip
            result = qgc.expect("COMMAND_ACK", uav).result
            if result != mavlink2.MAV_RESULT_TEMPORARILY_REJECTED:
                break
            time.sleep(0.5)
        assert result == mavlink2.MAV_RESULT_ACCEPTED
        home = qgc.expect("HOME_POSITION", uav)
        assert home.latitude != 0 and home.altitude == 0
        state = qgc.expect("EXTENDED_SYS_STATE", uav)
        assert state.landed_state == mavlink2.MAV_LANDED_STATE_IN_AIR
        gps = qgc.expect("GPS_RAW_INT", uav)
        assert gps.satellites_visible == 12 and gps.fix_type == mavlink2.GPS_FIX_TYPE_3D_FIX
        # GPS_STATUS and the battery, asked for: the same satellites; a battery unknown
        # (no reading exists), never a made-up voltage or charge.
        qgc.send(request_message(uav, mavlink2.MAVLINK_MSG_ID_GPS_STATUS))
        assert qgc.expect("COMMAND_ACK", uav).result == mavlink2.MAV_RESULT_ACCEPTED
        assert qgc.expect("GPS_STATUS", uav).satellites_visible == 12
        qgc.send(request_message(uav, mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS))
        assert qgc.expect("COMMAND_ACK", uav).result == mavlink2.MAV_RESULT_ACCEPTED
        battery = qgc.expect("BATTERY_STATUS", uav)
        assert battery.battery_remaining == -1 and battery.current_battery == -1
        assert list(battery.voltages) == [2**16 - 1] * 10
        status = qgc.expect("SYS_STATUS", uav)
        ok = mavlink2.MAV_SYS_STATUS_SENSOR_GPS | mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
        assert status.onboard_control_sensors_health & ok == ok
        assert status.onboard_control_sensors_health & mavlink2.MAV_SYS_STATUS_GEOFENCE
        # Armed, as an aircraft its telemetry shows flying is.
        assert qgc.expect("HEARTBEAT", uav).base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    finally:
        qgc.close()
        stop(gateway)


def test_mavsdk_sees_health_a_home_and_a_flight_mode(fleet_up: FleetUp) -> None:
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    gateway = fleet_up.gateway("udpin:127.0.0.1:0")
    port = served_port(gateway)
    try:
        with mavsdk_systems(port, len(UAVS)) as systems:
            system = systems[UAVS[1]]
            telemetry = Telemetry(system)

            def healthy() -> bool:
                health = telemetry.health()
                return bool(
                    health.is_gyrometer_calibration_ok
                    and health.is_accelerometer_calibration_ok
                    and health.is_global_position_ok
                    and health.is_home_position_ok
                )

            wait_until(healthy, WAIT_S, "MAVSDK's health checks")
            wait_until(
                lambda: telemetry.flight_mode() != FlightMode.UNKNOWN, WAIT_S, "a flight mode"
            )
            assert telemetry.flight_mode() == FlightMode.MISSION  # its own flight plan
            wait_until(lambda: telemetry.gps_info().num_satellites == 12, WAIT_S, "12 satellites")
            assert telemetry.armed()
    finally:
        stop(gateway)


def test_mavproxy_reports_no_fence_breach(fleet_up: FleetUp) -> None:
    with fleet_up.mavproxy_gateway() as (proxy, _):
        # It loads the parameters once it has heard a vehicle's heartbeat, and each
        # heartbeat comes with a SYS_STATUS, which its fence module reads: by then it has.
        proxy.wait_for_line(lambda line: said(line).startswith("Received 5 parameters"), WAIT_S)
        assert not [line for line in proxy.history if "fence" in line.lower()], proxy.history


# ---- attacks on the port --------------------------------------------------------------------
def test_one_byte_is_never_answered_and_strangers_cannot_lock_stations_out(
    fleet_up: FleetUp,
) -> None:
    gateway = fleet_up.gateway("udpin:127.0.0.1:0")
    port = served_port(gateway)
    strangers = [Station(port) for _ in range(8)]
    honest = Station(port)
    try:
        for stranger in strangers:
            stranger.sock.send(b"\x00")
        honest.heartbeat()
        for uav in UAVS:  # streamed to the honest station: at least a second of it
            honest.expect("HEARTBEAT", uav)
        honest.expect("HEARTBEAT", UAVS[0])
        assert all(stranger.nothing_waiting() for stranger in strangers)  # no reflection
    finally:
        for station in (*strangers, honest):
            station.close()
        lines = stop(gateway)
    assert "'bad_prefix': 8" in exit_drops(lines), lines[-3:]  # dropped, never answered


def test_idle_tcp_connections_cannot_lock_stations_out(fleet_up: FleetUp) -> None:
    gateway = fleet_up.gateway("tcpin:127.0.0.1:0")
    port = served_port(gateway)
    idle = [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(8)]
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=10) as honest:
            honest.settimeout(0.2)
            mav = mavlink2.MAVLink(None, 255, 190)
            honest.sendall(bytes(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(mav)))
            heard = receiver(honest, mavlink2.MAVLink(None))
            seen = heard(lambda m: m.get_type() == "HEARTBEAT")
            assert seen.get_srcSystem() in UAVS
    finally:
        for sock in idle:
            sock.close()
        stop(gateway)


def test_only_signed_stations_command_and_upload(fleet_up: FleetUp) -> None:
    keys = fleet_up.tmp / "stations.keys"
    keys.write_text(f"operator {PASSPHRASE}\n")
    keys.chmod(0o600)
    gateway = fleet_up.gateway("udpin:127.0.0.1:0", "--signing-key", str(keys))
    port = served_port(gateway)
    operator = Station(port, passphrase_secret(PASSPHRASE))
    unsigned = Station(port, component=191)
    forger = Station(port, passphrase_secret("a guess"), component=192)
    uav = UAVS[1]
    try:
        for attacker in (unsigned, forger):
            attacker.heartbeat()
            attacker.send(mavlink2.MAVLink_command_long_message(
                uav, 1, mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0, 0, 0, 0, 0))  # fmt: skip
            attacker.send(mavlink2.MAVLink_mission_count_message(uav, 1, 1, 0))
        operator.heartbeat()
        beat = operator.expect("HEARTBEAT", uav)
        assert beat.get_signed()  # pymavlink checked the gateway's signature with our secret
        operator.send(request_message(uav, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION))
        assert operator.expect("AUTOPILOT_VERSION", uav).uid == uav
        assert unsigned.nothing_waiting() and forger.nothing_waiting()
        phase = next(v for v in fleet_up.ground_cli("uavs", "--json") if v["id"] == uav)["phase"]
        assert phase != "aborted"
    finally:
        for station in (operator, unsigned, forger):
            station.close()
        lines = stop(gateway)
    summary = exit_drops(lines)
    assert "'unsigned': 3" in summary and "'bad_signature': 3" in summary, summary
    assert any("signed (1 station secret(s))" in line for line in lines)


def test_a_second_station_cannot_take_over_or_join_an_upload(fleet_up: FleetUp) -> None:
    gateway = fleet_up.gateway("udpin:127.0.0.1:0")
    port = served_port(gateway)
    operator, rival = Station(port), Station(port)
    uav = UAVS[0]
    targets = [(35.70, -120.78), (35.69, -120.76)]

    def item(seq: int, lat: float, lon: float) -> mavlink2.MAVLink_mission_item_int_message:
        return mavlink2.MAVLink_mission_item_int_message(
            uav, 1, seq, mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_CMD_NAV_WAYPOINT, 0, 1,
            0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 600.0,
        )  # fmt: skip

    try:
        for station in (operator, rival):
            station.heartbeat()
            station.expect("HEARTBEAT", uav)
        operator.send(mavlink2.MAVLink_mission_count_message(uav, 1, 2, 0))
        assert operator.expect("MISSION_REQUEST_INT", uav).seq == 0
        rival.send(mavlink2.MAVLink_mission_count_message(uav, 1, 1, 0))
        assert rival.expect("MISSION_ACK", uav).type == mavlink2.MAV_MISSION_DENIED
        rival.send(item(0, 35.0, -120.0))  # injected into the operator's upload: refused
        operator.send(item(0, *targets[0]))
        assert operator.expect("MISSION_REQUEST_INT", uav).seq == 1
        operator.send(item(1, *targets[1]))
        ack = operator.expect("MISSION_ACK", uav)
        assert ack.type == mavlink2.MAV_MISSION_ACCEPTED
        found = fleet_up.ground_cli("mission", "--json")
        flat = [degrees for t in found["targets"] for degrees in (t["lat"], t["lon"])]
        assert flat == pytest.approx([d for t in targets for d in t], abs=1e-7)
    finally:
        operator.close()
        rival.close()
        lines = stop(gateway)
    assert "'busy': 2" in exit_drops(lines), lines[-3:]


def test_mavproxy_commands_once_it_signs_with_its_passphrase(fleet_up: FleetUp) -> None:
    """MAVProxy's `signing key PASSPHRASE` derives the secret as the gateway does: before
    it, its frames are refused (`unsigned`); after it, it is answered."""
    passphrase = "operator-2026"  # MAVProxy takes one word
    keys = fleet_up.tmp / "mavproxy.keys"
    keys.write_text(f"mavproxy {passphrase}\n")
    keys.chmod(0o600)
    signed = fleet_up.mavproxy_gateway("--signing-key", str(keys), state="mavproxy-signed")
    with signed as (proxy, gateway):
        proxy.wait_for_line(lambda line: said(line).startswith("Detected vehicle"), WAIT_S)
        assert proxy.process.stdin is not None
        # Unsigned first (refused, counted), then signed.
        proxy.process.stdin.write(f"wp list\nsigning key {passphrase}\nwp list\n")
        proxy.process.stdin.flush()
        # Answered: the count of the mission the UAV flies (none, or an earlier test's).
        proxy.wait_for_line(
            lambda line: said(line).startswith("Requesting ") and "waypoints" in line, WAIT_S
        )
        proxy.process.stdin.write("exit\n")
        proxy.process.stdin.flush()
    lines = gateway.history
    assert "'unsigned'" in exit_drops(lines), lines[-3:]  # its frames before the key
