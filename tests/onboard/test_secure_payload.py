"""The payload pipe in the secure profile (case 5): a mission injected on the
simulator's payload ground port (a radio-only ground station, the thesis's path) is
refused and counted by an onboard on the secure profile, which flies nothing for it; the
same injection is obeyed in the open profile (tests/onboard/test_process.py).

Real parts: a secure router (mTLS and access control), the simulator, the onboard
process with UAV 112's identity, the ground's identity asking for its state.
"""

from __future__ import annotations

import socket
from pathlib import Path

import msgspec
import pytest
import zenoh

from fleet.files.certs import write_identities
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MISSION_MANAGER, MissionTargets, Target, UavState
from fleet.mission.phase import Phase
from fleet.payload.link import PiccoloLink
from fleet.payload.protocol import encode_message
from fleet.transport.router import Router
from fleet.transport.secure import SecureProfile
from fleet.transport.zenoh_config import build_config
from onboard.process import PAYLOAD_REFUSED
from tests.support.processes import Fleet
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

SPACE = KeySpace()
UAV = 112


def state_of(ground: zenoh.Session) -> UavState | None:
    for reply in ground.get(SPACE.state(UAV), timeout=5.0):
        if reply.ok is not None:
            return msgspec.json.decode(reply.ok.payload.to_bytes(), type=UavState)
    return None


@pytest.fixture
def certs(tmp_path: Path) -> Path:
    write_identities(tmp_path, ["router", "ground", f"uav-{UAV}"], [])
    return tmp_path.resolve()


def test_a_mission_on_the_payload_port_is_refused_in_the_secure_profile(
    certs: Path, fleet: Fleet
) -> None:
    with Router(["tls/127.0.0.1:0"], secure=SecureProfile.load(certs)) as router:
        (endpoint,) = router.endpoints
        ground_config = build_config(config_file=str(certs / "ground.json5"), connect=[endpoint])
        with zenoh.open(ground_config) as ground:
            sim = fleet.sim("single_uav", 5.0, 5.0)[UAV]
            onboard = fleet.onboard(
                UAV, sim, endpoint, "--zenoh-config", str(certs / f"uav-{UAV}.json5")
            )

            def telemetry_flows() -> bool:
                state = state_of(ground)
                return state is not None and state.telemetry is not None

            wait_until(telemetry_flows, 60.0, "UAV 112's state with telemetry")

            host, port = sim.ground.removeprefix("socket://").split(":")
            station = PiccoloLink(local_address=0)
            mission = MissionTargets(
                mission=9, team=(UAV,), targets=(Target(35.7153345, -120.7657532, 600.0),)
            )
            frame = station.encode_payload(encode_message(mission, MISSION_MANAGER, UAV), UAV)

            def refused() -> bool:
                state = state_of(ground)
                return (
                    state is not None
                    and state.link is not None
                    and (state.link.drops.get(PAYLOAD_REFUSED, 0) >= 1)
                )

            with socket.create_connection((host, int(port)), timeout=5.0) as radio:
                radio.sendall(frame)
                wait_until(refused, 30.0, "the payload port's mission counted refused")
            state = state_of(ground)
            assert state is not None
            assert state.mission is None and state.phase is Phase.IDLE  # nothing flown
            assert any(
                "refused MissionTargets from the payload port" in line for line in onboard.history
            )
            # Nor did it relay the mission onto the fleet's keys.
            assert [r for r in ground.get(SPACE.mission_targets(9), timeout=2.0) if r.ok] == []
