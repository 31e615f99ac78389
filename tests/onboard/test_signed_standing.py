"""A standing fetched by query in the secure profile: believed for its author's own
signature and right to the key, not for whoever answered.

The real onboard process logic of UAVs 74 and 112 and their simulated autopilots, in the
test's process (tests/support/memory_world.py), each onboard on a real Zenoh session that
signs and checks as its own identity, through a router of the test's process. 74 stops
after the commitment; 112 re-plans from its standing (fleet.consensus.resolve). The test
asks for 112's standing as the ground, while a rogue signed as UAV 74 answers the same
query with a standing it made up for 112.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from fleet.files.certs import write_identities
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, UavResult
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusQuery
from fleet.transport.router import Router
from onboard.bus_edge import standing_selector
from tests.onboard.test_signed_team import TARGETS
from tests.support.memory_world import memory_fleet
from tests.support.processes import ANY_PORT
from tests.support.signed import signing_bus
from tests.support.waiting import wait_until

SPACE = KeySpace()
MISSION = 52


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    where = tmp_path_factory.mktemp("certs")
    write_identities(where, ["router", "ground", "uav-74", "uav-112", "uav-75"], [])
    return where


@pytest.fixture(scope="module")
def endpoint() -> Iterator[str]:
    with Router([ANY_PORT]) as router:
        yield router.endpoints[0]


def test_a_standing_is_fetched_from_its_uav_and_a_forged_answer_is_refused(
    certs: Path, endpoint: str
) -> None:
    def bus_of(uav: int) -> Bus:
        return signing_bus(certs, endpoint, f"uav-{uav}")

    ground = signing_bus(certs, endpoint, "ground")
    rogue = signing_bus(certs, endpoint, "uav-75")  # a fleet identity, not 112's
    try:
        with memory_fleet("head_on", speedup=5.0, bus_of=bus_of) as fleet:
            processes = fleet.processes
            wait_until(
                lambda: all({74, 112} <= p.core.mission.team.alive for p in processes.values()),
                30.0,
                "74 and 112 counting each other",
            )
            mission = MissionTargets(MISSION, (74, 112), tuple(TARGETS))

            def committed() -> bool:
                rounds = [p.core.round for p in processes.values()]
                if not all(r is not None and r.mission == MISSION for r in rounds):
                    ground.publish(SPACE.mission_targets(MISSION), mission)  # until heard
                return all(r is not None and r.committed is not None for r in rounds)

            wait_until(committed, 60.0, "74 and 112 committed")
            fleet.stop_uav(74)
            survivor = processes[112].core

            def resolved() -> str | None:
                report = survivor.round.committed if survivor.round else None
                return report.basis if report is not None and report.epoch > 0 else None

            wait_until(resolved, 60.0, "112's re-plan solved from its standing")
            basis = resolved()
            assert basis is not None
            key = SPACE.mission_result(MISSION, 112)
            forged = UavResult(MISSION, 112, (1.0,) * len(TARGETS), basis=basis)
            answering = None
            answered: list[BusQuery] = []

            def answer_forged() -> None:  # on Zenoh's thread, as each query arrives
                while answering is not None and (query := answering.try_recv()) is not None:
                    query.reply(key, forged)  # it holds no key of 112's to sign with
                    query.drop()
                    answered.append(query)

            answering = rogue.declare_queryable(key, answer_forged)
            refused = bus_codec.DROPPED.total()
            replies = []
            for _ in range(3):  # the rogue's queryable may reach the router late: ask again
                replies += ground.query(standing_selector(key, basis), 2.0, every_reply=True)
            answering.undeclare()
            assert answered and bus_codec.DROPPED.total() > refused  # answered, refused
            standings = [bus_codec.decode(r.payload, UavResult, r.key) for r in replies if r.ok]
            own = survivor.own_standing(MISSION, basis)
            # 112's own, as it signed it; the rogue's made-up one never gets through.
            assert own is not None and standings and all(s == own for s in standings)
            assert all(r.author == "uav-112" for r in replies if r.ok)
    finally:
        rogue.close()
        ground.close()
