"""The gateway's answers, without a fleet: a real endpoint's output decoded, a
stand-in for the fleet's side, and the ground's view of the UAVs set by the test.

What is checked is the protocol a ground station sees: each step of an upload, the
MISSION_ACK only once the fleet took the mission, RTL's final COMMAND_ACK only once the
UAV confirmed, MISSION_CURRENT and MISSION_ITEM_REACHED from the observed phase, and
nothing dropped silently.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.transport.memory import MemoryNetwork
from ground.fleet_view import UavView
from ground.mavlink.endpoint import Address, Drop, Endpoint, Incoming, InputDrops
from ground.mavlink.fleet_link import AbortResult, FleetLink, SendOutcome, TeamChoice
from ground.mavlink.gateway import Gateway
from ground.mavlink.requests import Requests
from ground.mavlink.signing import StationKey
from ground.mavlink.sysids import SysIdMap
from ground.mavlink.vehicle import FleetMode
from tests.support.waiting import wait_until

STATION = (255, 190)
ADDRESS = ("127.0.0.1", 14550)  #: where the station's datagrams come from
OTHER = ("127.0.0.1", 14551)  #: another station, with the same system and component ids
_station = mavlink2.MAVLink(None, *STATION)


def from_station(message: mavlink2.MAVLink_message) -> mavlink2.MAVLink_message:
    """`message` as the gateway gets it: packed by a station and decoded."""
    parser = mavlink2.MAVLink(None)
    (decoded,) = parser.parse_buffer(bytes(message.pack(_station))) or []
    return decoded


class StandInFleet(FleetLink):
    """The fleet's side: takes every mission; an abort is confirmed when the test says."""

    def __init__(self) -> None:
        self.sent: list[tuple[int, tuple[Target, ...], TeamChoice]] = []
        self.confirm = threading.Event()
        self.refuse: str | None = None
        self.unacknowledged = False

    def send_mission(
        self, uav: int, targets: tuple[Target, ...], choice: TeamChoice, live: list[int]
    ) -> SendOutcome:
        self.sent.append((uav, targets, choice))
        if self.refuse is not None:
            return SendOutcome(None, (uav,), problem=self.refuse)
        if self.unacknowledged:
            return SendOutcome(None, (uav,), problem="not acknowledged by 74", sent=7)
        return SendOutcome(7, (uav,))

    def abort(self, uav: int) -> tuple[AbortResult, str]:
        if not self.confirm.wait(10.0):
            return AbortResult.NOT_CONFIRMED, "no confirmation"
        return AbortResult.CONFIRMED, f"mission 7: UAV {uav} aborted"

    def mission_targets(self, mission: int) -> MissionTargets | None:
        return None

    def close(self) -> None:
        pass


class Harness:
    def __init__(self, gateway: Gateway, fleet: StandInFleet, requests: Requests) -> None:
        self.gateway = gateway
        self.fleet = fleet
        self.requests = requests
        self.views = [UavView(id=74, phase="idle")]
        self.sent: list[mavlink2.MAVLink_message] = []
        self.to: list[tuple[mavlink2.MAVLink_message, Address | None]] = []
        self._parser = mavlink2.MAVLink(None)

    def capture(
        self, pack: Callable[[StationKey | None], bytes], to: Address | None = None
    ) -> None:
        """What the gateway sends (to the station at `to`, None: to every station)."""
        for message in self._parser.parse_buffer(pack(None)) or []:
            self.sent.append(message)
            self.to.append((message, to))

    def take(self, kind: str) -> list[mavlink2.MAVLink_message]:
        self.gateway.send_answers()
        found = [m for m in self.sent if m.get_type() == kind]
        self.sent = [m for m in self.sent if m.get_type() != kind]
        return found

    def wait_for(self, kind: str, count: int = 1) -> list[mavlink2.MAVLink_message]:
        """The `count` messages of `kind` the workers' answers bring, waited for."""
        got: list[mavlink2.MAVLink_message] = []

        def arrived() -> bool:
            got.extend(self.take(kind))
            return len(got) >= count

        wait_until(arrived, 5.0, f"{count} {kind}")
        return got

    def handle(self, message: mavlink2.MAVLink_message, station: Address = ADDRESS) -> None:
        self.requests.handle(Incoming(from_station(message), station))


@pytest.fixture
def harness(monkeypatch: pytest.MonkeyPatch) -> Iterator[Harness]:
    endpoint = Endpoint("udpin:127.0.0.1:0", InputDrops())
    fleet = StandInFleet()
    gateway = Gateway(MemoryNetwork().bus(), KeySpace(), fleet, endpoint, SysIdMap())
    requests = Requests(gateway, TeamChoice.UAV)
    harness = Harness(gateway, fleet, requests)
    monkeypatch.setattr(endpoint, "send", harness.capture)
    monkeypatch.setattr(gateway.view, "snapshot", lambda include_gone=False: harness.views)
    try:
        yield harness
    finally:
        gateway.workers.shutdown(wait=False, cancel_futures=True)
        fleet.confirm.set()
        endpoint.close()


def waypoint(seq: int) -> mavlink2.MAVLink_mission_item_int_message:
    return mavlink2.MAVLink_mission_item_int_message(
        74, 1, seq, mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_CMD_NAV_WAYPOINT, 0, 1,
        0, 0, 0, 0, 357000000 + seq * 100000, -1208000000, 600.0,
    )  # fmt: skip


def upload(harness: Harness, count: int) -> None:
    harness.handle(mavlink2.MAVLink_mission_count_message(74, 1, count, 0))
    for seq in range(count):
        (request,) = harness.take("MISSION_REQUEST_INT")
        assert (request.seq, request.get_srcSystem()) == (seq, 74)
        assert (request.target_system, request.target_component) == STATION
        harness.handle(waypoint(seq))


def test_an_upload_is_acked_only_once_the_fleet_took_it(harness: Harness) -> None:
    upload(harness, 3)
    assert harness.take("MISSION_REQUEST_INT") == []
    wait_until(lambda: harness.fleet.sent, 5.0, "the mission handed to the fleet")
    (uav, targets, choice) = harness.fleet.sent[0]
    assert (uav, choice) == (74, TeamChoice.UAV)
    assert targets[2] == Target(35.72, -120.8, 600.0)
    acks = harness.wait_for("MISSION_ACK")
    assert [a.type for a in acks] == [mavlink2.MAV_MISSION_ACCEPTED]
    assert harness.gateway.mission_of(7) == MissionTargets(7, (74,), targets)


def test_a_mission_the_fleet_refuses_is_acked_denied_with_why(harness: Harness) -> None:
    harness.fleet.refuse = "targets 0 and 1: 12 m apart"
    upload(harness, 2)
    acks = harness.wait_for("MISSION_ACK")
    assert [a.type for a in acks] == [mavlink2.MAV_MISSION_DENIED]
    assert "12 m apart" in "".join(t.text for t in harness.take("STATUSTEXT"))


def test_a_mission_sent_but_not_acknowledged_is_an_error(harness: Harness) -> None:
    harness.fleet.unacknowledged = True
    upload(harness, 1)
    (ack,) = harness.wait_for("MISSION_ACK")
    assert ack.type == mavlink2.MAV_MISSION_ERROR
    assert "not acknowledged by 74" in "".join(t.text for t in harness.take("STATUSTEXT"))


def test_an_item_the_fleet_cannot_fly_is_refused_at_once(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_mission_count_message(74, 1, 2, 0))
    harness.take("MISSION_REQUEST_INT")
    takeoff = mavlink2.MAVLink_mission_item_int_message(
        74, 1, 0, mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 1,
        0, 0, 0, 0, 357000000, -1208000000, 600.0,
    )  # fmt: skip
    harness.handle(takeoff)
    (ack,) = harness.take("MISSION_ACK")
    assert ack.type == mavlink2.MAV_MISSION_UNSUPPORTED
    chunks = harness.take("STATUSTEXT")  # longer than one STATUSTEXT: in chunks
    assert "mission item 0: MAV_CMD_NAV_TAKEOFF" in "".join(c.text for c in chunks)
    assert {c.severity for c in chunks} == {mavlink2.MAV_SEVERITY_ERROR}
    assert harness.fleet.sent == []


def test_a_huge_count_is_refused_and_counted(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_mission_count_message(74, 1, 65535, 0))
    (ack,) = harness.take("MISSION_ACK")
    assert ack.type == mavlink2.MAV_MISSION_NO_SPACE
    assert harness.gateway.drops.counts() == {Drop.REFUSED: 1}
    assert harness.take("MISSION_REQUEST_INT") == []


def test_rtl_is_in_progress_until_the_uav_confirmed(harness: Harness) -> None:
    rtl = mavlink2.MAVLink_command_long_message(
        74, 1, mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0, 0, 0, 0, 0
    )
    harness.handle(rtl)
    harness.handle(rtl)  # a station's retry
    results = [a.result for a in harness.take("COMMAND_ACK")]
    assert results == [mavlink2.MAV_RESULT_IN_PROGRESS] * 2
    harness.fleet.confirm.set()
    acks = harness.wait_for("COMMAND_ACK")
    assert [(a.command, a.result) for a in acks] == [
        (mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink2.MAV_RESULT_ACCEPTED)
    ]
    assert (acks[0].target_system, acks[0].target_component) == STATION


def test_set_mode_rtl_aborts_too(harness: Harness) -> None:
    harness.fleet.confirm.set()
    harness.handle(
        mavlink2.MAVLink_set_mode_message(74, mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 11)
    )
    acks = harness.wait_for("COMMAND_ACK", 2)
    assert [a.result for a in acks] == [
        mavlink2.MAV_RESULT_IN_PROGRESS,
        mavlink2.MAV_RESULT_ACCEPTED,
    ]


def test_unsupported_commands_are_answered_never_dropped(harness: Harness) -> None:
    arm = mavlink2.MAVLink_command_long_message(
        74, 1, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
    )
    harness.handle(arm)
    (ack,) = harness.take("COMMAND_ACK")
    assert (ack.command, ack.result) == (
        mavlink2.MAV_CMD_COMPONENT_ARM_DISARM,
        mavlink2.MAV_RESULT_UNSUPPORTED,
    )


def test_autopilot_version_on_request(harness: Harness) -> None:
    harness.handle(
        mavlink2.MAVLink_command_long_message(
            74, 1, mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0
        )
    )
    (ack,) = harness.take("COMMAND_ACK")
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    (version,) = harness.take("AUTOPILOT_VERSION")
    assert version.uid == 74
    assert version.capabilities & mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_INT


def request_message(message_id: int) -> mavlink2.MAVLink_command_long_message:
    return mavlink2.MAVLink_command_long_message(
        74, 1, mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, message_id, 0, 0, 0, 0, 0, 0
    )


def test_gps_status_and_battery_on_request(
    harness: Harness, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before any telemetry: the GPS is not known yet, said so; the battery never is.
    harness.handle(request_message(mavlink2.MAVLINK_MSG_ID_GPS_STATUS))
    (ack,) = harness.take("COMMAND_ACK")
    assert ack.result == mavlink2.MAV_RESULT_TEMPORARILY_REJECTED
    assert harness.take("GPS_STATUS") == []
    harness.handle(request_message(mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS))
    (ack,) = harness.take("COMMAND_ACK")
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    (battery,) = harness.take("BATTERY_STATUS")
    assert battery.battery_remaining == -1 and battery.voltages[0] == 2**16 - 1
    # With telemetry: its satellites.
    fix = Telemetry(system_time_ms=0, gps=GpsBlock(35.7, -120.8, 600.0, 0, 0, 0, 1.0, 11, 10))
    monkeypatch.setattr(harness.gateway.view, "telemetry", lambda uav: fix)
    harness.handle(request_message(mavlink2.MAVLINK_MSG_ID_GPS_STATUS))
    (ack,) = harness.take("COMMAND_ACK")
    assert (ack.command, ack.result) == (
        mavlink2.MAV_CMD_REQUEST_MESSAGE,
        mavlink2.MAV_RESULT_ACCEPTED,
    )
    (gps,) = harness.take("GPS_STATUS")
    assert gps.satellites_visible == 11 and gps.get_srcSystem() == 74


def test_a_message_for_a_system_not_shown_is_counted(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_mission_count_message(75, 1, 3, 0))
    harness.handle(mavlink2.MAVLink_mission_request_list_message(0, 0, 0))  # broadcast
    assert harness.sent == []
    assert harness.gateway.drops.counts() == {Drop.UNKNOWN_SYSTEM: 1}


def test_mission_progress_follows_the_reported_phase(harness: Harness) -> None:
    targets = (Target(35.7, -120.8, 600.0), Target(35.71, -120.8, 600.0))
    harness.gateway.remember_mission(MissionTargets(7, (74,), targets))
    harness.views = [UavView(id=74, mission=7, target=1, phase="committed")]
    harness.gateway._tick()
    (current,) = harness.take("MISSION_CURRENT")
    assert (current.seq, current.total) == (1, 2)
    assert harness.take("MISSION_ITEM_REACHED") == []
    (beat,) = harness.take("HEARTBEAT")
    assert beat.custom_mode == FleetMode.GUIDED  # PX4 OFFBOARD: the fleet steers it
    harness.views = [UavView(id=74, mission=7, target=1, phase="reached")]
    for _ in range(2):
        harness.gateway._next_slow = harness.gateway._next_fast = 0.0
        harness.gateway._tick()
    (reached,) = harness.take("MISSION_ITEM_REACHED")
    assert reached.seq == 1
    assert {c.mission_state for c in harness.take("MISSION_CURRENT")} == {
        mavlink2.MISSION_STATE_COMPLETE
    }


def test_download_returns_what_the_uav_flies(harness: Harness) -> None:
    targets = (Target(35.7, -120.8, 600.0), Target(35.71, -120.8, 610.0))
    harness.gateway.remember_mission(MissionTargets(7, (74, 75), targets))
    harness.views = [UavView(id=74, mission=7, target=1, phase="flying")]
    harness.handle(mavlink2.MAVLink_mission_request_list_message(74, 1, 0))
    (count,) = harness.take("MISSION_COUNT")
    assert count.count == 2
    harness.handle(mavlink2.MAVLink_mission_request_int_message(74, 1, 1, 0))
    (item,) = harness.take("MISSION_ITEM_INT")
    assert (item.seq, item.current, item.x, item.z) == (1, 1, 357100000, 610.0)
    harness.handle(mavlink2.MAVLink_mission_request_int_message(74, 1, 5, 0))
    (ack,) = harness.take("MISSION_ACK")
    assert ack.type == mavlink2.MAV_MISSION_INVALID_SEQUENCE


def test_no_mission_downloads_as_empty(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_mission_request_list_message(74, 1, 0))
    (count,) = harness.take("MISSION_COUNT")
    assert count.count == 0


def test_setting_the_current_item_is_answered_with_the_one_the_fleet_chose(
    harness: Harness,
) -> None:
    targets = (Target(35.7, -120.8, 600.0), Target(35.71, -120.8, 600.0))
    harness.gateway.remember_mission(MissionTargets(7, (74,), targets))
    harness.views = [UavView(id=74, mission=7, target=1, phase="flying")]
    harness.handle(mavlink2.MAVLink_mission_set_current_message(74, 1, 0))
    (current,) = harness.take("MISSION_CURRENT")
    assert current.seq == 1
    (text,) = harness.take("STATUSTEXT")
    assert text.severity == mavlink2.MAV_SEVERITY_WARNING


def test_a_hostile_telemetry_value_does_not_stop_the_streams(
    harness: Harness, monkeypatch: pytest.MonkeyPatch
) -> None:
    hostile = Telemetry(system_time_ms=0, gps=GpsBlock(35.7, -120.8, 1e300, 0, 0, 0))
    monkeypatch.setattr(harness.gateway.view, "telemetry", lambda uav: hostile)
    harness.views = [UavView(id=74, phase="idle")]
    harness.gateway._tick()  # VFR_HUD's float altitude cannot hold 1e300: skipped
    assert harness.take("HEARTBEAT")
    (position,) = harness.take("GLOBAL_POSITION_INT")
    assert position.alt == 2**31 - 1


def test_a_second_station_can_neither_take_over_nor_join_an_open_upload(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_mission_count_message(74, 1, 2, 0))
    (request,) = harness.take("MISSION_REQUEST_INT")
    assert request.seq == 0
    # Another station (same ids 255/190, another address) counts, then sends an item.
    harness.handle(mavlink2.MAVLink_mission_count_message(74, 1, 1, 0), OTHER)
    (refused,) = harness.take("MISSION_ACK")
    assert refused.type == mavlink2.MAV_MISSION_DENIED
    assert (refused, OTHER) in harness.to  # told to it alone
    harness.handle(waypoint(0), OTHER)
    assert harness.take("MISSION_REQUEST_INT") == []
    assert harness.gateway.drops.counts() == {Drop.BUSY: 2}
    # The operator's upload goes on, untouched.
    harness.handle(waypoint(0))
    (request,) = harness.take("MISSION_REQUEST_INT")
    assert request.seq == 1 and (request, ADDRESS) in harness.to
    harness.handle(waypoint(1))
    (ack,) = harness.wait_for("MISSION_ACK")
    assert ack.type == mavlink2.MAV_MISSION_ACCEPTED
    ((_, targets, _),) = harness.fleet.sent
    assert [round(t.lat, 4) for t in targets] == [35.7, 35.71]
    # Once it is over, the other station may upload.
    harness.handle(mavlink2.MAVLink_mission_count_message(74, 1, 1, 0), OTHER)
    (request,) = harness.take("MISSION_REQUEST_INT")
    assert (request, OTHER) in harness.to


def test_parameters_are_listed_read_and_refused_to_be_set(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_param_request_list_message(74, 1))
    listed = harness.take("PARAM_VALUE")
    assert [p.param_index for p in listed] == list(range(5))
    assert {p.param_count for p in listed} == {5}
    values = {p.param_id: p.param_value for p in listed}
    assert values["FLT_PICCOLO_ID"] == 74 and values["FLT_ACCEPT_RAD"] == 75.0
    harness.handle(mavlink2.MAVLink_param_request_read_message(74, 1, b"FLT_BANK_LIM", -1))
    (read,) = harness.take("PARAM_VALUE")
    assert (read.param_id, read.param_value, read.param_index) == ("FLT_BANK_LIM", 30.0, 3)
    harness.handle(mavlink2.MAVLink_param_request_read_message(74, 1, b"", 0))
    assert harness.take("PARAM_VALUE")[0].param_id == "FLT_PICCOLO_ID"
    harness.handle(mavlink2.MAVLink_param_request_read_message(74, 1, b"NO_SUCH", -1))
    assert harness.take("PARAM_VALUE") == []
    harness.handle(
        mavlink2.MAVLink_param_set_message(
            74, 1, b"FLT_BANK_LIM", 60.0, mavlink2.MAV_PARAM_TYPE_REAL32
        )
    )
    (unchanged,) = harness.take("PARAM_VALUE")
    assert unchanged.param_value == 30.0  # the protocol's refusal: the value it still has
    assert "read-only" in harness.take("STATUSTEXT")[0].text


def test_timesync_is_answered_with_the_stations_own_time(harness: Harness) -> None:
    harness.handle(mavlink2.MAVLink_timesync_message(0, 123456789))
    (answer,) = harness.take("TIMESYNC")
    assert answer.ts1 == 123456789 and answer.tc1 > 0
    assert answer.get_srcSystem() == 74
    harness.handle(mavlink2.MAVLink_timesync_message(5, 123456789))  # an answer: not ours
    assert harness.take("TIMESYNC") == []
