"""Flying a queue: on to the next target when one is reached, and a holder
lost mid-queue hands the rest of its queue to the survivors; driven through the core."""

from __future__ import annotations

import pytest

from fleet.consensus.legs import Air, leg_from_here
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, TargetOutcome, UavResult
from fleet.mission.phase import Phase
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.core import TARGET_WAYPOINT, OnboardCore
from tests.onboard.core_harness import TARGETS, Recorder, make_core, round_of_three, telemetry_at

SPACE = KeySpace()


def _two_uav_plan() -> tuple[OnboardCore, Recorder]:
    """112 (this core: 80, 40, 60 s) and 74 (10, 90, 90 s), three targets: 74 queues
    0 then 2 (it reaches 2 at ~148 s, 112 at ~260 s), 112 queues 1 alone."""
    core, out = make_core(uav=112)
    core.on_alive(74, True, 0.0)
    core.on_targets(MissionTargets(mission=1, team=(74, 112), targets=TARGETS), 1.0)
    core.on_result(UavResult(1, 74, (10.0, 90.0, 90.0)), 1.05)
    core.tick(1.1)
    (report,) = out.on(SPACE.mission_assignment(1, 112))
    assert isinstance(report, AssignmentReport)
    assert report.queues == {74: (0, 2), 112: (1,)}
    assert report.pairs == {74: 0, 112: 1} and report.unassigned == ()
    return core, out


def _fly_and_reach(core: OnboardCore, out: Recorder, index: int, now: float) -> None:
    waypoint = out.autopilot[-1]
    assert isinstance(waypoint, Waypoint)
    assert (waypoint.lat, waypoint.lon) == (TARGETS[index].lat, TARGETS[index].lon)
    core.on_telemetry(telemetry_at(42.0, -71.0), now)  # kilometres away, the link up
    core.on_waypoint(waypoint, now)
    core.on_track(Track(TARGET_WAYPOINT), now + 0.1)
    assert core.state(now + 0.1).phase == Phase.FLYING
    core.on_telemetry(telemetry_at(TARGETS[index].lat, TARGETS[index].lon), now + 1.0)
    assert any(s.startswith(f"reached target {index}") for s in out.statuses())


def test_a_holder_lost_mid_queue_hands_its_rest_to_a_busy_survivor() -> None:
    core, out = _two_uav_plan()
    core.on_outcome(TargetOutcome(1, 74, 0, Phase.REACHED), 5.0)  # 74 reached its first
    core.on_alive(74, False, 6.0)  # then it is lost, target 2 still to do
    replans = out.on(SPACE.mission_replan(1, 112))
    assert len(replans) == 1
    (replan,) = replans
    assert isinstance(replan, AssignmentReport)
    assert replan.epoch == 1 and replan.released == (74,)
    # 74's whole queue is appended behind 112's own target, which it keeps flying.
    assert replan.queues == {112: (1, 0, 2)} and replan.unassigned == ()
    _fly_and_reach(core, out, 1, 10.0)
    # Target 0 was reached by 74 before it was lost: 112 skips it and flies 2.
    _fly_and_reach(core, out, 2, 20.0)
    assert core.state(22.0).phase == Phase.REACHED


def test_a_teammate_done_with_its_queue_is_released_when_it_goes_and_nothing_flown_again() -> None:
    core, out = _two_uav_plan()
    core.on_outcome(TargetOutcome(1, 74, 0, Phase.REACHED), 5.0)
    core.on_outcome(TargetOutcome(1, 74, 2, Phase.REACHED), 6.0)
    core.on_alive(74, False, 7.0)
    # Released like any UAV that goes: a later epoch never hands it anything.
    (replan,) = out.on(SPACE.mission_replan(1, 112))
    assert isinstance(replan, AssignmentReport)
    assert replan.released == (74,) and 74 not in replan.queues
    # Its queue, handed on, was reached: 112 flies its own target and stops there.
    _fly_and_reach(core, out, 1, 10.0)
    assert core.state(12.0).phase == Phase.REACHED
    writes = [c for c in out.autopilot if isinstance(c, Waypoint) and c.index == TARGET_WAYPOINT]
    assert {(w.lat, w.lon) for w in writes} == {(TARGETS[1].lat, TARGETS[1].lon)}


def test_a_teammates_word_that_this_uav_reached_its_target_is_not_taken() -> None:
    """A captured 74's own signed outcome lists 112's target as reached by 112: 112 flies
    on to it, and its own outcome says nothing of it until it is there."""
    core, out = _two_uav_plan()
    core.on_outcome(TargetOutcome(1, 74, 0, Phase.REACHED, reached={0: 74, 1: 112}), 5.0)
    assert core.state(5.0).mission.reached == {0: 74}  # type: ignore[union-attr]
    _fly_and_reach(core, out, 1, 10.0)
    (outcome,) = out.on(SPACE.mission_outcome(1, 112))
    assert isinstance(outcome, TargetOutcome) and outcome.reached == {0: 74, 1: 112}


def test_a_hint_about_a_teammate_is_fetched_from_it_once() -> None:
    """74 says its teammate 200 reached a target: 200's own outcome is asked for by name,
    once, and believed when it comes."""
    core, out = make_core(uav=112)
    round_of_three(core, (10.0, 90.0, 90.0), (90.0, 90.0, 10.0))
    hint = TargetOutcome(1, 74, 0, Phase.REACHED, reached={0: 74, 2: 200})
    core.on_outcome(hint, 5.0)
    core.on_outcome(hint, 5.5)
    assert out.outcome_fetches == [(1, (200,))]
    assert core.state(6.0).mission.reached == {0: 74}  # type: ignore[union-attr]
    core.on_outcome(TargetOutcome(1, 200, 2, Phase.REACHED, reached={2: 200}), 7.0)
    assert core.state(7.0).mission.reached == {0: 74, 2: 200}  # type: ignore[union-attr]
    assert core.teammate_outcomes(1)[200].target == 2


def test_each_leg_is_timed_when_it_begins_in_the_air_of_that_moment() -> None:
    """The state says the UAV's time for the leg it flies: its result's approach time to
    its first target; for a later one, the plan's leg model timed as it leaves the
    target it reached, in its smoothed wind at its smoothed airspeed, its track in the one flown."""
    core, out = _two_uav_plan()
    progress = core.state(2.0).mission
    assert progress is not None and (progress.current_target, progress.leg_s) == (1, 40.0)
    core.on_outcome(TargetOutcome(1, 74, 0, Phase.REACHED), 5.0)
    core.on_alive(74, False, 6.0)  # 112 takes 74's queue: 1, then 0 (reached), then 2
    _fly_and_reach(core, out, 1, 10.0)
    progress = core.state(11.5).mission
    link, mission_round = core.mission.link, core.round
    assert progress is not None and mission_round is not None and link.gps is not None
    speed = link.smoothed_airspeed()
    assert speed is not None
    expected = leg_from_here(
        mission_round.geometry,
        Air(speed, link.wind.value),
        (link.gps.vel_east, link.gps.vel_north),
        1,
        2,
    )
    assert progress.current_target == 2 and expected is not None
    assert progress.leg_s == pytest.approx(expected)
    # The leg's length at about the airspeed, and a turn; not a time of its result's.
    metres = mission_round.geometry.metres[1][2]
    assert metres / (speed + 15.0) < expected < metres / max(speed - 15.0, 5.0) + 60.0
    assert expected not in (80.0, 40.0, 60.0)
    assert any("this leg" in s for s in out.statuses()), out.statuses()


def test_the_fix_that_proved_an_arrival_is_published_before_its_outcome() -> None:
    """Whatever the telemetry rate, the fix that put the aircraft within its target's
    radius goes on the bus before the outcome saying reached: a recording or a ground
    can check the claim against it."""
    core, out = _two_uav_plan()
    _fly_and_reach(core, out, 1, 10.0)
    keys = [key for key, _ in out.published]
    outcome_at = keys.index(SPACE.mission_outcome(1, 112))
    (fix_at,) = [i for i, key in enumerate(keys) if key == SPACE.telemetry(112)]
    assert fix_at < outcome_at
    fix = out.published[fix_at][1]
    assert isinstance(fix, Telemetry) and fix.gps is not None
    assert (fix.gps.lat, fix.gps.lon) == (TARGETS[1].lat, TARGETS[1].lon)
