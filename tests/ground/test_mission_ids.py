"""Mission ids two grounds cannot share: `claim_mission` against a real router on
loopback, with another Zenoh session of this process standing in for another ground."""

from __future__ import annotations

import logging
import random
import threading

import pytest
import zenoh

from fleet.mission.key_space import KeySpace, mission_of
from fleet.mission.messages import MissionTargets
from fleet.transport import bus_codec
from fleet.transport.memory import MemoryNetwork
from fleet.transport.zenoh_bus import ZenohBus
from fleet.transport.zenoh_config import make_config
from ground.mission_control import MissionError
from ground.mission_ids import (
    TargetsServer,
    claim_mission,
    current_mission_id,
    missions_seen,
    next_mission_id,
    rival_claims,
)
from tests.ground.memory_fleet import MemoryUav
from tests.ground.mission_samples import (
    OTHER_TARGETS,
    TARGETS,
    TIMEOUT_S,
    maker,
    mission,
)
from tests.support.waiting import wait_until

SPACE = KeySpace()


def test_a_fresh_key_space_is_claimed_at_once_and_served_while_open(
    session: ZenohBus, rival: ZenohBus
) -> None:
    with claim_mission(session, SPACE, lambda m: mission(m), TIMEOUT_S, mission=901) as server:
        assert server.targets == mission(901)
        # Served to others while claimed: a second ground sees the claim as a rival.
        assert rival_claims(rival, SPACE, mission(901, OTHER_TARGETS), TIMEOUT_S) == 1
        # The same content is no rival (a UAV holding this very mission, say).
        assert rival_claims(rival, SPACE, mission(901), TIMEOUT_S) == 0
    assert rival_claims(rival, SPACE, mission(901, OTHER_TARGETS), TIMEOUT_S) == 0


def test_a_given_mission_id_another_ground_serves_is_refused(
    session: ZenohBus, rival: ZenohBus
) -> None:
    with TargetsServer(rival, SPACE, mission(902, OTHER_TARGETS)):
        # Declared a moment ago, the rival's queryable may not have reached the router
        # yet: the test is about a claim this ground can see.
        wait_until(
            lambda: rival_claims(session, SPACE, mission(902), TIMEOUT_S) == 1, 10.0, "the claim"
        )
        with (
            pytest.raises(MissionError, match="902 is already in use"),
            claim_mission(session, SPACE, lambda m: mission(m), TIMEOUT_S, mission=902),
        ):
            pass


class Squatter:
    """Another ground that claims, with other targets, every mission id asked about by
    its own key (as if it had chosen the same id a moment earlier); it does not answer
    the ground's wildcard look for missions seen, so the collision happens every time.
    `limit` bounds how many ids it squats."""

    def __init__(self, session: zenoh.Session, limit: int) -> None:
        self.asked: list[int] = []
        self._limit = limit
        self._queryable = session.declare_queryable(SPACE.all_mission_targets, self._on_query)

    def _on_query(self, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        if "*" in key:
            return
        m = mission_of(key)
        if m not in self.asked:
            self.asked.append(m)
        if self.asked.index(m) < self._limit:
            reply = mission(m, OTHER_TARGETS)
            query.reply(key, bus_codec.encode(reply), encoding=bus_codec.ENCODING)

    def close(self) -> None:
        self._queryable.undeclare()


def test_a_collision_moves_on_to_a_higher_id_and_says_so(
    session: ZenohBus, rival: ZenohBus, caplog: pytest.LogCaptureFixture
) -> None:
    squatter = Squatter(rival.session, limit=1)
    caplog.set_level(logging.WARNING, logger="ground.mission_ids")
    try:
        with claim_mission(session, SPACE, lambda m: mission(m), TIMEOUT_S) as server:
            chosen = server.targets.mission
    finally:
        squatter.close()
    first = squatter.asked[0]
    assert first < chosen <= first + 4, squatter.asked
    assert squatter.asked == [first, chosen]
    assert f"mission {first}: another ground chose it too" in caplog.text
    assert f"mission {chosen}: claimed at attempt 2" in caplog.text


def test_running_out_of_attempts_is_an_error(session: ZenohBus, rival: ZenohBus) -> None:
    squatter = Squatter(rival.session, limit=1000)
    try:
        with (
            pytest.raises(MissionError, match="no free mission id after 3 attempts"),
            claim_mission(session, SPACE, lambda m: mission(m), TIMEOUT_S, attempts=3),
        ):
            pass
    finally:
        squatter.close()
    assert len(squatter.asked) == 3
    assert squatter.asked == sorted(squatter.asked)


def test_two_grounds_claiming_together_get_different_ids(router: str) -> None:
    sessions = [ZenohBus(zenoh.open(make_config("client", [router]))) for _ in range(2)]
    try:
        for _ in range(3):
            claimed = claim_together(sessions)
            assert len(claimed) == 2 and claimed[0] != claimed[1], claimed
    finally:
        for opened in sessions:
            opened.close()


def claim_together(sessions: list[ZenohBus]) -> dict[int, int]:
    """Two grounds claim at the same moment, each holding its claim until both have one."""
    start = threading.Barrier(2)
    held = threading.Barrier(3)
    claimed: dict[int, int] = {}

    def claim(index: int) -> None:
        targets = TARGETS if index == 0 else OTHER_TARGETS
        start.wait()
        with claim_mission(sessions[index], SPACE, maker(targets), TIMEOUT_S) as server:
            claimed[index] = server.targets.mission
            held.wait(30)

    threads = [threading.Thread(target=claim, args=(i,)) for i in range(2)]
    for thread in threads:
        thread.start()
    held.wait(30)
    for thread in threads:
        thread.join(30)
    return claimed


# ---- on the in-memory bus -------------------------------------------------------------------
def test_the_next_id_is_above_every_mission_served_or_reported() -> None:
    network = MemoryNetwork()
    ground = network.bus()
    assert next_mission_id(ground, SPACE, 0.1) == 1
    uav = MemoryUav(network, 7)
    uav.fly(mission(12))
    assert missions_seen(ground, SPACE, 0.1) == {12}
    assert next_mission_id(ground, SPACE, 0.1) == 13
    assert current_mission_id(ground, SPACE, 0.1) == 12


def test_a_targets_server_answers_and_notes_a_contested_id() -> None:
    network = MemoryNetwork()
    ground, rival = network.bus(), network.bus()
    with TargetsServer(ground, SPACE, mission(20)) as server:
        assert rival.query_messages(SPACE.mission_targets(20), MissionTargets, 0.1) == [
            (SPACE.mission_targets(20), mission(20))
        ]
        assert not server.contested.is_set()
        assert rival_claims(rival, SPACE, mission(20, OTHER_TARGETS), 0.1) == 1
        assert server.contested.is_set()
    assert rival_claims(rival, SPACE, mission(20, OTHER_TARGETS), 0.1) == 0


def test_a_claim_on_the_memory_bus_skips_an_id_a_uav_holds_with_other_targets() -> None:
    network = MemoryNetwork()
    MemoryUav(network, 7).fly(mission(30, OTHER_TARGETS))
    rng = random.Random(1)
    with claim_mission(network.bus(), SPACE, lambda m: mission(m), 0.1, rng=rng) as server:
        assert server.targets.mission > 30
    with (
        pytest.raises(MissionError, match="30 is already in use"),
        claim_mission(network.bus(), SPACE, lambda m: mission(m), 0.1, mission=30),
    ):
        pass
