"""A re-plan solved again from the survivors' fresh standings (fleet.consensus.resolve),
as one UAV's module runs it: it waits for every survivor's standing, commits the plan of
what is left from their times, falls back to the append rule when one is overdue, takes
a late one, and adopts a teammate's resolved plan it could not compute."""

from __future__ import annotations

import math

import msgspec

from fleet.consensus.mission_round import STANDINGS_WAIT_S
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, TargetOutcome, UavResult
from fleet.mission.phase import Phase
from onboard.core import OnboardCore
from tests.onboard.core_harness import TARGETS, Recorder, make_core, round_of_three
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()


def _three_uav_plan(
    times: tuple[float, ...] = (80.0, 40.0, 60.0),
    times_200: tuple[float, ...] = (50.0, 50.0, 50.0),
) -> tuple[OnboardCore, Recorder]:
    """112 (this core: `times`), 74 (10, 90, 90 s), 200 (`times_200`): one target each,
    74 target 0, 112 target 1, 200 target 2."""
    core, out = make_core(uav=112, times=times, fresh_replans=True)
    round_of_three(core, (10.0, 90.0, 90.0), times_200)
    (report,) = out.on(SPACE.mission_assignment(1, 112))
    assert isinstance(report, AssignmentReport)
    assert report.queues == {74: (0,), 112: (1,), 200: (2,)}
    return core, out


def _lose_74(core: OnboardCore, out: Recorder, now: float) -> UavResult:
    """74 is lost before it reached target 0; 200 has reached target 2. This UAV gives its
    standing (the scripted planner's times, flying target 1) and waits for 200's."""
    core.on_telemetry(sample_telemetry(), now)
    core.on_outcome(_reached(200, 2), now)
    core.on_alive(74, False, now)
    assert out.on(SPACE.mission_replan(1, 112)) == []  # waiting for 200's standing
    core.on_telemetry(sample_telemetry(), now + 0.1)
    core.tick(now + 0.1)  # its own standing, from the planner
    (own,) = _standings(out)
    assert own.flying == 1 and own.reached == () and own.times == (80.0, 40.0, 60.0)
    assert out.on(SPACE.mission_replan(1, 112)) == []
    return own


def _reached(uav: int, target: int) -> TargetOutcome:
    return TargetOutcome(1, uav, target, Phase.REACHED)


def _standings(out: Recorder) -> list[UavResult]:
    """This UAV's standings published on its result key."""
    results = out.on(SPACE.mission_result(1, 112))
    return [m for m in results if isinstance(m, UavResult) and m.basis is not None]


def _standing_of_200(basis: str) -> UavResult:
    """200 is done with target 2 and has flown on to 5 s from target 0."""
    return UavResult(1, 200, (5.0, 70.0, 60.0), basis=basis, reached=(2,))


def test_the_orphan_goes_to_the_survivor_now_closest_by_its_fresh_times() -> None:
    core, out = _three_uav_plan()
    own = _lose_74(core, out, 6.0)
    assert own.basis is not None
    core.on_result(_standing_of_200(own.basis), 6.3)
    (replan,) = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(replan, AssignmentReport)
    assert replan.epoch == 1 and replan.released == (74,) and replan.basis == own.basis
    # From the epoch-0 times the append rule hands target 0 to 112 (after its own
    # target 1, at ~167 s, before 200 at ~172 s); from where they are now, 200 is 5 s away.
    assert replan.queues == {112: (1,), 200: (0,)}
    assert replan.arrivals[200] == (5.0,)
    assert replan.unassigned == ()


def test_without_a_survivors_standing_the_append_plan_is_committed_when_the_wait_is_over() -> None:
    core, out = _three_uav_plan()
    own = _lose_74(core, out, 6.0)
    core.on_telemetry(sample_telemetry(), 6.0 + STANDINGS_WAIT_S - 0.2)
    core.tick(6.0 + STANDINGS_WAIT_S - 0.2)
    assert out.on(SPACE.mission_replan(1, 112)) == []
    core.on_telemetry(sample_telemetry(), 6.1 + STANDINGS_WAIT_S)
    core.tick(6.1 + STANDINGS_WAIT_S)
    (fallback,) = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(fallback, AssignmentReport)
    assert fallback.basis is None and fallback.digest == own.basis
    assert fallback.queues == {112: (1, 0), 200: (2,)}  # the append rule
    assert out.assignment_fetches[-1] == 1  # a teammate may have resolved it: asked
    # 200's standing comes late: the plan is solved again with it.
    assert own.basis is not None
    core.on_result(_standing_of_200(own.basis), 9.5)
    *_, resolved = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(resolved, AssignmentReport)
    assert resolved.basis == own.basis and resolved.queues == {112: (1,), 200: (0,)}


def test_a_teammates_resolved_plan_of_the_awaited_epoch_is_adopted() -> None:
    core, out = _three_uav_plan()
    own = _lose_74(core, out, 6.0)
    assert own.basis is not None
    theirs = AssignmentReport(
        mission=1,
        uav=200,
        target=0,
        pairs={112: 1, 200: 0},
        unassigned=(),
        team=(74, 112, 200),
        digest="0123456789abcdef",
        epoch=1,
        released=(74,),
        queues={112: (1,), 200: (0,)},
        arrivals={112: (40.0,), 200: (5.0,)},
        basis=own.basis,
    )
    core.on_assignment(theirs, 6.4)
    (adopted,) = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(adopted, AssignmentReport)
    assert (adopted.digest, adopted.queues, adopted.uav) == (theirs.digest, theirs.queues, 112)
    # Another basis (an epoch this UAV does not hold) is not adopted.
    other = msgspec.structs.replace(theirs, basis="fedcba9876543210", digest="1111111111111111")
    core.on_assignment(other, 6.5)
    assert len(out.on(SPACE.mission_replan(1, 112))) == 1


def test_a_uav_whose_autopilot_link_is_lost_gives_no_standing_and_the_append_plan_stands() -> None:
    core, out = _three_uav_plan()
    core.on_outcome(_reached(200, 2), 6.0)
    core.on_alive(74, False, 6.0)  # no telemetry since 0 s: its link is lost
    assert not _standings(out)
    core.tick(6.1 + STANDINGS_WAIT_S)
    (fallback,) = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(fallback, AssignmentReport) and fallback.basis is None


# ---- a finished UAV on the append fallback --------------------------------------------
def _finished_200_plan(
    times: tuple[float, ...] = (80.0, 40.0, 60.0),
) -> tuple[OnboardCore, Recorder]:
    """As `_three_uav_plan`, but 200 is 15 s from target 2: the append rule's clock has
    it, once at target 2, the earliest at target 0 (its epoch-0 times, from the start)."""
    return _three_uav_plan(times, times_200=(50.0, 50.0, 15.0))


def _wait_out(core: OnboardCore, out: Recorder, since: float) -> AssignmentReport:
    """The standings' wait passes without 200's: the append plan is committed."""
    now = since + STANDINGS_WAIT_S + 0.1
    core.on_telemetry(sample_telemetry(), now)
    core.tick(now)
    fallback = out.on(SPACE.mission_replan(1, 112))[-1]
    assert isinstance(fallback, AssignmentReport) and fallback.basis is None
    return fallback


def test_on_the_append_fallback_a_finished_uav_is_not_handed_an_orphan_a_busy_one_can_fly() -> None:
    core, out = _finished_200_plan()
    core.on_telemetry(sample_telemetry(), 6.0)
    core.on_outcome(_reached(200, 2), 6.0)  # 200's queue is done
    core.on_alive(74, False, 6.0)
    core.tick(6.1)  # its own standing; 200 (done, its link to the team slow) gives none
    fallback = _wait_out(core, out, 6.1)
    # Its epoch-0 times put 200 first at target 0 after target 2, long flown; done, it
    # is no holder of a later epoch's orphan unless it gives fresh times.
    assert fallback.queues == {112: (1, 0), 200: (2,)}


def test_a_finished_uav_alone_able_to_reach_an_orphan_takes_it_on_the_fallback() -> None:
    """Dropping a target is worse than a holder timed from old times: the last resort."""
    core, out = _finished_200_plan(times=(math.inf, 40.0, 60.0))
    core.on_telemetry(sample_telemetry(), 6.0)
    core.on_outcome(_reached(200, 2), 6.0)
    core.on_alive(74, False, 6.0)
    core.tick(6.1)
    fallback = _wait_out(core, out, 6.1)
    assert fallback.queues == {112: (1,), 200: (2, 0)} and fallback.unassigned == ()


def test_an_arrival_heard_during_the_wait_moves_the_fallback_and_its_standing() -> None:
    """200 finished its queue just as 74 was lost: a UAV that heard the loss first
    computes the append plan again when it hears the arrival, as 200 itself did, so
    both wait for standings of one plan."""
    core, out = _finished_200_plan()
    core.on_telemetry(sample_telemetry(), 6.0)
    core.on_alive(74, False, 6.0)
    core.tick(6.05)
    (first,) = _standings(out)
    core.on_outcome(_reached(200, 2), 6.1)
    core.tick(6.15)
    _, second = _standings(out)
    assert second.basis != first.basis  # a standing for the moved plan too
    fallback = _wait_out(core, out, 6.1)
    assert fallback.digest == second.basis
    assert fallback.queues == {112: (1, 0), 200: (2,)}


# ---- standings fetched by query ---------------------------------------------------------
def test_a_standing_still_missing_a_second_into_the_wait_is_asked_for_once() -> None:
    core, out = _three_uav_plan()
    own = _lose_74(core, out, 6.0)
    core.tick(6.5)
    assert out.standing_fetches == []  # it may be on its way
    core.tick(7.2)
    core.tick(7.5)
    assert out.standing_fetches == [(1, (200,), own.basis)]  # 200's own, for this plan
    assert own.basis is not None
    core.on_result(_standing_of_200(own.basis), 7.6)  # the answer: solved at once
    (resolved,) = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(resolved, AssignmentReport) and resolved.basis == own.basis


def test_a_restarted_uav_stands_for_the_plan_its_teammates_standings_name() -> None:
    """Back from a restart it follows its teammates' epochs (no epoch 0 of its own), and
    the one it takes counts it out: it asks for their standings and gives its own for
    the append plan they name, so they solve the re-plan with it without waiting for
    their append plan's wait to pass."""
    core, out = make_core(uav=200, times=(5.0, 70.0, 60.0), fresh_replans=True)
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    targets = MissionTargets(mission=1, team=(74, 112, 200), targets=TARGETS)
    core.on_targets(targets, 0.5, replayed=True)  # its catch-up's reply
    epoch_1 = AssignmentReport(
        1, 112, 1, {74: 0, 112: 1}, (2,), (74, 112, 200), "e1", epoch=1, released=(200,),
        queues={74: (0, 2), 112: (1,)}, basis="b0",
    )  # fmt: skip
    core.on_assignment(epoch_1, 0.6)
    assert out.standing_fetches == [(1, (), None)]  # the standings of the plan awaited
    assert _standings_of(out, 200) == []
    theirs = UavResult(1, 112, (80.0, 40.0, 60.0), basis="b1", flying=1)
    core.on_result(theirs, 0.7)  # 112's standing, for the append plan counting 200 back
    core.on_telemetry(sample_telemetry(), 0.8)
    core.tick(0.8)  # its own, from the planner
    (own,) = _standings_of(out, 200)
    assert own.basis == "b1" and own.times == (5.0, 70.0, 60.0)
    resolved = msgspec.structs.replace(
        epoch_1, epoch=2, released=(), digest="e2", basis="b1", back={200: 1}, left={200: 1},
        pairs={74: 2, 112: 1, 200: 0}, queues={74: (2,), 112: (1,), 200: (0,)},
    )  # fmt: skip
    core.on_assignment(resolved, 1.0)
    mine = out.on(SPACE.mission_assignment(1, 200))[-1]
    assert isinstance(mine, AssignmentReport) and (mine.digest, mine.target) == ("e2", 0)


def test_a_restarted_uav_without_telemetry_yet_stands_once_it_has_some() -> None:
    core, out = make_core(uav=200, times=(5.0, 70.0, 60.0), fresh_replans=True)
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=1, team=(74, 112, 200), targets=TARGETS), 9.0)
    epoch_1 = AssignmentReport(
        1, 112, 1, {74: 0, 112: 1}, (2,), (74, 112, 200), "e1", epoch=1, released=(200,),
        queues={74: (0, 2), 112: (1,)},
    )  # fmt: skip
    core.on_assignment(epoch_1, 9.1)
    core.on_result(UavResult(1, 74, (10.0, 90.0, 90.0), basis="b1"), 9.2)
    core.tick(9.3)  # its last telemetry was at 0 s: its link is lost, no standing yet
    assert _standings_of(out, 200) == []
    core.on_telemetry(sample_telemetry(), 9.5)
    core.tick(9.5)
    core.tick(9.6)
    (own,) = _standings_of(out, 200)
    assert own.basis == "b1"


def _standings_of(out: Recorder, uav: int) -> list[UavResult]:
    results = out.on(SPACE.mission_result(1, uav))
    return [m for m in results if isinstance(m, UavResult) and m.basis is not None]
