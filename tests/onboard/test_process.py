"""The onboard process on its own against the simulator: the adapter's Zenoh face,
its commands, the payload-port ground path, bad input, and the link dropping.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from dataclasses import dataclass
from types import SimpleNamespace

import msgspec
import pytest
import zenoh

from fleet.launch.endpoints import SimEndpoints
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    MISSION_MANAGER,
    AssignmentReport,
    LinkHealth,
    MissionAbort,
    MissionTargets,
    StatusText,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.payload.link import PiccoloLink, PlanningEvent
from fleet.payload.protocol import encode_message
from onboard.process import _Outputs
from tests.support.ground_view import GroundView
from tests.support.processes import Child, Fleet, client_session, router_session
from tests.support.waiting import wait_until

SPACE = KeySpace()

UAV = 112


@dataclass
class Rig:
    fleet: Fleet
    ground: zenoh.Session
    seen: GroundView
    sim: SimEndpoints
    onboard: Child
    router: str


@pytest.fixture
def rig() -> Iterator[Rig]:
    fleet = Fleet()
    try:
        with router_session() as running, client_session(running.endpoints[0]) as ground:
            router = running.endpoints[0]
            seen = GroundView(ground)
            endpoints = fleet.sim("single_uav", 5.0, 5.0)
            onboard = fleet.onboard(UAV, endpoints[UAV], router, "--payload-ground")
            wait_until(lambda: seen.latest_track(UAV) is not None, 30.0, "telemetry and track")
            yield Rig(fleet, ground, seen, endpoints[UAV], onboard, router)
            seen.close()
    finally:
        fleet.stop_all()


def get_one(session: zenoh.Session, key: str, payload: bytes | None = None) -> zenoh.Reply:
    replies = list(session.get(key, payload=payload, timeout=5.0))
    assert len(replies) == 1, f"{key}: {len(replies)} replies"
    return replies[0]


# The state query's answer, commands confirmed by the autopilot's echo, bad commands
# and messages refused, the module switched off, malformed targets, the model built at
# the cruise speed: in memory, tests/onboard/test_process_in_memory.py.


@pytest.mark.e2e
def test_targets_from_a_radio_only_ground_station_on_the_payload_port(rig: Rig) -> None:
    """The thesis's path: PAYLOAD_TARGETS in through the Piccolo payload stream."""
    host, port = rig.sim.ground.removeprefix("socket://").split(":")
    station = PiccoloLink(local_address=0)
    mission = MissionTargets(
        mission=9, team=(UAV,), targets=(Target(35.7153345, -120.7657532, 600.0),)
    )
    with socket.create_connection((host, int(port)), timeout=5.0) as radio:
        radio.sendall(station.encode_payload(encode_message(mission, MISSION_MANAGER, UAV), UAV))
        wait_until(lambda: UAV in rig.seen.assignments, 30.0, "the assignment on Zenoh")
        assert rig.seen.assignments[UAV].mission == 9 and rig.seen.assignments[UAV].target == 0
        # Status and the result come back down the same radio path.
        radio.settimeout(0.2)
        heard: list[object] = []
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and not any(isinstance(m, UavResult) for m in heard):
            try:
                data = radio.recv(65536)
            except TimeoutError:
                continue
            events = station.feed(data, time.monotonic())
            heard += [e.envelope.message for e in events if isinstance(e, PlanningEvent)]
        assert UavResult(9, UAV, rig.seen.results[UAV].times) in heard
        assert any(isinstance(m, StatusText) for m in heard)
    # ...and the mission was published on its key for Zenoh observers.
    reply = get_one(rig.ground, SPACE.mission_targets(9))
    assert reply.ok is not None
    assert msgspec.json.decode(reply.ok.payload.to_bytes(), type=MissionTargets) == mission
    assigned = get_one(rig.ground, SPACE.mission_assignment(9, UAV))
    assert assigned.ok is not None
    assert msgspec.json.decode(assigned.ok.payload.to_bytes(), type=AssignmentReport).target == 0


@pytest.mark.e2e
def test_link_drop_is_reported_and_the_adapter_reconnects(rig: Rig) -> None:
    health: list[LinkHealth] = []
    subscriber = rig.ground.declare_subscriber(
        SPACE.link(UAV),
        lambda s: health.append(msgspec.json.decode(s.payload.to_bytes(), type=LinkHealth)),
    )
    try:
        sim = rig.fleet.children[0]
        assert sim.name == "fleet sim"
        assert sim.stop() == 0
        wait_until(lambda: bool(health) and not health[-1].program_up, 10.0, "link down")
        alive = list(rig.ground.liveliness().get(SPACE.alive(UAV), timeout=2.0))
        assert len(alive) == 1  # still present on Zenoh meanwhile
        program_port = int(rig.sim.program.rsplit(":", 1)[1])
        payload_port = int(rig.sim.payload.rsplit(":", 1)[1])
        rig.fleet.sim(
            "single_uav", 5.0, 5.0,
            "--program-port", str(program_port), "--payload-port", str(payload_port),
        )  # fmt: skip
        wait_until(lambda: health[-1].program_up and health[-1].payload_up, 15.0, "link back")
        count = len(rig.seen.telemetry[UAV])
        wait_until(lambda: len(rig.seen.telemetry[UAV]) > count + 5, 10.0, "telemetry again")
    finally:
        subscriber.undeclare()


# Telemetry relayed at the rate asked for: in memory, tests/onboard/test_process_in_memory.py.


def test_a_catch_up_fetches_the_assignments_outcomes_and_abort() -> None:
    asked: list[tuple[str, type]] = []
    node = SimpleNamespace(fetch=lambda key, kind: asked.append((key, kind)))
    _Outputs(SimpleNamespace(node=node, space=SPACE)).fetch_assignments(5)  # type: ignore[arg-type]
    # A restarted UAV learns who reached which target, so that it never flies one again.
    assert asked == [
        (SPACE.mission_assignments(5), AssignmentReport),
        (SPACE.mission_outcomes(5), TargetOutcome),
        (SPACE.mission_abort(5), MissionAbort),
    ]
