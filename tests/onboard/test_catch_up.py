"""Catching up with the team (onboard.catch_up): after a freeze, a late join, a
catch-up asked too soon."""

from __future__ import annotations

import pytest

from fleet.consensus.mission_round import JOIN_GRACE_S
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.piccolo.waypoint import Waypoint
from onboard.catch_up import CatchUp
from onboard.core import (
    CATCH_UP_INTERVAL_S,
)
from tests.onboard.core_harness import (
    TARGETS,
    Recorder,
    make_core,
)
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()


@pytest.mark.parametrize("tick_first", [False, True])
def test_a_mission_heard_live_just_after_a_freeze_asks_the_team_at_once(
    tick_first: bool,
) -> None:
    # Frozen while the mission was sent: it arrives live but late, before or after the
    # first tick that notices the freeze, and the team committed meanwhile.
    core, out = make_core(74)
    core.on_alive(112, True, 0.0)
    core.tick(0.0)
    if tick_first:
        core.tick(20.0)
    mission = MissionTargets(mission=8, team=(74, 112), targets=TARGETS)
    core.on_targets(mission, 20.1)
    assert 8 in out.assignment_fetches
    committed = AssignmentReport(8, 112, 1, {74: 0, 112: 1}, (2,), (74, 112), "abc")
    core.on_result(UavResult(8, 112, (50.0, 10.0, 50.0)), 20.15)
    core.on_assignment(committed, 20.2)  # the answer
    (report,) = out.on(SPACE.mission_assignment(8, 74))
    assert isinstance(report, AssignmentReport) and report.digest == "abc"


def test_a_uav_back_from_a_freeze_adopts_the_team_decision_made_without_it() -> None:
    # The answer comes late (a loaded machine): this UAV holds every result by then,
    # its own too, and still falls in line with what the team decided while it was away.
    core, out = make_core(74, (5.0, 50.0, 50.0))
    core.on_alive(112, True, 0.0)
    core.tick(0.0)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 20.0)
    core.on_result(UavResult(8, 112, (50.0, 10.0, 50.0)), 20.1)
    core.tick(20.2)  # its own result; it asks before deciding
    without = AssignmentReport(8, 112, 0, {112: 0}, (1, 2), (112,), "without-74")
    core.on_assignment(without, 20.2 + JOIN_GRACE_S + 0.1)
    (report,) = out.on(SPACE.mission_assignment(8, 74))
    assert isinstance(report, AssignmentReport) and report.digest == "without-74"
    assert report.target is None


def test_a_mission_heard_live_in_the_normal_course_asks_nobody() -> None:
    core, out = make_core(74)
    for t in (0.0, 0.25, 0.5):
        core.tick(t)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.6)
    assert out.assignment_fetches == []


def test_a_mission_heard_live_asks_nobody_and_one_from_a_catch_up_asks_the_team() -> None:
    # Heard live, the mission is as new to the team as to this UAV: no queries while
    # everybody plans. Learnt from a catch-up, the team may have decided already.
    core, out = make_core(74)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.0)
    assert out.assignment_fetches == []
    core.on_targets(MissionTargets(mission=9, team=(74, 112), targets=TARGETS), 0.1, replayed=True)
    assert out.assignment_fetches == [9]


def test_a_teammates_result_for_a_mission_not_heard_asks_for_the_live_missions() -> None:
    # The mission's put never reached this UAV (a router that may not relay it), but a
    # teammate's result for it did: a catch-up's query brings the mission.
    core, out = make_core(74)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.0)
    fetched = out.mission_fetches
    core.on_result(UavResult(8, 112, (50.0, 10.0, 50.0)), 0.1)
    assert out.mission_fetches == fetched  # the current mission's: nothing to ask
    core.on_result(UavResult(9, 112, (50.0, 10.0, 50.0)), 10.0)
    assert out.mission_fetches == fetched + 1
    core.on_targets(MissionTargets(mission=9, team=(74, 112), targets=TARGETS), 10.2, replayed=True)
    assert out.assignment_fetches[-1] == 9  # learnt late: the team may have decided


def test_a_catch_up_during_a_round_asks_for_its_assignments_committed_or_not() -> None:
    # A UAV frozen while the mission was sent hears it live, late: its catch-ups after
    # the freeze must still bring what the team decided meanwhile.
    core, out = make_core(74)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.0)
    core.catch_up(0.1, force=True)
    assert out.assignment_fetches == [8]


def test_a_module_suspended_for_a_while_catches_up_at_once_when_it_runs_again() -> None:
    core, out = make_core()
    core.on_alive(74, True, 0.0)  # a catch-up at 0 s: the next is rate-limited
    fetched = out.mission_fetches
    core.tick(0.1)
    core.tick(0.2)
    assert out.mission_fetches == fetched
    core.tick(3.5)  # frozen (SIGSTOP) for 3.3 s: a mission and its abort may be missed
    assert out.mission_fetches == fetched + 1
    for step in range(36, 80):  # and twice more, in case the first query went unanswered
        core.tick(step / 10)
    assert out.mission_fetches == fetched + 3


def test_a_catch_up_asked_too_soon_after_another_is_deferred_not_dropped() -> None:
    # Resumed after Zenoh's lease: the forced catch-ups may go out before the session has
    # reconnected; the teammates reappearing afterwards must still bring a catch-up.
    core, out = make_core()
    core.catch_up(0.0, force=True)
    fetched = out.mission_fetches
    core.on_alive(74, True, 1.0)  # rate-limited: due at 0 + CATCH_UP_INTERVAL_S
    core.on_alive(75, True, 1.5)  # the same deferred catch-up
    assert out.mission_fetches == fetched
    core.tick(CATCH_UP_INTERVAL_S - 0.1)
    assert out.mission_fetches == fetched
    core.tick(CATCH_UP_INTERVAL_S)
    core.tick(CATCH_UP_INTERVAL_S + 0.25)
    assert out.mission_fetches == fetched + 1


def test_a_catch_up_asks_for_the_current_missions_assignments_too() -> None:
    out = Recorder()
    mission: list[int | None] = [None]
    catch_up = CatchUp(out, lambda: mission[0])
    catch_up.request(0.0)
    assert (out.mission_fetches, out.assignment_fetches) == (1, [])
    mission[0] = 4
    catch_up.request(CATCH_UP_INTERVAL_S, force=True)
    assert (out.mission_fetches, out.assignment_fetches) == (2, [4])


def test_a_round_open_across_a_freeze_waits_for_the_team_so_a_queued_abort_is_final() -> None:
    # Frozen holding its own result; meanwhile the teammate's result and the mission's
    # abort were sent. On resume the result is handled, then a tick comes before the
    # abort (still in the bus session's backlog): the decision must not go ahead.
    core, out = make_core(74, (5.0, 50.0, 50.0))
    core.on_alive(112, True, 0.0)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.0)
    core.tick(0.1)  # its own result is published; 112's is awaited
    assert core.round is not None and core.round.results.keys() == {74}
    fetches = len(out.assignment_fetches)
    core.on_telemetry(sample_telemetry(), 6.1)
    core.on_result(UavResult(8, 112, (50.0, 10.0, 50.0)), 6.1)  # the first event after it
    core.tick(6.15)  # ready to decide, but it asked the team what it missed: it waits
    assert core.round.committed is None
    # The catch-up's question (the abort's relay among its answers), then the decision's
    # own: asked when the round is ready, which a reconnecting session still answers.
    assert out.assignment_fetches[fetches:] == [8, 8]
    core.on_abort(MissionAbort(8), 6.2)  # the backlog's abort
    for step in range(25, 60):
        core.tick(6.0 + step / 10)
    assert core.phase == Phase.ABORTED
    assert core.round.committed is None
    assert not out.on(SPACE.mission_assignment(8, 74))
    assert not any(isinstance(c, Waypoint) for c in out.autopilot)
