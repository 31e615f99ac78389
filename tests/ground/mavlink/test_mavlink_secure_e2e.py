"""`fleet mavlink` in the secure profile: `fleet up --secure` (mutual TLS, access
control), the gateway holding the ground's identity says so and its uploads are
acknowledged by the UAV; holding a UAV's identity, it says it is not the ground's and
its upload is refused with MISSION_ACK ERROR, since the routers drop what it puts."""

from __future__ import annotations

import signal
import socket
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from tests.ground.mavlink.mavlink_fleet import SERVING, served_port
from tests.ground.mavlink.stations import receiver
from tests.support.processes import Child, start, wait_fleet_up
from tests.support.secure_fleet import start_secure_up

pytestmark = pytest.mark.e2e

UAVS = (74, 112)
WAIT_S = 90.0


@dataclass
class SecureFleet:
    endpoint: str
    certs: Path

    def gateway(self, identity: str) -> Child:
        """A gateway holding `identity`, listening for stations on a free UDP port."""
        child = start(
            "fleet mavlink",
            [sys.executable, "-m", "programs.fleet_cli", "mavlink",
             "--zenoh-config", str(self.certs / f"{identity}.json5"),
             "--connect", self.endpoint, "--out", "udpin:127.0.0.1:0"],
        )  # fmt: skip
        return child


@pytest.fixture(scope="module")
def secure_fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SecureFleet]:
    certs = tmp_path_factory.mktemp("certs")
    up = start_secure_up(certs, "--no-record")
    try:
        endpoint = wait_fleet_up(up, WAIT_S).connect
        yield SecureFleet(endpoint, certs.resolve())
    finally:
        up.process.send_signal(signal.SIGTERM)
        up.process.wait(30)


def upload_one(identity: str, fleet: SecureFleet) -> tuple[list[str], int]:
    """Start a gateway holding `identity`, upload one waypoint to UAV 74 once every
    UAV is shown; its output and the MISSION_ACK's type."""
    gateway = fleet.gateway(identity)
    station = mavlink2.MAVLink(None, 250, 190)
    try:
        gateway.wait_for_line(lambda line: line.startswith(SERVING), WAIT_S)
        port = served_port(gateway)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.connect(("127.0.0.1", port))
            sock.settimeout(0.2)
            heard = receiver(sock, mavlink2.MAVLink(None))
            sock.send(bytes(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(station)))
            shown: set[int] = set()

            def shows_all(message: mavlink2.MAVLink_message) -> bool:
                if message.get_type() == "HEARTBEAT":
                    shown.add(message.get_srcSystem())
                return shown >= set(UAVS)

            heard(shows_all)
            count = mavlink2.MAVLink_mission_count_message(74, 1, 1, 0)
            sock.send(bytes(count.pack(station)))
            heard(lambda m: m.get_type() == "MISSION_REQUEST_INT" and m.seq == 0)
            item = mavlink2.MAVLink_mission_item_int_message(
                74, 1, 0, mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_CMD_NAV_WAYPOINT, 1, 1,
                0, 0, 0, 0, 357300000, -1207900000, 600.0,
            )  # fmt: skip
            sock.send(bytes(item.pack(station)))
            ack = heard(lambda m: m.get_type() == "MISSION_ACK" and m.get_srcSystem() == 74)
            return list(gateway.history), int(ack.type)
    finally:
        gateway.stop(grace=15.0)


@dataclass
class Upload:
    """What a gateway said while uploading, and the MISSION_ACK's type."""

    lines: list[str]
    result: int


@pytest.fixture(scope="module")
def grounds_upload(secure_fleet: SecureFleet) -> Upload:
    """The ground's gateway's upload, once per fleet: UAV 74 then holds mission 1 (each
    test that needs it asks for it, so none depends on another having run first)."""
    return Upload(*upload_one("ground", secure_fleet))


def test_holding_the_grounds_identity_it_says_so_and_missions_are_taken(
    grounds_upload: Upload,
) -> None:
    lines, result = grounds_upload.lines, grounds_upload.result
    assert any("Zenoh: holding the ground's identity" in line for line in lines)
    assert result == mavlink2.MAV_MISSION_ACCEPTED, "\n".join(lines)


def test_holding_a_uavs_identity_it_says_so_and_its_missions_are_refused(
    secure_fleet: SecureFleet, grounds_upload: Upload
) -> None:
    assert grounds_upload.result == mavlink2.MAV_MISSION_ACCEPTED, "the ground's mission first"
    lines, result = upload_one("uav-112", secure_fleet)
    assert any("not the ground's identity" in line for line in lines)
    # The routers drop its put. It must not take UAV 74's holding the ground's mission
    # (the same waypoint, under mission id 1) for an acknowledgement: it sees that
    # mission (a UAV's identity may fetch the ground's targets) and chooses id 2, which
    # no UAV acknowledges.
    assert any("mission 2: 1 items from MAVLink sent to (74,)" in line for line in lines), (
        "\n".join(lines)
    )
    assert result in (mavlink2.MAV_MISSION_ERROR, mavlink2.MAV_MISSION_DENIED), "\n".join(lines)
