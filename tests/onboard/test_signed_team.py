"""Who is on the team in the secure profile: a UAV counts once it spoke for itself, never
on a liveliness token alone.

The real onboard process logic of UAVs 74 and 112 and their simulated autopilots, in the
test's process (tests/support/memory_world.py), each onboard on a real Zenoh session that
signs and checks as its own identity, through a router of the test's process; the test
holds the ground's identity, a ghost's token (a client with no key of UAV 299's: anyone
on the way can declare a token of a roster identity) and a UAV 300 frozen a moment ago
(its token and its queryable still there, its last state put, signed, and then silence).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from fleet.files.certs import write_identities
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, UavState
from fleet.mission.targets_file import decode_targets
from fleet.transport.bus import Bus
from fleet.transport.router import Router
from fleet.transport.zenoh_bus import ZenohBus, connect
from ground.fleet_view import live_uav_ids
from tests.support.memory_world import MemoryFleet, memory_fleet
from tests.support.processes import ANY_PORT
from tests.support.secure_fleet import TARGETS_FILE
from tests.support.signed import signing_bus
from tests.support.waiting import wait_until

SPACE = KeySpace()
TARGETS = decode_targets(Path(TARGETS_FILE).read_bytes(), TARGETS_FILE)
#: Far longer than a decision takes: a team that waits for a ghost waits this long.
DEADLINE_S = 120.0


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    where = tmp_path_factory.mktemp("certs")
    names = ["router", "ground", "uav-74", "uav-112", "uav-299", "uav-300"]
    write_identities(where, names, [])
    return where


@pytest.fixture(scope="module")
def endpoint() -> Iterator[str]:
    with Router([ANY_PORT]) as router:
        yield router.endpoints[0]


@pytest.fixture(scope="module")
def uavs(certs: Path, endpoint: str) -> Iterator[MemoryFleet]:
    def bus_of(uav: int) -> Bus:
        return signing_bus(certs, endpoint, f"uav-{uav}")

    with memory_fleet("head_on", speedup=5.0, bus_of=bus_of) as running:
        # Each onboard counts the other once its signed state answered (`_ask_word`).
        wait_until(
            lambda: all(
                {74, 112} <= process.core.mission.team.alive
                for process in running.processes.values()
            ),
            30.0,
            "74 and 112 counting each other",
        )
        yield running


@pytest.fixture
def ground_bus(certs: Path, endpoint: str) -> Iterator[ZenohBus]:
    bus = signing_bus(certs, endpoint, "ground")
    yield bus
    bus.close()


@pytest.fixture
def ghost(endpoint: str) -> Iterator[None]:
    """UAV 299's liveliness token, declared by a client that holds no key of 299's."""
    bus = connect(endpoint)
    token = bus.declare_token(SPACE.alive(299))  # held: a token dropped is undeclared
    yield
    token.undeclare()
    bus.close()


@pytest.fixture
def frozen(certs: Path, endpoint: str, uavs: MemoryFleet) -> Iterator[None]:
    """UAV 300 as a frozen onboard is: its token and its state queryable still declared,
    nothing answered; its last state, signed by its own key, put before it froze (and
    kept by its teammates)."""
    bus = signing_bus(certs, endpoint, "uav-300")
    token = bus.declare_token(SPACE.alive(300))  # held: a token dropped is undeclared
    queryable = bus.declare_queryable(SPACE.state(300))  # never answered
    last = UavState(300, True, 1.0, None, None, None, None)

    def kept_by_the_team() -> bool:
        # Put until heard: the teammates' subscriptions may not have reached the router.
        bus.publish(SPACE.state(300), last)
        return all(p.node.bus.latest(SPACE.state(300)) for p in uavs.processes.values())

    wait_until(kept_by_the_team, 10.0, "74 and 112 keeping 300's state")
    yield
    queryable.undeclare()
    token.undeclare()
    bus.close()


def test_the_team_send_targets_picks_leaves_a_ghost_out(
    uavs: MemoryFleet, ground_bus: ZenohBus, ghost: None
) -> None:
    """The live UAVs `send-targets` picks a team from: 74 and 112, whose signed states
    answer, never the ghost 299 (on the code before, its token was enough)."""
    wait_until(lambda: ground_bus.live_tokens(SPACE.alive(299), 1.0), 10.0, "299's token seen")
    assert live_uav_ids(ground_bus, SPACE, 1.0) == [74, 112]


def test_the_team_send_targets_picks_keeps_a_uav_frozen_a_moment_ago(
    uavs: MemoryFleet, ground_bus: ZenohBus, ghost: None, frozen: None
) -> None:
    """300, frozen: its state query gets no answer, but its own signed state, relayed by
    a teammate that heard it put, keeps it in the team (it fetches the mission when it
    resumes); the ghost 299 stays out."""
    assert live_uav_ids(ground_bus, SPACE, 1.0) == [74, 112, 300]


def test_an_onboard_does_not_wait_for_a_ghost_teammate(
    uavs: MemoryFleet, ground_bus: ZenohBus, ghost: None
) -> None:
    """A mission naming 74, 112 and the ghost 299: both onboards see 299's token, but 299
    never speaks for itself (no signed state answers, no result comes), so neither
    waits for it until the deadline: both commit, on one plan, without it, long before.
    On the code before, the token made 299 a live teammate whose result was awaited
    for the whole deadline."""
    wait_until(
        lambda: all(299 in process.core.mission.team.tokens for process in uavs.processes.values()),
        10.0,
        "both onboards seeing 299's token",
    )
    mission = MissionTargets(41, (74, 112, 299), tuple(TARGETS), deadline_s=DEADLINE_S)

    def committed() -> dict[int, UavState]:
        states = dict(ground_bus.query_messages(SPACE.all_state, UavState, 1.0))
        return {
            state.uav: state
            for state in states.values()
            if state.mission is not None
            and state.mission.mission == mission.mission
            and state.mission.assignment is not None
        }

    def sent_and_committed() -> bool:
        # Put again until both hold it (a repeat is ignored): a put may go unheard.
        rounds = [p.core.round for p in uavs.processes.values()]
        if not all(r is not None and r.mission == mission.mission for r in rounds):
            ground_bus.publish(SPACE.mission_targets(mission.mission), mission)
        return set(committed()) == {74, 112}

    # Far within the deadline: a team waiting for 299 commits only at its end.
    wait_until(sent_and_committed, DEADLINE_S / 2, "74 and 112 committed")
    reports = [state.mission.assignment for state in committed().values() if state.mission]
    assert all(r is not None and r.team == (74, 112) for r in reports), reports
    assert len({r.digest for r in reports if r is not None}) == 1, reports
