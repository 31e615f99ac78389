"""The onboard's bus edge over the in-memory bus: what it declares, what it hands on,
and what it drops."""

from __future__ import annotations

import logging
import queue
from collections.abc import Iterator
from contextlib import closing

import pytest

from fleet.consensus.mission_round import MissionRound
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, OpmCommand, Target, UavResult
from fleet.transport import bus_codec
from fleet.transport.memory import MemoryBus, MemoryNetwork
from onboard.bus_edge import BusEdge, BusEvent, PresenceEvent

SPACE = KeySpace()

UAV = 112
MISSION = MissionTargets(mission=3, team=(UAV, 74), targets=(Target(35.7, -120.7, 600.0),))


class Harness:
    def __init__(self) -> None:
        self.network = MemoryNetwork()
        self.events: queue.SimpleQueue[BusEvent | PresenceEvent] = queue.SimpleQueue()
        self.node = BusEdge(UAV, self.network.bus(), self.events.put)
        self.ground = self.network.bus()

    def next_event(self) -> BusEvent | PresenceEvent:
        return self.events.get(timeout=5.0)

    def drain(self) -> list[BusEvent | PresenceEvent]:
        found: list[BusEvent | PresenceEvent] = []
        while not self.events.empty():
            found.append(self.events.get_nowait())
        return found


@pytest.fixture
def harness() -> Iterator[Harness]:
    h = Harness()
    with closing(h.ground), closing(h.node):  # closed in reverse: the node first
        yield h


def test_it_is_alive_and_sees_itself(harness: Harness) -> None:
    assert harness.next_event() == PresenceEvent(UAV, True)
    seen: list[tuple[str, bool]] = []
    harness.ground.subscribe_presence(SPACE.all_alive, lambda key, alive: seen.append((key, alive)))
    assert seen == [(SPACE.alive(UAV), True)]


def test_teammates_coming_and_going_are_events(harness: Harness) -> None:
    harness.drain()
    teammate = MemoryBus(harness.network)
    token = teammate.declare_token(SPACE.alive(74))
    assert harness.next_event() == PresenceEvent(74, True)
    token.undeclare()
    assert harness.next_event() == PresenceEvent(74, False)
    teammate.declare_token(SPACE.alive(75))
    teammate.close()  # a crashed teammate: its token goes with its session
    assert harness.drain() == [PresenceEvent(75, True), PresenceEvent(75, False)]


def test_messages_are_decoded_for_the_main_loop(harness: Harness) -> None:
    harness.drain()
    harness.ground.publish(SPACE.mission_targets(3), MISSION)
    harness.ground.publish(SPACE.opm(UAV), OpmCommand(enabled=False, status_rate_hz=0.0))
    harness.ground.publish(SPACE.opm(74), OpmCommand(enabled=False))  # not ours
    assert harness.drain() == [
        BusEvent(SPACE.mission_targets(3), MISSION),
        BusEvent(SPACE.opm(UAV), OpmCommand(enabled=False, status_rate_hz=0.0)),
    ]


def test_a_bad_message_is_dropped_and_logged(
    harness: Harness, caplog: pytest.LogCaptureFixture
) -> None:
    harness.drain()
    with caplog.at_level(logging.WARNING, logger="onboard.bus_edge"):
        harness.ground.put(SPACE.mission_targets(4), b'{"mission": "four"}')
        harness.ground.put(SPACE.mission_result(4, 74), b"\xff not json")
    assert harness.drain() == []
    assert "fleet/mission/4/targets: not a valid MissionTargets" in caplog.text
    assert "fleet/mission/4/result/74: not a valid UavResult" in caplog.text


def test_fetch_replies_arrive_like_publications_marked_replayed(harness: Harness) -> None:
    harness.drain()
    result = UavResult(mission=3, uav=74, times=(12.5,))
    answers = harness.ground.declare_queryable(SPACE.mission_result(3, 74))
    harness.node.fetch(SPACE.mission_results(3), UavResult)
    query = answers.try_recv()
    assert query is not None and query.intersects(SPACE.mission_result(3, 74))
    query.reply(SPACE.mission_result(3, 74), result)
    query.drop()
    # Marked: a mission learnt this way may be under way (the core then asks what the
    # team decided on it); one heard live is not.
    assert harness.drain() == [BusEvent(SPACE.mission_result(3, 74), result, replayed=True)]


def test_queries_to_it_wait_for_its_loop(harness: Harness) -> None:
    answers: list[str] = []
    harness.ground.get(SPACE.state(UAV), lambda sample: answers.append(sample.key), timeout=1.0)
    query = harness.node.state_queries.try_recv()
    assert query is not None and query.key == SPACE.state(UAV)
    assert harness.node.state_queries.try_recv() is None
    query.reply_bytes(SPACE.state(UAV), b"{}")
    assert answers == [SPACE.state(UAV)]


def test_close_withdraws_the_token(harness: Harness) -> None:
    seen: list[tuple[str, bool]] = []
    harness.ground.subscribe_presence(SPACE.all_alive, lambda key, alive: seen.append((key, alive)))
    harness.node.close()
    assert seen == [(SPACE.alive(UAV), True), (SPACE.alive(UAV), False)]


def _report(uav: int, mission: int = 3, **changes: object) -> AssignmentReport:
    fields: dict[str, object] = {
        "mission": mission, "uav": uav, "target": 0, "pairs": {uav: 0},
        "unassigned": (), "team": (UAV, 74), "digest": "d",
    }  # fmt: skip
    fields.update(changes)
    return AssignmentReport(**fields)  # type: ignore[arg-type]


def test_a_settled_uav_drops_reports_that_change_nothing_on_their_header() -> None:
    network = MemoryNetwork()
    events: queue.SimpleQueue[BusEvent | PresenceEvent] = queue.SimpleQueue()
    mission_round = MissionRound(MISSION, UAV, 0.0)
    mission_round.add_result(UavResult(3, UAV, (10.0,)))
    mission_round.add_result(UavResult(3, 74, (20.0,)))
    mission_round.decide({UAV, 74})
    settled = mission_round.settled(aborted=False)
    node = BusEdge(UAV, network.bus(), events.put, settled=lambda: settled)
    ground = network.bus()
    try:
        while not events.empty():
            events.get_nowait()
        before = bus_codec.DROPPED.counts()
        # An epoch 0 on the re-plan key (no teammate puts one there) changes nothing.
        ground.publish(SPACE.mission_replan(3, 74), _report(74))
        assert events.empty()
        assert bus_codec.DROPPED.counts() == before
        replan = _report(74, epoch=1, released=(UAV,))  # a re-plan: it matters
        ground.publish(SPACE.mission_replan(3, 74), replan)
        assert events.get_nowait() == BusEvent(SPACE.mission_replan(3, 74), replan)
        newer = _report(74, mission=4)
        ground.publish(SPACE.mission_replan(4, 74), newer)
        assert events.get_nowait() == BusEvent(SPACE.mission_replan(4, 74), newer)
        # A header its key does not vouch for, or that does not decode, is refused and
        # counted as before: on the full decode.
        ground.publish(SPACE.mission_replan(3, 75), _report(74))
        ground.put(SPACE.mission_replan(3, 74), b'{"mission": 3, "uav": "74"}')
        assert events.empty()
        after = bus_codec.DROPPED.counts()
        assert after.get("wrong_key", 0) == before.get("wrong_key", 0) + 1
        assert after.get("invalid", 0) == before.get("invalid", 0) + 1
    finally:
        node.close()
        ground.close()


def test_a_uav_hears_its_teammates_re_plans_live_and_their_commitments_by_query() -> None:
    network = MemoryNetwork()
    events: queue.SimpleQueue[BusEvent | PresenceEvent] = queue.SimpleQueue()
    node = BusEdge(UAV, network.bus(), events.put)
    teammate = network.bus()
    commitment = _report(74)
    served = teammate.declare_queryable(SPACE.mission_assignment(3, 74))
    try:
        while not events.empty():
            events.get_nowait()
        teammate.publish(SPACE.mission_assignment(3, 74), commitment)
        assert events.empty()  # N - 1 of these per mission would reach every UAV
        replan = _report(74, epoch=1, released=(UAV,))
        teammate.publish(SPACE.mission_replan(3, 74), replan)
        assert events.get_nowait() == BusEvent(SPACE.mission_replan(3, 74), replan)
        node.fetch(SPACE.mission_assignments(3), AssignmentReport)
        query = served.try_recv()
        assert query is not None
        query.reply(SPACE.mission_assignment(3, 74), commitment)
        query.drop()
        assert events.get_nowait() == BusEvent(
            SPACE.mission_assignment(3, 74), commitment, replayed=True
        )
    finally:
        served.undeclare()
        node.close()
        teammate.close()
