"""Flying a target (onboard.target_flight): writes, echoes, arrival, leaving the route,
resuming, the confirm limit; driven through the whole core."""

from __future__ import annotations

import math

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.lifecycle import Observation
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    TargetOutcome,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.core import (
    CONFIRM_LIMIT_S,
    LINK_RELEASE_S,
    TARGET_WAYPOINT,
    OnboardCore,
)
from onboard.link_watch import LinkWatch
from onboard.mission_phase import MissionPhase
from onboard.target_flight import FlightNews, TargetFlight
from tests.onboard.core_harness import (
    TARGETS,
    TWO_TARGETS,
    Recorder,
    ScriptedPlanner,
    fly_target_1,
    make_core,
    run_with_telemetry,
    telemetry_at,
    tick_without_telemetry,
)
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()
#: Approach times by which target 1 is the UAV's only one: its queue is that target alone.
ONLY_TARGET_1 = (math.inf, 40.0, math.inf)


def test_single_uav_flies_to_the_fastest_target_then_resumes() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)
    (result,) = out.on(SPACE.mission_result(1, 112))
    assert isinstance(result, UavResult)
    assert (result.mission, result.uav, result.times) == (1, 112, (80.0, 40.0, 60.0))
    assert (result.model_times, result.fallback_times) == (3, 0)
    (report,) = out.on(SPACE.mission_assignment(1, 112))
    assert isinstance(report, AssignmentReport) and report.target == 1 and report.eta_s == 40.0
    (waypoint,) = out.autopilot
    assert isinstance(waypoint, Waypoint)
    assert (waypoint.index, waypoint.next_index) == (TARGET_WAYPOINT, 2)
    assert (waypoint.lat, waypoint.lon) == (TARGETS[1].lat, TARGETS[1].lon)
    assert core.state(1.5).phase == Phase.COMMITTED  # nothing echoed yet
    core.on_waypoint(waypoint, 1.5)  # the autopilot's echo
    assert out.autopilot[-1] == Track(TARGET_WAYPOINT)
    core.on_track(Track(TARGET_WAYPOINT), 2.0)
    assert core.state(2.0).phase == Phase.FLYING
    assert report.queues == {112: (1, 0, 2)}  # one UAV queues all three
    core.on_telemetry(telemetry_at(TARGETS[1].lat + 0.0005, TARGETS[1].lon), 59.0)  # ~56 m
    assert any("reached target 1" in s for s in out.statuses())
    # On to the next of its queue: the target waypoint rewritten there, still leading back.
    assert core.state(59.0).phase == Phase.COMMITTED
    waypoint = out.autopilot[-1]
    assert isinstance(waypoint, Waypoint) and waypoint.next_index == 2
    assert (waypoint.lat, waypoint.lon) == (TARGETS[0].lat, TARGETS[0].lon)
    for index, target in ((0, TARGETS[0]), (2, TARGETS[2])):
        written = out.autopilot[-1]
        assert isinstance(written, Waypoint)
        core.on_waypoint(written, 60.0)
        core.on_track(Track(TARGET_WAYPOINT), 60.5)
        assert core.state(60.5).phase == Phase.FLYING
        core.on_telemetry(telemetry_at(target.lat + 0.0005, target.lon), 100.0 + index)
        assert any(f"reached target {index}" in s for s in out.statuses())
    # The queue done: reached, and the autopilot moving on changes nothing.
    assert core.state(103.0).phase == Phase.REACHED
    core.on_track(Track(2), 104.0)
    assert core.state(104.0).phase == Phase.REACHED


def test_leaving_the_target_route_far_from_it_is_preempted_not_reached() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    core.on_telemetry(telemetry_at(42.36, -71.09), 10.0)  # kilometres from target 1
    core.on_track(Track(5), 10.5)  # an operator re-tasks the aircraft
    state = core.state(10.5)
    assert state.phase == Phase.PREEMPTED
    assert state.reason is not None and "waypoint 5" in state.reason
    assert not any("reached" in s and "not reached" not in s for s in out.statuses())


def test_moving_on_to_the_next_waypoint_during_a_link_outage_is_an_arrival() -> None:
    core, out = make_core(times=ONLY_TARGET_1)
    fly_target_1(core, out)  # the target waypoint leads back to waypoint 2
    now = tick_without_telemetry(core, 2.0, 8.0)  # the link drops: "autopilot link lost"
    core.on_telemetry(telemetry_at(TARGETS[1].lat + 0.0034, TARGETS[1].lon), now)  # ~375 m
    core.on_track(Track(2), now + 0.2)  # it moved on while nobody could see it arrive
    assert core.state(now + 0.2).phase == Phase.REACHED
    reached = [s for s in out.statuses() if s.startswith("reached target 1")]
    assert reached and "moved on to waypoint 2 during a link outage" in reached[0]


def test_moving_on_to_the_next_waypoint_far_from_it_with_the_link_up_is_preempted() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    now = run_with_telemetry(core, 2.0, 8.0)  # telemetry all along: no arrival was missed
    core.on_telemetry(telemetry_at(TARGETS[1].lat + 0.0034, TARGETS[1].lon), now)
    core.on_track(Track(2), now + 0.2)
    assert core.state(now + 0.2).phase == Phase.PREEMPTED


def test_a_stale_resume_echo_before_the_track_echo_is_not_an_arrival() -> None:
    core, _ = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)
    core.on_track(Track(TARGET_WAYPOINT), 1.2)
    core.on_track(Track(2), 1.3)  # an echo from before the commitment
    assert core.state(1.3).phase == Phase.COMMITTED


def test_an_unechoed_target_is_retried_until_the_limit_then_failed_and_released() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.0)
    now = run_with_telemetry(core, 0.0, 10.0)
    assert core.state(now).phase == Phase.COMMITTED  # still retrying, not failed
    assert len([c for c in out.autopilot if isinstance(c, Waypoint)]) > 4
    now = run_with_telemetry(core, now, CONFIRM_LIMIT_S + 1.0)
    state = core.state(now)
    assert state.phase == Phase.FAILED
    assert state.reason is not None and "not echoed" in state.reason
    (outcome,) = out.on(SPACE.mission_outcome(1, 112))
    assert outcome == TargetOutcome(1, 112, 1, Phase.FAILED, state.reason)
    assert any(s.startswith("error: mission 1: cannot fly target 1") for s in out.statuses())


def test_a_late_echo_is_not_a_failure() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.0)
    now = run_with_telemetry(core, 0.0, 8.0)  # no echo for 8 s: four times the old limit
    core.on_waypoint(out.autopilot[0], now)  # type: ignore[arg-type]
    core.on_track(Track(TARGET_WAYPOINT), now + 0.1)
    assert core.state(now + 0.1).phase == Phase.FLYING


def test_writes_are_retried_across_a_link_outage() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.0)
    for step in range(1, 40):  # 10 s without telemetry: the link is lost
        core.tick(step * 0.25)
    assert core.state(10.0).phase == Phase.LINK_LOST
    sent_during_outage = len(out.autopilot)
    now = run_with_telemetry(core, 10.0, 11.0)  # the link is back
    assert len(out.autopilot) > sent_during_outage
    core.on_waypoint(out.autopilot[0], now)  # type: ignore[arg-type]
    core.on_track(Track(TARGET_WAYPOINT), now)
    assert core.state(now).phase == Phase.FLYING


def test_module_off_never_writes_to_the_autopilot() -> None:
    core, out = make_core()
    core.on_opm(OpmCommand(enabled=False, status_rate_hz=0.0), 0.0)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(2.0)
    assert out.autopilot == []
    assert out.on(SPACE.mission_result(1, 112)) == [UavResult(1, 112, (None, None, None))]
    results: list[object] = []
    core.command_autopilot(Track(3), 3.0, results.append)
    assert out.autopilot == [] and not results[0].ok  # type: ignore[attr-defined]


def test_an_operator_track_command_preempts_the_target_at_once() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    answers: list[object] = []
    core.command_autopilot(Track(5), 3.0, answers.append)
    state = core.state(3.0)
    assert state.phase == Phase.PREEMPTED
    assert state.reason is not None and "track to waypoint 5" in state.reason
    assert out.autopilot[-1] == Track(5)


def test_reaching_the_target_before_the_track_echo_stops_the_target_writes() -> None:
    core, out = make_core(times=ONLY_TARGET_1)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)  # the waypoint write, not echoed yet
    core.on_telemetry(telemetry_at(TARGETS[1].lat, TARGETS[1].lon), 1.2)  # passing by
    assert core.phase == Phase.REACHED
    sent = len(out.autopilot)
    run_with_telemetry(core, 1.2, 10.0)
    assert len(out.autopilot) == sent  # no more resends that would turn it back
    assert core.commands.pending == 0


def test_the_resume_after_a_link_release_outlives_the_outage_so_it_stops_flying_the_target() -> (
    None
):
    core, out = make_core()
    fly_target_1(core, out)  # tracking the target waypoint, telemetry last at t=0
    now = tick_without_telemetry(core, 2.0, LINK_RELEASE_S + 5.0)  # released meanwhile
    assert core.phase == Phase.FAILED
    now = tick_without_telemetry(core, now, now + 10.0)  # the outage goes on
    sent = len(out.autopilot)
    core.on_telemetry(sample_telemetry(), now)  # the link is back; still on the target
    run_with_telemetry(core, now, now + 2.0)
    # The resume is still being sent: the teammate now flies this target.
    assert out.autopilot[sent:] and set(out.autopilot[sent:]) == {Track(2)}
    core.on_track(Track(2), now + 2.5)  # echoed: done
    assert core.commands.pending == 0


def test_an_abort_during_an_outage_takes_the_aircraft_off_its_target_once_it_is_back() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    core.on_abort(MissionAbort(1), 2.5)
    now = tick_without_telemetry(core, 2.5, 15.0)  # no echo of the resume
    sent = len(out.autopilot)
    run_with_telemetry(core, now, now + 2.0)
    assert out.autopilot[sent:] and set(out.autopilot[sent:]) == {Track(2)}
    assert core.state(now + 2.0).phase == Phase.ABORTED


@pytest.mark.parametrize("track_first", [True, False])
def test_a_restarted_uav_left_on_the_target_route_leaves_it_when_the_re_plan_released_it(
    track_first: bool,
) -> None:
    recorder = Recorder()
    core = OnboardCore(uav_id=112, outputs=recorder, planner=ScriptedPlanner((40.0, 20.0)))
    core.on_telemetry(sample_telemetry(), 0.0)
    if track_first:
        core.on_track(Track(TARGET_WAYPOINT), 0.0)  # its autopilot still flies the old target
    for uav in (74, 200):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS), 0.1)
    epoch_1 = AssignmentReport(
        3, 74, 0, {74: 0, 200: 1}, (), (74, 112, 200), "r", epoch=1, released=(112,)
    )
    core.on_assignment(epoch_1, 0.2)  # fetched at start: it was released meanwhile
    if not track_first:
        core.on_track(Track(TARGET_WAYPOINT), 0.3)  # the autopilot's first report, later
    mine = recorder.on(SPACE.mission_assignment(3, 112))[-1]
    assert isinstance(mine, AssignmentReport) and (mine.epoch, mine.target) == (1, None)
    # 200 flies target 1 now: this aircraft must not fly it too.
    assert recorder.autopilot and recorder.autopilot[-1] == Track(0)
    run_with_telemetry(core, 0.2, 5.0)
    assert recorder.autopilot[-1] == Track(0)  # resent until echoed
    core.on_track(Track(0), 5.1)
    assert core.commands.pending == 0


def test_the_flight_tells_its_mission_by_its_answers_not_by_a_reference_to_it() -> None:
    """A flight stands alone: its commitment carries the mission, an arrival comes back
    as the answer of the telemetry that saw it, and a restart supersedes the mission."""
    recorder = Recorder()
    life = MissionPhase()
    link = LinkWatch(lambda *_args, **_kwargs: None)
    flight = TargetFlight(112, SPACE, recorder, life, link, lambda *_args, **_kwargs: None)
    assert flight.mission is None
    link.on_telemetry(sample_telemetry(), 0.0)
    life.observe(Observation.MISSION_STARTED)
    life.observe(Observation.ASSIGNED_TARGET)
    flight.commit(7, 1, TARGETS[1], 1.0)
    assert flight.mission == 7 and not flight.superseded(7) and flight.superseded(6)
    assert flight.on_telemetry(2.0) is None  # far from the target
    link.on_telemetry(telemetry_at(TARGETS[1].lat, TARGETS[1].lon), 3.0)
    assert flight.on_telemetry(3.0) is FlightNews.REACHED
    flight.restart("mission 8 started", 4.0)
    assert flight.mission is None and flight.superseded(7)
