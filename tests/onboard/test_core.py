"""The module's logic in one process: a recording Outputs and a scripted planner.

(Unit tests of one module: the end-to-end tests in test_single_uav.py and
test_multi_uav.py use the real link, simulator, planner and Zenoh.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec
import pytest

from fleet.consensus.mission_round import ASK_GRACE_S, JOIN_GRACE_S
from fleet.mission import keys
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    StatusText,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.phase import Phase, Severity
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.autopilot_commands import AutopilotCommand
from onboard.core import (
    CATCH_UP_INTERVAL_S,
    CONFIRM_LIMIT_S,
    LINK_LOST_S,
    LINK_RELEASE_S,
    LIVELINESS_GRACE_S,
    TARGET_WAYPOINT,
    OnboardCore,
)
from onboard.planner_worker import PlanRequest, PlanResult
from tests.support.link_samples import sample_telemetry

TARGETS = (Target(42.37, -71.08, 120.0), Target(42.35, -71.10, 130.0), Target(42.36, -71.05, 90.0))


@dataclass
class Recorder:
    autopilot: list[AutopilotCommand] = field(default_factory=list)
    published: list[tuple[str, msgspec.Struct]] = field(default_factory=list)
    ground: list[msgspec.Struct] = field(default_factory=list)
    fetches: list[int] = field(default_factory=list)
    assignment_fetches: list[int] = field(default_factory=list)
    mission_fetches: int = 0

    def send_autopilot(self, command: AutopilotCommand) -> None:
        self.autopilot.append(command)

    def publish(self, key: str, message: msgspec.Struct) -> None:
        self.published.append((key, message))

    def send_ground(self, message: StatusText | UavResult) -> None:
        self.ground.append(message)

    def fetch_results(self, mission: int, uavs: tuple[int, ...]) -> None:
        self.fetches.append(mission)

    def fetch_assignments(self, mission: int) -> None:
        self.assignment_fetches.append(mission)

    def fetch_missions(self) -> None:
        self.mission_fetches += 1

    def statuses(self) -> list[str]:
        return [m.text for _, m in self.published if isinstance(m, StatusText)]

    def on(self, key: str) -> list[msgspec.Struct]:
        return [m for k, m in self.published if k == key]


@dataclass
class ScriptedPlanner:
    times: tuple[float, ...]
    requests: list[PlanRequest] = field(default_factory=list)
    _done: PlanResult | None = None

    def run(self, request: PlanRequest) -> bool:
        self.requests.append(request)
        n = len(request.targets)
        self._done = PlanResult(
            request=request,
            times=self.times[:n],
            fallback=(False,) * n,
            solve_seconds=0.01,
            error=None,
        )
        return True

    def result(self) -> PlanResult | None:
        done, self._done = self._done, None
        return done


def make_core(
    uav: int = 112,
    times: tuple[float, ...] = (80.0, 40.0, 60.0),
    liveliness_grace_s: float = 0.0,  # most tests: a lost teammate is released at once
) -> tuple[OnboardCore, Recorder]:
    recorder = Recorder()
    core = OnboardCore(
        uav_id=uav,
        outputs=recorder,
        planner=ScriptedPlanner(times),
        liveliness_grace_s=liveliness_grace_s,
    )
    core.on_telemetry(sample_telemetry(), 0.0)
    core.on_track(Track(2), 0.0)
    return core, recorder


def test_single_uav_flies_to_the_fastest_target_then_resumes() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)
    assert out.on(keys.mission_result(1, 112)) == [
        UavResult(1, 112, (80.0, 40.0, 60.0), model_times=3, fallback_times=0)
    ]
    (report,) = out.on(keys.mission_assignment(1, 112))
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
    core.on_telemetry(telemetry_at(TARGETS[1].lat + 0.0005, TARGETS[1].lon), 59.0)  # ~56 m
    assert core.state(59.0).phase == Phase.REACHED
    core.on_track(Track(2), 60.0)  # the autopilot moves on: still reached
    assert core.state(60.0).phase == Phase.REACHED
    assert any("reached target 1" in s for s in out.statuses())


def telemetry_at(lat: float, lon: float) -> Telemetry:
    sample = sample_telemetry()
    assert sample.gps is not None
    return msgspec.structs.replace(
        sample, gps=msgspec.structs.replace(sample.gps, lat=lat, lon=lon)
    )


def fly_target_1(core: OnboardCore, out: Recorder) -> None:
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)
    (waypoint,) = out.autopilot
    assert isinstance(waypoint, Waypoint)
    core.on_waypoint(waypoint, 1.5)
    core.on_track(Track(TARGET_WAYPOINT), 2.0)


def test_leaving_the_target_route_far_from_it_is_preempted_not_reached() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    core.on_telemetry(telemetry_at(42.36, -71.09), 10.0)  # kilometres from target 1
    core.on_track(Track(5), 10.5)  # an operator re-tasks the aircraft
    state = core.state(10.5)
    assert state.phase == Phase.PREEMPTED
    assert state.reason is not None and "waypoint 5" in state.reason
    assert not any("reached" in s and "not reached" not in s for s in out.statuses())


def test_a_stale_resume_echo_before_the_track_echo_is_not_an_arrival() -> None:
    core, _ = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)
    core.on_track(Track(TARGET_WAYPOINT), 1.2)
    core.on_track(Track(2), 1.3)  # an echo from before the commitment
    assert core.state(1.3).phase == Phase.COMMITTED


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
    assert out.on(keys.mission_assignment(1, 112)) == []
    assert out.autopilot == []
    assert core.state(30.0).phase == Phase.ABORTED


def test_lost_telemetry_is_link_lost_and_declines_a_mission() -> None:
    core, out = make_core()  # telemetry at t=0
    core.tick(LINK_LOST_S + 1.0)
    state = core.state(LINK_LOST_S + 1.0)
    assert state.phase == Phase.LINK_LOST and state.reason is not None
    assert any(s.startswith("error: autopilot link lost") for s in out.statuses())
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), LINK_LOST_S + 2)
    assert out.on(keys.mission_result(1, 112)) == [UavResult(1, 112, (None, None, None))]
    assert out.autopilot == []
    core.on_telemetry(sample_telemetry(), LINK_LOST_S + 3)
    assert core.state(LINK_LOST_S + 3).phase != Phase.LINK_LOST


def test_status_messages_carry_their_severity() -> None:
    core, out = make_core()
    core.tick(LINK_LOST_S + 1.0)
    severities = {m.text: m.severity for _, m in out.published if isinstance(m, StatusText)}
    assert Severity.ERROR in severities.values()


def run_with_telemetry(core: OnboardCore, start: float, end: float, step: float = 0.25) -> float:
    """Tick the module from `start` to `end` with telemetry flowing; returns the end time."""
    now = start
    while now < end:
        now += step
        core.on_telemetry(sample_telemetry(), now)
        core.tick(now)
    return now


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
    (outcome,) = out.on(keys.mission_outcome(1, 112))
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
    assert out.on(keys.mission_result(1, 112)) == [UavResult(1, 112, (None, None, None))]
    results: list[object] = []
    core.command_autopilot(Track(3), 3.0, results.append)
    assert out.autopilot == [] and not results[0].ok  # type: ignore[attr-defined]


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
    assert out.on(keys.mission_assignment(5, 112)) == []
    core.tick(1.2)
    assert out.fetches == [5]  # a missing result is fetched before it is given up on
    core.on_result(UavResult(5, 74, (50.0, 30.0, 70.0)), 1.3)
    core.tick(1.4)
    (report,) = out.on(keys.mission_assignment(5, 112))
    assert isinstance(report, AssignmentReport)
    assert report.pairs == {"74": 1, "112": 2} and report.target == 2


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


def test_dead_teammate_is_left_out_and_deadline_commits() -> None:
    core, out = make_core(112)
    core.on_alive(74, True, 0.0)
    core.on_alive(75, True, 0.0)
    mission = MissionTargets(mission=6, team=(74, 75, 112), targets=TARGETS, deadline_s=5.0)
    core.on_targets(mission, 0.0)
    core.on_result(UavResult(6, 74, (10.0, 10.0, 10.0)), 0.5)
    core.tick(1.0)
    core.on_alive(75, False, 0.0)  # killed
    core.tick(1.1)
    assert out.assignment_fetches == [6]  # 74 may have committed with 75's result
    core.tick(1.1 + ASK_GRACE_S)
    (report,) = out.on(keys.mission_assignment(6, 112))
    assert isinstance(report, AssignmentReport) and report.team == (74, 112)


def test_silent_teammate_is_dropped_at_the_deadline() -> None:
    core, out = make_core(112)
    core.on_alive(74, True, 0.0)
    core.on_targets(MissionTargets(mission=7, team=(74, 112), targets=TARGETS, deadline_s=3.0), 0.0)
    core.tick(2.9)
    assert out.on(keys.mission_assignment(7, 112)) == []
    core.tick(3.1)
    assert out.assignment_fetches == [7]  # the team is asked what it decided first
    assert out.on(keys.mission_assignment(7, 112)) == []
    core.tick(3.1 + ASK_GRACE_S)
    (report,) = out.on(keys.mission_assignment(7, 112))
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
    pairs = {"74": 0, "75": 1, "112": 2}
    committed = AssignmentReport(7, 74, 0, pairs, (), team, "with-75")
    core.on_assignment(committed, 3.2)  # the answer to the query
    (report,) = out.on(keys.mission_assignment(7, 112))
    assert isinstance(report, AssignmentReport)
    assert (report.digest, report.target) == ("with-75", 2)
    core.tick(3.1 + ASK_GRACE_S)
    assert len(out.on(keys.mission_assignment(7, 112))) == 1


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
    assert out.on(keys.mission_assignment(4, 200)) == []
    pairs = {"74": 0, "112": 1, "200": 2}
    core.on_assignment(AssignmentReport(4, 74, 0, pairs, (), team, "with-112"), 0.5)
    (report,) = out.on(keys.mission_assignment(4, 200))
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
    assert out.on(keys.mission_assignment(9, 74)) == []
    old = AssignmentReport(9, 112, 2, {"74": 1, "112": 2}, (0,), team, "old-times")
    core.on_assignment(old, 0.4)
    (report,) = out.on(keys.mission_assignment(9, 74))
    assert isinstance(report, AssignmentReport) and report.digest == "old-times"


def test_a_missing_result_arriving_while_asking_is_decided_on_at_once() -> None:
    core, out = make_core(112, (80.0, 40.0, 60.0))
    core.on_alive(74, True, 0.0)
    core.on_targets(MissionTargets(mission=7, team=(74, 112), targets=TARGETS, deadline_s=3.0), 0.0)
    core.tick(3.1)
    assert out.assignment_fetches == [7]
    core.on_result(UavResult(7, 74, (50.0, 30.0, 70.0)), 3.2)
    core.tick(3.2)  # every result held, heard live: nothing to wait for
    (report,) = out.on(keys.mission_assignment(7, 112))
    assert isinstance(report, AssignmentReport) and report.team == (74, 112)


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
    committed = AssignmentReport(8, 112, 1, {"74": 0, "112": 1}, (2,), (74, 112), "abc")
    core.on_result(UavResult(8, 112, (50.0, 10.0, 50.0)), 20.15)
    core.on_assignment(committed, 20.2)  # the answer
    (report,) = out.on(keys.mission_assignment(8, 74))
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
    without = AssignmentReport(8, 112, 0, {"112": 0}, (1, 2), (112,), "without-74")
    core.on_assignment(without, 20.2 + JOIN_GRACE_S + 0.1)
    (report,) = out.on(keys.mission_assignment(8, 74))
    assert isinstance(report, AssignmentReport) and report.digest == "without-74"
    assert report.target is None


def test_a_mission_heard_live_in_the_normal_course_asks_nobody() -> None:
    core, out = make_core(74)
    for t in (0.0, 0.25, 0.5):
        core.tick(t)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.6)
    assert out.assignment_fetches == []


def test_late_joiner_adopts_the_committed_assignment() -> None:
    core, out = make_core(74)
    mission = MissionTargets(mission=8, team=(74, 112), targets=TARGETS)
    committed = AssignmentReport(8, 112, 1, {"74": 0, "112": 1}, (2,), (74, 112), "abc")
    core.on_targets(mission, 0.0)
    core.on_assignment(committed, 0.05)
    (report,) = out.on(keys.mission_assignment(8, 74))
    assert isinstance(report, AssignmentReport) and report.target == 0 and report.digest == "abc"


def test_a_mission_heard_live_asks_nobody_and_one_from_a_catch_up_asks_the_team() -> None:
    # Heard live, the mission is as new to the team as to this UAV: no queries while
    # everybody plans. Learnt from a catch-up, the team may have decided already.
    core, out = make_core(74)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.0)
    assert out.assignment_fetches == []
    core.on_targets(MissionTargets(mission=9, team=(74, 112), targets=TARGETS), 0.1, replayed=True)
    assert out.assignment_fetches == [9]


def test_a_catch_up_during_a_round_asks_for_its_assignments_committed_or_not() -> None:
    # A UAV frozen while the mission was sent hears it live, late: its catch-ups after
    # the freeze must still bring what the team decided meanwhile.
    core, out = make_core(74)
    core.on_targets(MissionTargets(mission=8, team=(74, 112), targets=TARGETS), 0.0)
    core.catch_up(0.1, force=True)
    assert out.assignment_fetches == [8]


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
    assert keys.mission_result(8, 112) not in published
    assert keys.mission_result(10, 112) in published


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


# ---- re-planning, thin commitments, operator commands, quick succession -------------
TWO_TARGETS = TARGETS[:2]


def commit_three_uav_team(core: OnboardCore) -> None:
    """UAV 200 (this core) in a team with 74 and 112, 2 targets: 200 is left idle."""
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    mission = MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS)
    core.on_targets(mission, 0.0)
    core.on_result(UavResult(3, 74, (10.0, 50.0)), 0.1)
    core.on_result(UavResult(3, 112, (40.0, 20.0)), 0.1)
    core.tick(0.2)


def test_an_idle_uav_flies_the_target_of_a_holder_lost_after_the_commitment() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    (first,) = out.on(keys.mission_assignment(3, 200))
    assert isinstance(first, AssignmentReport) and first.target is None and first.epoch == 0
    assert out.on(keys.mission_replan(3, 200)) == []  # teammates hear epoch 0 by query
    assert core.state(0.2).phase == Phase.IDLE
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_alive(112, False, 5.0)  # the holder of target 1 is killed
    second = out.on(keys.mission_assignment(3, 200))[-1]
    assert out.on(keys.mission_replan(3, 200)) == [second]  # and re-plans live too
    assert isinstance(second, AssignmentReport)
    assert (second.target, second.epoch, second.released) == (1, 1, (112,))
    assert second.pairs == {"74": 0, "200": 1}
    assert core.state(5.0).phase == Phase.COMMITTED
    (waypoint,) = [c for c in out.autopilot if isinstance(c, Waypoint)]
    assert (waypoint.lat, waypoint.lon) == (TWO_TARGETS[1].lat, TWO_TARGETS[1].lon)


def test_a_liveliness_blip_after_the_commitment_releases_nobody() -> None:
    # A router failover withdraws a teammate's token and declares it again at once.
    core, out = make_core(200, (30.0, 35.0), liveliness_grace_s=LIVELINESS_GRACE_S)
    commit_three_uav_team(core)
    core.on_alive(112, False, 5.0)
    core.tick(5.1)
    core.on_alive(112, True, 5.2)
    core.tick(5.0 + LIVELINESS_GRACE_S + 1.0)
    reports = out.on(keys.mission_assignment(3, 200))
    assert [r.epoch for r in reports] == [0]  # type: ignore[attr-defined]


def test_a_teammate_gone_past_the_grace_is_released_at_the_next_tick() -> None:
    core, out = make_core(200, (30.0, 35.0), liveliness_grace_s=LIVELINESS_GRACE_S)
    commit_three_uav_team(core)
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_alive(112, False, 5.0)
    core.tick(5.0 + LIVELINESS_GRACE_S / 2)
    assert out.on(keys.mission_assignment(3, 200))[-1].epoch == 0  # type: ignore[attr-defined]
    core.on_telemetry(sample_telemetry(), 5.0 + LIVELINESS_GRACE_S)
    core.tick(5.0 + LIVELINESS_GRACE_S)
    report = out.on(keys.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.target, report.epoch, report.released) == (1, 1, (112,))


def test_a_teammates_failure_outcome_releases_it_and_a_reached_one_does_not() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_outcome(TargetOutcome(3, 74, 0, Phase.REACHED), 4.0)
    core.on_alive(74, False, 5.0)  # gone after reaching: nothing orphaned
    assert out.on(keys.mission_assignment(3, 200))[-1].epoch == 0  # type: ignore[attr-defined]
    core.on_telemetry(sample_telemetry(), 6.0)
    core.on_outcome(TargetOutcome(3, 112, 1, Phase.FAILED, "waypoint not echoed"), 6.0)
    report = out.on(keys.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport) and report.target == 1
    assert report.released == (112,)


def test_an_orphan_handed_to_a_uav_without_autopilot_link_is_released_again() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    core.on_alive(112, False, LINK_LOST_S + 1.0)  # no telemetry since t=0
    report = out.on(keys.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (2, (112, 200), None)
    (outcome,) = out.on(keys.mission_outcome(3, 200))
    assert isinstance(outcome, TargetOutcome) and outcome.phase == Phase.FAILED


def test_a_teammates_later_epoch_is_merged_and_re_planned_identically() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    theirs = AssignmentReport(
        3, 74, 0, {"74": 0, "200": 1}, (), (74, 112, 200), "x", epoch=1, released=(112,)
    )
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_assignment(theirs, 5.0)
    report = out.on(keys.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released, report.target) == (1, (112,), 1)


def test_a_thinner_commitment_is_not_adopted() -> None:
    core, out = make_core(200, (30.0, 35.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=4, team=(74, 112, 200), targets=TWO_TARGETS), 0.0)
    core.on_result(UavResult(4, 112, (40.0, 20.0)), 0.1)
    core.tick(0.2)  # own result out; 74's missing
    thin = AssignmentReport(4, 74, 0, {"74": 0}, (1,), (74,), "thin")
    core.on_assignment(thin, 0.3)  # 74 committed on its own result alone
    assert out.on(keys.mission_assignment(4, 200)) == []
    core.on_result(UavResult(4, 74, (10.0, 50.0)), 0.4)
    core.tick(0.5)
    (own,) = out.on(keys.mission_assignment(4, 200))
    assert isinstance(own, AssignmentReport) and own.team == (74, 112, 200)
    assert own.digest != "thin"  # the disagreement is visible to the ground


def test_an_operator_track_command_preempts_the_target_at_once() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    answers: list[object] = []
    core.command_autopilot(Track(5), 3.0, answers.append)
    state = core.state(3.0)
    assert state.phase == Phase.PREEMPTED
    assert state.reason is not None and "track to waypoint 5" in state.reason
    assert out.autopilot[-1] == Track(5)


@dataclass
class HeldPlanner:
    """Answers only when told to: the test picks which request's answer arrives."""

    requests: list[PlanRequest] = field(default_factory=list)
    ready: PlanResult | None = None

    def run(self, request: PlanRequest) -> bool:
        self.requests.append(request)
        return True

    def answer(self, request: PlanRequest, times: tuple[float, ...]) -> None:
        self.ready = PlanResult(request, times, (False,) * len(times), 0.01)

    def result(self) -> PlanResult | None:
        done, self.ready = self.ready, None
        return done


def test_a_stale_plan_is_never_used_for_the_next_mission() -> None:
    planner = HeldPlanner()
    out = Recorder()
    core = OnboardCore(uav_id=112, outputs=out, planner=planner)
    core.on_telemetry(sample_telemetry(), 0.0)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TWO_TARGETS), 0.0)
    core.on_targets(MissionTargets(mission=2, team=(112,), targets=TWO_TARGETS), 0.05)
    first, second = planner.requests
    planner.answer(first, (1.0, 2.0))  # mission 1's answer, same target count
    core.tick(0.1)
    assert out.on(keys.mission_result(2, 112)) == []
    planner.answer(second, (7.0, 8.0))
    core.tick(0.2)
    assert out.on(keys.mission_result(2, 112)) == [
        UavResult(2, 112, (7.0, 8.0), model_times=2, fallback_times=0)
    ]


def test_the_planning_budget_grows_with_the_missions_deadline() -> None:
    core, _ = make_core()
    planner = core.planner
    assert isinstance(planner, ScriptedPlanner)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS, deadline_s=3.0), 0.0)
    core.on_targets(MissionTargets(mission=2, team=(112,), targets=TARGETS, deadline_s=30.0), 1.0)
    assert [r.budget_s for r in planner.requests] == [2.0, 15.0]


# ---- review of issue 10: hostile reports, finished candidates, writes after arrival --
def test_an_assignment_naming_a_target_beyond_the_mission_is_refused_never_indexed() -> None:
    core, out = make_core(200, (30.0, 35.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS), 0.0)
    bad = AssignmentReport(3, 74, 0, {"74": 0, "200": 7}, (), (74, 112, 200), "x")
    core.on_assignment(bad, 0.2)  # raised IndexError, then every telemetry did
    core.on_telemetry(sample_telemetry(), 0.5)
    assert core.phase == Phase.COMPUTING and out.on(keys.mission_assignment(3, 200)) == []
    later = AssignmentReport(
        3, 74, 0, {"200": 9}, (), (74, 112, 200), "y", epoch=2, released=(74, 112)
    )
    core.on_assignment(later, 0.6)
    assert core.phase == Phase.COMPUTING and not any(isinstance(c, Waypoint) for c in out.autopilot)


def test_a_base_assignment_with_a_pair_that_is_no_uav_id_never_breaks_a_re_plan() -> None:
    core, out = make_core(200, (30.0, 35.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS), 0.0)
    odd = AssignmentReport(3, 74, 0, {"74": 0, "abc": 1}, (), (74, 112, 200), "x")
    core.on_assignment(odd, 0.2)  # adopted, then int("abc") raised at each re-plan
    core.on_result(UavResult(3, 74, (10.0, 50.0)), 0.3)
    core.on_result(UavResult(3, 112, (40.0, 20.0)), 0.3)
    core.tick(0.4)  # commits its own
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_alive(112, False, 1.0)
    report = out.on(keys.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.target) == (1, 1)


FOUR_TEAM = (10, 20, 30, 40)


def commit_four_uav_team(core: OnboardCore) -> None:
    """UAV 30 (this core, times (30, 35)) with 10 (holds 0), 20 (holds 1) and 40 (idle).

    Once 20 is lost, 30 takes target 1; once 10 is lost too, the greedy over 30 and 40
    gives 30 target 0 (30 s) and 40 target 1.
    """
    for uav in (10, 20, 40):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=5, team=FOUR_TEAM, targets=TWO_TARGETS), 0.0)
    core.on_result(UavResult(5, 10, (10.0, 50.0)), 0.1)
    core.on_result(UavResult(5, 20, (40.0, 20.0)), 0.1)
    core.on_result(UavResult(5, 40, (32.0, 60.0)), 0.1)
    core.tick(0.2)
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_alive(20, False, 1.0)
    assert core.phase == Phase.COMMITTED and core.round is not None
    assert core.round.committed is not None and core.round.committed.target == 1


def test_a_candidate_that_reached_its_orphan_flies_the_next_one_and_shows_it() -> None:
    core, out = make_core(30, (30.0, 35.0))
    commit_four_uav_team(core)
    core.on_waypoint(out.autopilot[-1], 1.1)  # type: ignore[arg-type]
    core.on_track(Track(TARGET_WAYPOINT), 1.2)
    core.on_telemetry(telemetry_at(TWO_TARGETS[1].lat, TWO_TARGETS[1].lon), 2.0)
    assert core.phase == Phase.REACHED
    core.on_alive(10, False, 3.0)  # epoch 2 hands 30 target 0
    report = out.on(keys.mission_assignment(5, 30))[-1]
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
    outcome = out.on(keys.mission_outcome(5, 30))[-1]
    assert isinstance(outcome, TargetOutcome)
    assert (outcome.phase, outcome.target) == (Phase.FAILED, 0)
    report = out.on(keys.mission_assignment(5, 30))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.epoch, report.released) == (3, (10, 20, 30))
    assert report.pairs == {"40": 0}  # the orphan went on to 40, not left with 30


def test_reaching_the_target_before_the_track_echo_stops_the_target_writes() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 1.0)
    core.tick(1.1)  # the waypoint write, not echoed yet
    core.on_telemetry(telemetry_at(TARGETS[1].lat, TARGETS[1].lon), 1.2)  # passing by
    assert core.phase == Phase.REACHED
    sent = len(out.autopilot)
    run_with_telemetry(core, 1.2, 10.0)
    assert len(out.autopilot) == sent  # no more resends that would turn it back
    assert core.commands.pending == 0


def tick_without_telemetry(core: OnboardCore, start: float, end: float) -> float:
    now = start
    while now < end:
        now += 0.25
        core.tick(now)
    return now


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
        3, 74, 0, {"74": 0, "200": 1}, (), (74, 112, 200), "r", epoch=1, released=(112,)
    )
    core.on_assignment(epoch_1, 0.2)  # fetched at start: it was released meanwhile
    if not track_first:
        core.on_track(Track(TARGET_WAYPOINT), 0.3)  # the autopilot's first report, later
    mine = recorder.on(keys.mission_assignment(3, 112))[-1]
    assert isinstance(mine, AssignmentReport) and (mine.epoch, mine.target) == (1, None)
    # 200 flies target 1 now: this aircraft must not fly it too.
    assert recorder.autopilot and recorder.autopilot[-1] == Track(0)
    run_with_telemetry(core, 0.2, 5.0)
    assert recorder.autopilot[-1] == Track(0)  # resent until echoed
    core.on_track(Track(0), 5.1)
    assert core.commands.pending == 0


def test_a_restarted_idle_uav_follows_the_re_plan_that_hands_it_the_orphan() -> None:
    core, out = make_core(200, (30.0, 35.0))
    for uav in (74, 112):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=3, team=(74, 112, 200), targets=TWO_TARGETS), 0.0)
    base = AssignmentReport(3, 74, 0, {"74": 0, "112": 1}, (), (74, 112, 200), "d0")
    core.on_assignment(base, 0.05)  # fetched at once: adopted before its own result
    core.tick(0.1)
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_alive(112, False, 1.0)  # its own epoch-0 times are gone with its old process
    epoch_1 = AssignmentReport(
        3, 74, 0, {"74": 0, "200": 1}, (), (74, 112, 200), "d1", epoch=1, released=(112,)
    )
    core.on_assignment(epoch_1, 1.2)  # it used to stay at epoch 0, waiting for itself
    mine = out.on(keys.mission_assignment(3, 200))[-1]
    assert isinstance(mine, AssignmentReport)
    assert (mine.epoch, mine.target, mine.digest) == (1, 1, "d1")
    assert core.state(1.2).phase == Phase.COMMITTED


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


def test_a_mission_whose_abort_came_first_shows_aborted_and_is_never_flown() -> None:
    core, out = make_core()
    core.on_abort(MissionAbort(5), 1.0)  # away when mission 5 was sent; its abort arrives
    core.on_targets(MissionTargets(mission=5, team=(112,), targets=TARGETS), 2.0)
    run_with_telemetry(core, 2.0, 4.0)
    state = core.state(4.0)
    assert state.phase == Phase.ABORTED
    assert state.mission is not None and state.mission.mission == 5
    assert out.autopilot == [] and out.on(keys.mission_result(5, 112)) == []


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
