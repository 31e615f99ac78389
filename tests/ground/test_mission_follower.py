"""Following a mission that gets superseded: `MissionFollower` against a real router
on loopback, with other Zenoh sessions standing in for another ground and the UAVs."""

from __future__ import annotations

from fleet.mission.claims import reached_by
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, TargetOutcome, UavResult
from fleet.mission.phase import Phase
from fleet.transport import bus_codec
from fleet.transport.memory import MemoryNetwork
from fleet.transport.zenoh_bus import ZenohBus
from ground.mission_follower import MissionFollower
from ground.mission_ids import TargetsServer
from tests.ground.memory_fleet import MemoryUav
from tests.ground.mission_samples import (
    TIMEOUT_S,
    mission,
)
from tests.support.waiting import wait_until

SPACE = KeySpace()


def test_a_later_mission_for_the_team_supersedes_the_followed_one(
    session: ZenohBus, rival: ZenohBus
) -> None:
    with MissionFollower(session, SPACE, 40, team=(7, 8)) as follower:
        # Another team's later mission is no concern of this one.
        rival.session.put(
            SPACE.mission_targets(41),
            bus_codec.encode(mission(41, team=(9,))),
            encoding=bus_codec.ENCODING,
        )

        def put_later_mission() -> bool:
            # Put again until heard: the follower's subscription reaches the router
            # asynchronously, and a put before it arrives is not delivered.
            rival.session.put(
                SPACE.mission_targets(43),
                bus_codec.encode(mission(43, team=(8, 9))),
                encoding=bus_codec.ENCODING,
            )
            return follower.wait_superseded(0.2, fetch_every_s=1.0) is not None

        wait_until(put_later_mission, 10.0, "the later mission")
        assert follower.superseded_by == 43
        # Waiting for commitments of a superseded mission ends at once.
        assert follower.wait_committed((7, 8), timeout_s=30.0, fetch_every_s=1.0) is False


def test_a_later_mission_the_uavs_serve_is_found_by_the_fetch(
    session: ZenohBus, rival: ZenohBus
) -> None:
    with MissionFollower(session, SPACE, 50, team=(7,)) as follower:
        with TargetsServer(rival, SPACE, mission(52, team=(7,))):
            follower.fetch(TIMEOUT_S)
        assert follower.superseded_by == 52
        follower.note_later_mission(51)  # an older later one changes nothing
        assert follower.superseded_by == 52


# ---- on the in-memory bus -------------------------------------------------------------------
def test_results_and_commitments_are_collected_and_a_lost_uav_is_not_waited_for() -> None:
    network = MemoryNetwork()
    seven, eight = MemoryUav(network, 7), MemoryUav(network, 8)
    heard: list[str] = []
    with MissionFollower(network.bus(), SPACE, 60, lambda kind, _: heard.append(kind), (7, 8)) as f:
        seven.bus.publish(SPACE.mission_result(60, 7), UavResult(60, 7, (1.0,)))
        report = AssignmentReport(60, 7, 0, {7: 0}, (), (7,), "d")
        seven.bus.publish(SPACE.mission_assignment(60, 7), report)
        assert heard == ["result", "assignment"]
        assert f.wait_committed((7, 8), timeout_s=0.1, fetch_every_s=0.05) is False
        eight.leave()
        assert f.lost == {8}
        assert f.wait_committed((7, 8), timeout_s=0.1, fetch_every_s=0.05) is True


def test_a_fetch_collects_what_the_uavs_serve() -> None:
    network = MemoryNetwork()
    result = UavResult(61, 7, (2.0, 3.0))
    MemoryUav(network, 7).fly(mission(61), result)
    with MissionFollower(network.bus(), SPACE, 61) as follower:
        follower.fetch(0.1)
        assert follower.snapshot() == ({7: result}, {})
        assert follower.superseded_by is None


def test_a_teammates_word_is_a_hint_and_the_uavs_own_outcome_is_fetched_by_name() -> None:
    """7 says 8 reached target 1: not believed; the follower asks for 8's own outcome by
    name (8 is gone: a teammate relays it), and believes it from that."""
    network = MemoryNetwork()
    seven = MemoryUav(network, 7)
    relayed = TargetOutcome(62, 8, 1, Phase.REACHED, reached={1: 8})
    seven.serve(SPACE.mission_outcome(62, 8), relayed)
    with MissionFollower(network.bus(), SPACE, 62) as follower:
        follower.add_outcome(TargetOutcome(62, 7, 0, Phase.REACHED, reached={0: 7, 1: 8}))
        assert reached_by(follower.outcome_snapshot().values()) == {0: 7}
        follower.fetch(0.1)
        assert follower.outcome_snapshot()[8] == relayed
        assert reached_by(follower.outcome_snapshot().values()) == {0: 7, 1: 8}
        # An older copy of 8's outcome (claiming less) does not replace it.
        follower.add_outcome(TargetOutcome(62, 8, 3, Phase.REACHED, reached={3: 8, 1: 8}))
        follower.add_outcome(TargetOutcome(62, 8, 3, Phase.REACHED, reached={3: 8}))
        assert follower.outcome_snapshot()[8].reached == {3: 8, 1: 8}
