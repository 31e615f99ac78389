"""Taking part in a mission (onboard.mission_participation): targets, results, the
decision, re-plans, adoption, abort; driven through the whole core with a recording
Outputs and a scripted planner (tests.onboard.core_harness)."""

from __future__ import annotations

import msgspec

from fleet.consensus.mission_change import next_revision
from fleet.consensus.mission_round import ASK_GRACE_S
from fleet.consensus.targets_digest import targets_digest
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.core import (
    LINK_LOST_S,
    LIVELINESS_GRACE_S,
    TARGET_WAYPOINT,
    OnboardCore,
)
from tests.onboard.core_harness import (
    TARGETS,
    TWO_TARGETS,
    Recorder,
    ScriptedPlanner,
    commit_four_uav_team,
    commit_three_uav_team,
    fly_target_1,
    make_core,
    run_with_telemetry,
    telemetry_at,
)
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()


def uav_200_given_two_targets(mission: int) -> tuple[OnboardCore, Recorder]:
    """UAV 200, its teammates 74 and 112 alive, given `mission` over two targets."""
    core, out = make_core(200, (30.0, 35.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=mission, team=(74, 112, 200), targets=TWO_TARGETS), 0.0)
    return core, out


def test_abort_while_waiting_for_a_teammate_is_final() -> None:
    core, out = make_core()
    core.on_alive(74, True, 0.0)
    core.on_targets(MissionTargets(mission=1, team=(74, 112), targets=TARGETS), 1.0)
    core.tick(1.1)  # own result out; waiting for 74
    core.on_abort(MissionAbort(1), 2.0)
    core.on_result(UavResult(1, 74, (10.0, 20.0, 30.0)), 3.0)
    for step in range(4, 30):
        core.on_telemetry(sample_telemetry(), float(step))
        core.tick(float(step))  # well past the 10 s deadline
    assert out.on(SPACE.mission_assignment(1, 112)) == []
    assert out.autopilot == []
    assert core.state(30.0).phase == Phase.ABORTED


def test_malformed_targets_are_refused_without_disturbing_the_mission() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.0)
    bad = (Target(float("nan"), 0.0, 0.0),)
    core.on_targets(MissionTargets(mission=2, team=(112,), targets=bad), 1.0)
    core.on_targets(MissionTargets(mission=3, team=(112,), targets=()), 1.0)
    core.on_targets(MissionTargets(mission=4, team=(112,), targets=(Target(95.0, 0, 0),)), 1.0)
    errors = [s for s in out.statuses() if s.startswith("error")]
    assert "target 0" in errors[0] and "latitude" in errors[0]
    assert "no targets" in errors[1]
    assert "outside [-90, 90]" in errors[2]
    assert core.round is not None and core.round.mission == 1


def test_team_waits_for_the_teammate_then_both_agree() -> None:
    core, out = make_core(112, (80.0, 40.0, 60.0))
    core.on_alive(74, True, 0.0)
    mission = MissionTargets(mission=5, team=(74, 112), targets=TARGETS, deadline_s=10.0)
    core.on_targets(mission, 0.0)
    core.tick(0.1)
    assert out.on(SPACE.mission_assignment(5, 112)) == []
    core.tick(1.2)
    assert out.fetches == [5]  # a missing result is fetched before it is given up on
    core.on_result(UavResult(5, 74, (50.0, 30.0, 70.0)), 1.3)
    core.tick(1.4)
    (report,) = out.on(SPACE.mission_assignment(5, 112))
    assert isinstance(report, AssignmentReport)
    assert report.pairs == {74: 1, 112: 2} and report.target == 2


def test_results_still_coming_push_the_fetch_back() -> None:
    core, out = make_core(112, (80.0, 40.0, 60.0))
    for uav in (74, 75):
        core.on_alive(uav, True, 0.0)
    mission = MissionTargets(mission=5, team=(74, 75, 112), targets=TARGETS, deadline_s=10.0)
    core.on_targets(mission, 0.0)
    core.tick(0.1)  # its own result published
    core.on_result(UavResult(5, 74, (50.0, 30.0, 70.0)), 0.9)
    core.tick(1.2)
    assert out.fetches == []  # 74's result just came: 75's may be on its way too
    core.tick(2.0)
    assert out.fetches == [5]  # an interval after the last result heard


def test_silent_teammate_is_dropped_at_the_deadline() -> None:
    core, out = make_core(112)
    core.on_alive(74, True, 0.0)
    core.on_targets(MissionTargets(mission=7, team=(74, 112), targets=TARGETS, deadline_s=3.0), 0.0)
    core.tick(2.9)
    assert out.on(SPACE.mission_assignment(7, 112)) == []
    core.tick(3.1)
    assert out.assignment_fetches == [7]  # the team is asked what it decided first
    assert out.on(SPACE.mission_assignment(7, 112)) == []
    core.tick(3.1 + ASK_GRACE_S)
    (report,) = out.on(SPACE.mission_assignment(7, 112))
    assert isinstance(report, AssignmentReport) and report.team == (112,) and report.target == 1
    assert any("without 74" in s for s in out.statuses())
    assert out.assignment_fetches == [7]


def test_at_the_deadline_a_teammates_commitment_with_the_missing_result_is_adopted() -> None:
    # 75's result reached 74 but not 112: 74 committed with it, and 112 falls in line.
    core, out = make_core(112, (80.0, 40.0, 60.0))
    for uav in (74, 75):
        core.on_alive(uav, True, 0.0)
    team = (74, 75, 112)
    core.on_targets(MissionTargets(mission=7, team=team, targets=TARGETS, deadline_s=3.0), 0.0)
    core.on_result(UavResult(7, 74, (10.0, 50.0, 50.0)), 0.5)
    core.tick(3.1)
    assert out.assignment_fetches == [7]
    pairs = {74: 0, 75: 1, 112: 2}
    committed = AssignmentReport(7, 74, 0, pairs, (), team, "with-75")
    core.on_assignment(committed, 3.2)  # the answer to the query
    (report,) = out.on(SPACE.mission_assignment(7, 112))
    assert isinstance(report, AssignmentReport)
    assert (report.digest, report.target) == ("with-75", 2)
    core.tick(3.1 + ASK_GRACE_S)
    assert len(out.on(SPACE.mission_assignment(7, 112))) == 1


def test_a_teammate_gone_before_its_result_reached_this_uav_makes_it_ask_first() -> None:
    # 112's result reached 74 but not 200, then 112 went away: 74 committed with it,
    # and 200, with nothing missing among the live, adopts that instead of deciding alone.
    core, out = make_core(200, (50.0, 15.0, 20.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    team = (74, 112, 200)
    core.on_targets(MissionTargets(mission=4, team=team, targets=TARGETS), 0.0)
    core.on_result(UavResult(4, 74, (10.0, 50.0, 50.0)), 0.1)
    core.tick(0.2)
    core.on_alive(112, False, 0.3)
    core.tick(0.4)
    assert out.assignment_fetches == [4]
    assert out.on(SPACE.mission_assignment(4, 200)) == []
    pairs = {74: 0, 112: 1, 200: 2}
    core.on_assignment(AssignmentReport(4, 74, 0, pairs, (), team, "with-112"), 0.5)
    (report,) = out.on(SPACE.mission_assignment(4, 200))
    assert isinstance(report, AssignmentReport) and report.digest == "with-112"


def test_a_restarted_uav_asks_again_before_deciding_on_its_new_times() -> None:
    # The team committed with 74's result from before its restart, after the query
    # 74 sent when the mission reached it by catch-up: 74 asks again before deciding.
    core, out = make_core(74, (5.0, 50.0, 50.0))
    core.on_alive(112, True, 0.0)
    team = (74, 112)
    mission = MissionTargets(mission=9, team=team, targets=TARGETS)
    core.on_targets(mission, 0.0, replayed=True)
    assert out.assignment_fetches == [9]
    core.tick(0.1)  # its new result
    core.on_result(UavResult(9, 112, (50.0, 50.0, 20.0)), 0.2)
    core.tick(0.3)
    assert out.assignment_fetches == [9, 9]
    assert out.on(SPACE.mission_assignment(9, 74)) == []
    old = AssignmentReport(9, 112, 2, {74: 1, 112: 2}, (0,), team, "old-times")
    core.on_assignment(old, 0.4)
    (report,) = out.on(SPACE.mission_assignment(9, 74))
    assert isinstance(report, AssignmentReport) and report.digest == "old-times"


def test_a_missing_result_arriving_while_asking_is_decided_on_at_once() -> None:
    core, out = make_core(112, (80.0, 40.0, 60.0))
    core.on_alive(74, True, 0.0)
    core.on_targets(MissionTargets(mission=7, team=(74, 112), targets=TARGETS, deadline_s=3.0), 0.0)
    core.tick(3.1)
    assert out.assignment_fetches == [7]
    core.on_result(UavResult(7, 74, (50.0, 30.0, 70.0)), 3.2)
    core.tick(3.2)  # every result held, heard live: nothing to wait for
    (report,) = out.on(SPACE.mission_assignment(7, 112))
    assert isinstance(report, AssignmentReport) and report.team == (74, 112)


def test_late_joiner_adopts_the_committed_assignment() -> None:
    core, out = make_core(74)
    mission = MissionTargets(mission=8, team=(74, 112), targets=TARGETS)
    committed = AssignmentReport(8, 112, 1, {74: 0, 112: 1}, (2,), (74, 112), "abc")
    core.on_targets(mission, 0.0)
    core.on_assignment(committed, 0.05)
    (report,) = out.on(SPACE.mission_assignment(8, 74))
    assert isinstance(report, AssignmentReport) and report.target == 0 and report.digest == "abc"


def test_stale_messages_are_ignored_and_a_new_mission_supersedes() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=9, team=(112,), targets=TARGETS), 0.0)
    core.on_targets(MissionTargets(mission=8, team=(112,), targets=TARGETS[:1]), 0.1)
    assert core.round is not None and core.round.mission == 9
    core.on_result(UavResult(3, 74, (1.0,)), 0.2)
    core.on_targets(MissionTargets(mission=10, team=(112,), targets=TARGETS[:2]), 0.3)
    assert core.round.mission == 10
    core.tick(0.4)
    published = {key for key, _ in out.published}
    assert SPACE.mission_result(8, 112) not in published
    assert SPACE.mission_result(10, 112) in published


def test_abort_returns_to_the_original_course() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=11, team=(112,), targets=TARGETS), 0.0)
    core.tick(0.1)
    core.on_waypoint(out.autopilot[0], 1.5)  # type: ignore[arg-type]
    core.on_track(Track(TARGET_WAYPOINT), 0.2)
    core.on_abort(MissionAbort(11), 0.3)
    assert out.autopilot[-1] == Track(2)
    assert core.phase == "aborted"


def test_an_abort_for_one_uav_leaves_its_teammates_flying() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    core.on_telemetry(sample_telemetry(), 3.0)
    core.on_abort(MissionAbort(1, uav=74), 3.0)  # a teammate's own abort
    assert core.state(3.0).phase == Phase.FLYING
    core.on_abort(MissionAbort(1, uav=112), 4.0)
    assert core.state(4.0).phase == Phase.ABORTED


def test_a_teammates_failure_outcome_releases_it_and_a_reached_one_does_not() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_outcome(TargetOutcome(3, 74, 0, Phase.REACHED), 4.0)
    assert out.on(SPACE.mission_assignment(3, 200))[-1].epoch == 0  # type: ignore[attr-defined]
    core.on_telemetry(sample_telemetry(), 6.0)
    core.on_outcome(TargetOutcome(3, 112, 1, Phase.FAILED, "waypoint not echoed"), 6.0)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport) and report.target == 1
    assert report.released == (112,)


def test_a_finished_teammate_that_goes_is_released_and_its_reached_target_not_flown_again() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_outcome(TargetOutcome(3, 74, 0, Phase.REACHED), 4.0)
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_alive(74, False, 5.0)
    core.tick(5.0 + LIVELINESS_GRACE_S)  # gone past the grace, after reaching its queue
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    # Released like any UAV that goes: a later epoch never hands it an orphan.
    assert (report.epoch, report.released) == (1, (74,))
    assert 74 not in report.queues
    # Its target, handed on with its queue, was reached: nobody flies it again.
    assert core.state(5.0 + LIVELINESS_GRACE_S).phase != Phase.COMMITTED
    core.on_outcome(TargetOutcome(3, 112, 1, Phase.FAILED, "waypoint not echoed"), 8.0)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport) and report.released == (74, 112)
    assert 74 not in report.queues and 1 in report.queues[200]  # the live UAV flies it


def test_an_orphan_handed_to_a_uav_without_autopilot_link_is_released_again() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_alive(112, False, LINK_LOST_S + 1.0)  # no telemetry since t=0
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (2, (112, 200), None)
    (outcome,) = out.on(SPACE.mission_outcome(3, 200))
    assert isinstance(outcome, TargetOutcome) and outcome.phase == Phase.FAILED


def test_a_teammates_later_epoch_is_merged_and_re_planned_identically() -> None:
    """A teammate's re-plan releasing a UAV this one still sees alive (a captured UAV
    could release an honest teammate and have its targets flown by others) is believed
    once the released UAV's own outcome says it dropped out."""
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    theirs = AssignmentReport(
        3, 74, 0, {74: 0, 200: 1}, (), (74, 112, 200), "x", epoch=1, released=(112,)
    )
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_assignment(theirs, 5.0)
    # That 112 dropped out is 74's word about 112, still alive here: a hint. 200 asks
    # for 112's own outcome, and re-plans (identically) once 112's own word says so.
    assert out.outcome_fetches == [(3, (112,))]
    assert out.on(SPACE.mission_assignment(3, 200))[-1].epoch == 0  # type: ignore[attr-defined]
    core.on_outcome(TargetOutcome(3, 112, 1, Phase.FAILED, "waypoint not echoed"), 5.5)
    core.on_assignment(theirs, 6.0)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (1, (112,), 1)


def test_a_thinner_commitment_is_not_adopted() -> None:
    core, out = uav_200_given_two_targets(mission=4)
    core.on_result(UavResult(4, 112, (40.0, 20.0)), 0.1)
    core.tick(0.2)  # own result out; 74's missing
    thin = AssignmentReport(4, 74, 0, {74: 0}, (1,), (74,), "thin")
    core.on_assignment(thin, 0.3)  # 74 committed on its own result alone
    assert out.on(SPACE.mission_assignment(4, 200)) == []
    core.on_result(UavResult(4, 74, (10.0, 50.0)), 0.4)
    core.tick(0.5)
    (own,) = out.on(SPACE.mission_assignment(4, 200))
    assert isinstance(own, AssignmentReport) and own.team == (74, 112, 200)
    assert own.digest != "thin"  # the disagreement is visible to the ground


# ---- review of hostile reports, finished candidates, writes after arrival --
def test_an_assignment_naming_a_target_beyond_the_mission_is_refused_never_indexed() -> None:
    core, out = uav_200_given_two_targets(mission=3)
    bad = AssignmentReport(3, 74, 0, {74: 0, 200: 7}, (), (74, 112, 200), "x")
    core.on_assignment(bad, 0.2)  # raised IndexError, then every telemetry did
    core.on_telemetry(sample_telemetry(), 0.5)
    assert core.phase == Phase.COMPUTING and out.on(SPACE.mission_assignment(3, 200)) == []
    later = AssignmentReport(
        3, 74, 0, {200: 9}, (), (74, 112, 200), "y", epoch=2, released=(74, 112)
    )
    core.on_assignment(later, 0.6)
    assert core.phase == Phase.COMPUTING and not any(isinstance(c, Waypoint) for c in out.autopilot)


def test_a_candidate_that_reached_its_orphan_flies_the_next_one_and_shows_it() -> None:
    core, out = make_core(30, (30.0, 35.0))
    # 40 cannot reach target 0: 30, done with its queue, is the only one that can.
    commit_four_uav_team(core, times_40=(None, 60.0))
    core.on_waypoint(out.autopilot[-1], 1.1)  # type: ignore[arg-type]
    core.on_track(Track(TARGET_WAYPOINT), 1.2)
    core.on_telemetry(telemetry_at(TWO_TARGETS[1].lat, TWO_TARGETS[1].lon), 2.0)
    assert core.phase == Phase.REACHED
    core.on_alive(10, False, 3.0)  # epoch 2 hands 30 target 0: the last resort
    report = out.on(SPACE.mission_assignment(5, 30))[-1]
    assert isinstance(report, AssignmentReport) and (report.epoch, report.target) == (2, 0)
    waypoint = [c for c in out.autopilot if isinstance(c, Waypoint)][-1]
    assert (waypoint.lat, waypoint.lon) == (TWO_TARGETS[0].lat, TWO_TARGETS[0].lon)
    # It flies target 0: the phase says so (it said `reached` while flying before).
    assert core.state(3.0).phase == Phase.COMMITTED


def test_a_preempted_candidate_handed_another_orphan_drops_out_and_it_is_handed_on() -> None:
    core, out = make_core(30, (30.0, 35.0))
    commit_four_uav_team(core)
    core.command_autopilot(Track(5), 1.5, lambda _: None)  # the operator takes it off
    assert core.phase == Phase.PREEMPTED
    writes = len([c for c in out.autopilot if isinstance(c, Waypoint)])
    core.on_alive(10, False, 3.0)  # epoch 2 would hand 30 target 0
    assert len([c for c in out.autopilot if isinstance(c, Waypoint)]) == writes  # not flown
    assert core.state(3.0).phase == Phase.PREEMPTED
    outcome = out.on(SPACE.mission_outcome(5, 30))[-1]
    assert isinstance(outcome, TargetOutcome)
    assert (outcome.phase, outcome.target) == (Phase.FAILED, 0)
    report = out.on(SPACE.mission_assignment(5, 30))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released) == (3, (10, 20, 30))
    assert report.pairs == {40: 0}  # the orphan went on to 40, not left with 30


def test_a_restarted_idle_uav_follows_the_re_plan_that_hands_it_the_orphan() -> None:
    core, out = uav_200_given_two_targets(mission=3)
    base = AssignmentReport(3, 74, 0, {74: 0, 112: 1}, (), (74, 112, 200), "d0")
    core.on_assignment(base, 0.05)  # fetched at once: adopted before its own result
    core.tick(0.1)
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_alive(112, False, 1.0)  # its own epoch-0 times are gone with its old process
    epoch_1 = AssignmentReport(
        3, 74, 0, {74: 0, 200: 1}, (), (74, 112, 200), "d1", epoch=1, released=(112,)
    )
    core.on_assignment(epoch_1, 1.2)  # it used to stay at epoch 0, waiting for itself
    mine = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(mine, AssignmentReport)
    assert (mine.epoch, mine.target, mine.digest) == (1, 1, "d1")
    assert core.state(1.2).phase == Phase.COMMITTED


def test_a_mission_whose_abort_came_first_shows_aborted_and_is_never_flown() -> None:
    core, out = make_core()
    core.on_abort(MissionAbort(5), 1.0)  # away when mission 5 was sent; its abort arrives
    core.on_targets(MissionTargets(mission=5, team=(112,), targets=TARGETS), 2.0)
    run_with_telemetry(core, 2.0, 4.0)
    state = core.state(4.0)
    assert state.phase == Phase.ABORTED
    assert state.mission is not None and state.mission.mission == 5
    assert out.autopilot == [] and out.on(SPACE.mission_result(5, 112)) == []


def test_the_state_names_the_targets_held_by_their_digest() -> None:
    """The ground checks an acknowledgement by this digest (ground.mission_ack): a
    second mission under the same id, which the UAV ignores, leaves it unchanged."""
    core, _ = make_core()
    held = MissionTargets(mission=4, team=(112,), targets=TARGETS)
    core.on_targets(held, 1.0)
    progress = core.state(1.1).mission
    assert progress is not None and progress.targets_digest == targets_digest(held)
    rival = MissionTargets(mission=4, team=(112,), targets=TWO_TARGETS)
    core.on_targets(rival, 1.2)
    progress = core.state(1.3).mission
    assert progress is not None and progress.mission == 4
    assert progress.targets_digest == targets_digest(held) != targets_digest(rival)


def test_the_legs_are_computed_when_the_mission_arrives_not_at_the_decision() -> None:
    """The target-to-target legs depend on the mission alone: computed while the planner
    runs, so the decision on the last result (every UAV's at once) does not wait on them."""
    core, _ = uav_200_given_two_targets(5)
    assert core.round is not None
    assert "legs" in vars(core.round)  # functools.cached_property: already computed


def test_a_teammate_lost_then_back_rejoins_at_the_next_epoch_and_takes_its_queue_again() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_alive(112, False, 1.0)
    core.tick(1.0 + LIVELINESS_GRACE_S)  # gone past the grace: released
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (1, (112,), 1)
    core.on_telemetry(sample_telemetry(), 4.0)
    core.on_alive(112, True, 4.0)  # back (a router restart, a healed partition)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (2, (), None)
    assert report.left == {112: 1} and report.back == {112: 1}
    assert report.queues[112] == (1,)  # its own queue again
    assert core.state(4.0).phase != Phase.COMMITTED


def test_a_uav_counted_out_by_a_teammate_while_alive_stays_in() -> None:
    """That this UAV is out is a teammate's claim about it (a partition, or a captured
    UAV): left out of the merge; the teammate counts it back once it sees it again."""
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_telemetry(sample_telemetry(), 1.0)
    # 74 lost sight of 200 and 112 (a partition) and re-planned alone.
    theirs = AssignmentReport(
        3, 74, 0, {74: 0}, (), (74, 112, 200), "x", epoch=2, released=(112, 200)
    )
    core.on_assignment(theirs, 2.0)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    # Both are alive here: nothing merged; 112's own outcome is asked for.
    assert (report.epoch, report.released) == (0, ())
    assert out.outcome_fetches == [(3, (112,))]
    core.on_alive(112, False, 2.5)
    core.tick(2.5 + LIVELINESS_GRACE_S)  # now gone here too: 74's count of it is believed
    core.on_assignment(theirs, 5.0)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (1, (112,), 1)


def restarted_200_handed_target_1() -> tuple[OnboardCore, Recorder]:
    """UAV 200's onboard just started (a restart, no telemetry yet) and catches up with
    an epoch that counted it back in with its own target 1."""
    out = Recorder()
    core = OnboardCore(uav_id=200, outputs=out, planner=ScriptedPlanner((30.0, 35.0)))
    core.start(0.0)
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS), 0.1)
    theirs = AssignmentReport(
        3, 74, 0, {74: 0, 200: 1}, (), (74, 112, 200), "x", epoch=2,
        left={200: 1}, back={200: 1},
    )  # fmt: skip
    core.on_assignment(theirs, 0.2)
    return core, out


def test_a_restarted_uav_handed_its_target_before_its_first_telemetry_flies_it_once_heard() -> None:
    core, out = restarted_200_handed_target_1()
    assert core.state(0.3).phase == Phase.COMMITTED
    assert out.autopilot == []  # nothing written blind
    core.tick(0.3)
    assert out.on(SPACE.mission_outcome(3, 200)) == []  # not a lost link: not heard yet
    core.on_telemetry(sample_telemetry(), 0.5)
    assert out.autopilot != []  # the target, written once the autopilot is heard
    assert core.state(0.6).phase == Phase.COMMITTED


def test_a_restarted_uav_that_never_hears_its_autopilot_drops_its_target_as_link_lost() -> None:
    core, out = restarted_200_handed_target_1()
    core.tick(LINK_LOST_S + 0.5)
    (outcome,) = out.on(SPACE.mission_outcome(3, 200))
    assert isinstance(outcome, TargetOutcome) and outcome.phase == Phase.LINK_LOST
    assert core.state(LINK_LOST_S + 0.5).phase != Phase.COMMITTED


def test_targets_added_and_removed_in_flight_are_re_planned_at_once_as_a_new_epoch() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)  # 74 -> 0, 112 -> 1, 200 idle
    held = MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS)
    near_200 = Target(42.3605, -71.0905, 100.0)
    changed = next_revision(held, added=(near_200,), removed=(1,))
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_targets(changed, 1.0)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.revision, report.released) == (1, 1, ())
    assert all(1 not in queue for queue in report.queues.values())  # removed: never flown
    # Only 200 said where it planned from: the added target is its own.
    assert (report.target, report.queues[200]) == (2, (2,))
    assert core.state(1.0).phase == Phase.COMMITTED
    assert any("revision 1" in s for s in out.statuses())
    core.on_targets(changed, 2.0)  # relayed again: a repeat changes nothing
    assert len(out.on(SPACE.mission_assignment(3, 200))) == 2
    rewritten = msgspec.structs.replace(changed, revision=2, targets=(near_200, *TWO_TARGETS))
    core.on_targets(rewritten, 3.0)
    assert any("indexes never change" in s for s in out.statuses())


def test_a_change_heard_before_the_commitment_is_taken_once_committed() -> None:
    core, out = uav_200_given_two_targets(mission=3)
    held = MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS)
    core.on_targets(next_revision(held, removed=(0,)), 0.05)
    core.on_result(UavResult(3, 74, (10.0, 50.0)), 0.1)
    core.on_result(UavResult(3, 112, (40.0, 20.0)), 0.1)
    core.tick(0.2)
    reports = out.on(SPACE.mission_assignment(3, 200))
    assert [r.revision for r in reports] == [0, 1]  # type: ignore[attr-defined]
    assert all(0 not in q for q in reports[-1].queues.values())  # type: ignore[attr-defined]


def test_a_restarted_uav_catching_up_on_a_changed_mission_flies_an_added_target() -> None:
    core, out = make_core(200, (30.0, 35.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    held = MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS)
    changed = next_revision(held, added=(Target(42.3605, -71.0905, 100.0),))
    core.on_targets(changed, 0.1, replayed=True)  # learnt from a teammate, revision 1
    theirs = AssignmentReport(
        3, 74, 0, {74: 0, 112: 1, 200: 2}, (), (74, 112, 200), "x", epoch=1, revision=1,
        queues={74: (0,), 112: (1,), 200: (2,)},
    )  # fmt: skip
    core.on_assignment(theirs, 0.2)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.revision, report.target) == (1, 2)
    assert core.state(0.3).phase == Phase.COMMITTED
    assert out.autopilot  # the added target's waypoint written
