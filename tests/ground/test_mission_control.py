"""Mission ids two grounds cannot share, and a superseded mission reported as such:
`claim_mission` and `MissionFollower` against a real router on loopback, with other
Zenoh sessions of this process standing in for another ground and for the UAVs."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterator

import pytest
import zenoh

from fleet.mission import keys
from fleet.mission.messages import AssignmentReport, MissionTargets, Target, TargetOutcome
from fleet.mission.phase import Phase
from fleet.transport import bus_codec
from fleet.transport.zenoh_config import make_config
from ground.cli import _summary
from ground.mission_control import (
    MissionError,
    MissionFollower,
    MissionOutcome,
    TargetsServer,
    claim_mission,
    rival_claims,
)
from tests.processes import wait_until

TIMEOUT_S = 1.0
TARGETS = (Target(42.36, -71.09, 120.0), Target(42.365, -71.10, 110.0))
OTHER_TARGETS = (Target(42.37, -71.08, 150.0),)


@pytest.fixture
def session(router: str) -> Iterator[zenoh.Session]:
    opened = zenoh.open(make_config("client", [router]))
    try:
        yield opened
    finally:
        opened.close()


@pytest.fixture
def rival(router: str) -> Iterator[zenoh.Session]:
    """Another ground's session."""
    opened = zenoh.open(make_config("client", [router]))
    try:
        yield opened
    finally:
        opened.close()


def mission(
    m: int, targets: tuple[Target, ...] = TARGETS, team: tuple[int, ...] = (7, 8)
) -> MissionTargets:
    return MissionTargets(mission=m, team=team, targets=targets)


def maker(targets: tuple[Target, ...]) -> Callable[[int], MissionTargets]:
    def make(m: int) -> MissionTargets:
        return mission(m, targets)

    return make


# ---- the outcome -----------------------------------------------------------------------
def test_a_superseded_mission_is_no_success_even_when_agreed() -> None:
    outcome = MissionOutcome(mission=3, team=(), targets=TARGETS)
    assert outcome.to_json()["superseded_by"] is None
    outcome.superseded_by = 5
    report = outcome.to_json()
    assert report["superseded_by"] == 5
    assert report["success"] is False


# ---- claiming an id --------------------------------------------------------------------
def test_a_fresh_key_space_is_claimed_at_once_and_served_while_open(
    session: zenoh.Session, rival: zenoh.Session
) -> None:
    with claim_mission(session, lambda m: mission(m), TIMEOUT_S, mission=901) as server:
        assert server.targets == mission(901)
        # Served to others while claimed: a second ground sees the claim as a rival.
        assert rival_claims(rival, mission(901, OTHER_TARGETS), TIMEOUT_S) == 1
        # The same content is no rival (a UAV holding this very mission, say).
        assert rival_claims(rival, mission(901), TIMEOUT_S) == 0
    assert rival_claims(rival, mission(901, OTHER_TARGETS), TIMEOUT_S) == 0


def test_a_given_mission_id_another_ground_serves_is_refused(
    session: zenoh.Session, rival: zenoh.Session
) -> None:
    with (
        TargetsServer(rival, mission(902, OTHER_TARGETS)),
        pytest.raises(MissionError, match="902 is already in use"),
        claim_mission(session, lambda m: mission(m), TIMEOUT_S, mission=902),
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
        self._queryable = session.declare_queryable(keys.ALL_MISSION_TARGETS, self._on_query)

    def _on_query(self, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        if "*" in key:
            return
        m = keys.mission_of(key)
        if m not in self.asked:
            self.asked.append(m)
        if self.asked.index(m) < self._limit:
            reply = mission(m, OTHER_TARGETS)
            query.reply(key, bus_codec.encode(reply), encoding=bus_codec.ENCODING)

    def close(self) -> None:
        self._queryable.undeclare()


def test_a_collision_moves_on_to_a_higher_id_and_says_so(
    session: zenoh.Session, rival: zenoh.Session, caplog: pytest.LogCaptureFixture
) -> None:
    squatter = Squatter(rival, limit=1)
    caplog.set_level(logging.WARNING, logger="ground.mission_control")
    try:
        with claim_mission(session, lambda m: mission(m), TIMEOUT_S) as server:
            chosen = server.targets.mission
    finally:
        squatter.close()
    first = squatter.asked[0]
    assert first < chosen <= first + 4, squatter.asked
    assert squatter.asked == [first, chosen]
    assert f"mission {first}: another ground chose it too" in caplog.text
    assert f"mission {chosen}: claimed at attempt 2" in caplog.text


def test_running_out_of_attempts_is_an_error(session: zenoh.Session, rival: zenoh.Session) -> None:
    squatter = Squatter(rival, limit=1000)
    try:
        with (
            pytest.raises(MissionError, match="no free mission id after 3 attempts"),
            claim_mission(session, lambda m: mission(m), TIMEOUT_S, attempts=3),
        ):
            pass
    finally:
        squatter.close()
    assert len(squatter.asked) == 3
    assert squatter.asked == sorted(squatter.asked)


def test_two_grounds_claiming_together_get_different_ids(router: str) -> None:
    sessions = [zenoh.open(make_config("client", [router])) for _ in range(2)]
    try:
        for _ in range(3):
            claimed = claim_together(sessions)
            assert len(claimed) == 2 and claimed[0] != claimed[1], claimed
    finally:
        for opened in sessions:
            opened.close()


def claim_together(sessions: list[zenoh.Session]) -> dict[int, int]:
    """Two grounds claim at the same moment, each holding its claim until both have one."""
    start = threading.Barrier(2)
    held = threading.Barrier(3)
    claimed: dict[int, int] = {}

    def claim(index: int) -> None:
        targets = TARGETS if index == 0 else OTHER_TARGETS
        start.wait()
        with claim_mission(sessions[index], maker(targets), TIMEOUT_S) as server:
            claimed[index] = server.targets.mission
            held.wait(30)

    threads = [threading.Thread(target=claim, args=(i,)) for i in range(2)]
    for thread in threads:
        thread.start()
    held.wait(30)
    for thread in threads:
        thread.join(30)
    return claimed


# ---- following a mission that gets superseded -------------------------------------------
def test_a_later_mission_for_the_team_supersedes_the_followed_one(
    session: zenoh.Session, rival: zenoh.Session
) -> None:
    with MissionFollower(session, 40, team=(7, 8)) as follower:
        # Another team's later mission is no concern of this one.
        rival.put(
            keys.mission_targets(41),
            bus_codec.encode(mission(41, team=(9,))),
            encoding=bus_codec.ENCODING,
        )

        def put_later_mission() -> bool:
            # Put again until heard: the follower's subscription reaches the router
            # asynchronously, and a put before it arrives is not delivered.
            rival.put(
                keys.mission_targets(43),
                bus_codec.encode(mission(43, team=(8, 9))),
                encoding=bus_codec.ENCODING,
            )
            return follower.wait_superseded(0.2) is not None

        wait_until(put_later_mission, 10.0, "the later mission")
        assert follower.superseded_by == 43
        # Waiting for commitments of a superseded mission ends at once.
        assert follower.wait_committed((7, 8), timeout_s=30.0, fetch_every_s=1.0) is False


def test_a_later_mission_the_uavs_serve_is_found_by_the_fetch(
    session: zenoh.Session, rival: zenoh.Session
) -> None:
    with MissionFollower(session, 50, team=(7,)) as follower:
        with TargetsServer(rival, mission(52, team=(7,))):
            follower.fetch(TIMEOUT_S)
        assert follower.superseded_by == 52
        follower.note_later_mission(51)  # an older later one changes nothing
        assert follower.superseded_by == 52


def test_the_summary_says_superseded() -> None:
    outcome = MissionOutcome(mission=2, team=(7,), targets=TARGETS, superseded_by=3)
    assert "  SUPERSEDED by mission 3: the team no longer flies mission 2" in _summary(outcome)


def test_after_a_re_plan_a_target_belongs_to_its_latest_epoch_holder() -> None:
    def report(uav: int, target: int | None, epoch: int) -> AssignmentReport:
        pairs = {"101": 0, "102": 1} if epoch == 0 else {"102": 1, "103": 0}
        released = () if epoch == 0 else (101,)
        return AssignmentReport(
            1, uav, target, pairs, (), (101, 102, 103), "d", epoch=epoch, released=released
        )

    outcome = MissionOutcome(mission=1, team=(101, 102, 103), targets=TARGETS)
    outcome.assignments = {101: report(101, 0, 0), 102: report(102, 1, 1), 103: report(103, 0, 1)}
    outcome.lost = {101}
    assert outcome.epoch == 1
    assert outcome.holders() == {0: 103, 1: 102}
    states = {s["index"]: s for s in outcome.target_states()}
    assert states[0] == {"index": 0, "state": "assigned", "uav": 103}
    outcome.outcomes = {103: TargetOutcome(1, 103, 0, Phase.REACHED)}
    assert outcome.target_states()[0] == {"index": 0, "state": "reached", "uav": 103}
    assert outcome.succeeded
