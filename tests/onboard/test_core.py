"""The module's logic in one process: a recording Outputs and a scripted planner.

(Unit tests of one module: the end-to-end tests in test_single_uav.py and
test_multi_uav.py use the real link, simulator, planner and Zenoh.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec

from fleet.mission import keys
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    StatusText,
    Target,
    UavResult,
)
from fleet.mission.phase import Phase, Severity
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.autopilot_commands import AutopilotCommand
from onboard.core import LINK_LOST_S, TARGET_WAYPOINT, OnboardCore
from onboard.planner_worker import PlanRequest, PlanResult
from tests.link_samples import sample_telemetry

TARGETS = (Target(42.37, -71.08, 120.0), Target(42.35, -71.10, 130.0), Target(42.36, -71.05, 90.0))


@dataclass
class Recorder:
    autopilot: list[AutopilotCommand] = field(default_factory=list)
    published: list[tuple[str, msgspec.Struct]] = field(default_factory=list)
    ground: list[msgspec.Struct] = field(default_factory=list)
    fetches: list[int] = field(default_factory=list)
    assignment_fetches: list[int] = field(default_factory=list)

    def send_autopilot(self, command: AutopilotCommand) -> None:
        self.autopilot.append(command)

    def publish(self, key: str, message: msgspec.Struct) -> None:
        self.published.append((key, message))

    def send_ground(self, message: StatusText | UavResult) -> None:
        self.ground.append(message)

    def fetch_results(self, mission: int) -> None:
        self.fetches.append(mission)

    def fetch_assignments(self, mission: int) -> None:
        self.assignment_fetches.append(mission)

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
    uav: int = 112, times: tuple[float, ...] = (80.0, 40.0, 60.0)
) -> tuple[OnboardCore, Recorder]:
    recorder = Recorder()
    core = OnboardCore(uav_id=uav, outputs=recorder, planner=ScriptedPlanner(times))
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
    core.on_waypoint(waypoint)  # the autopilot's echo
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
    core.on_waypoint(waypoint)
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
    core.on_alive(74, True)
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


def test_unconfirmed_waypoint_is_retried_then_reported_failed() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.0)
    for step in range(1, 40):
        core.tick(step * 0.25)
    assert len([c for c in out.autopilot if isinstance(c, Waypoint)]) == 4
    assert any("target waypoint not stored" in s for s in out.statuses())


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
    core.on_alive(74, True)
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


def test_dead_teammate_is_left_out_and_deadline_commits() -> None:
    core, out = make_core(112)
    core.on_alive(74, True)
    core.on_alive(75, True)
    mission = MissionTargets(mission=6, team=(74, 75, 112), targets=TARGETS, deadline_s=5.0)
    core.on_targets(mission, 0.0)
    core.on_result(UavResult(6, 74, (10.0, 10.0, 10.0)), 0.5)
    core.tick(1.0)
    core.on_alive(75, False)  # killed
    core.tick(1.1)
    (report,) = out.on(keys.mission_assignment(6, 112))
    assert isinstance(report, AssignmentReport) and report.team == (74, 112)


def test_silent_teammate_is_dropped_at_the_deadline() -> None:
    core, out = make_core(112)
    core.on_alive(74, True)
    core.on_targets(MissionTargets(mission=7, team=(74, 112), targets=TARGETS, deadline_s=3.0), 0.0)
    core.tick(2.9)
    assert out.on(keys.mission_assignment(7, 112)) == []
    core.tick(3.1)
    (report,) = out.on(keys.mission_assignment(7, 112))
    assert isinstance(report, AssignmentReport) and report.team == (112,) and report.target == 1
    assert any("without 74" in s for s in out.statuses())


def test_late_joiner_adopts_the_committed_assignment() -> None:
    core, out = make_core(74)
    mission = MissionTargets(mission=8, team=(74, 112), targets=TARGETS)
    committed = AssignmentReport(8, 112, 1, {"74": 0, "112": 1}, (2,), (74, 112), "abc")
    core.on_targets(mission, 0.0)
    core.on_assignment(committed, 0.05)
    (report,) = out.on(keys.mission_assignment(8, 74))
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
    assert keys.mission_result(8, 112) not in published
    assert keys.mission_result(10, 112) in published


def test_abort_returns_to_the_original_course() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=11, team=(112,), targets=TARGETS), 0.0)
    core.tick(0.1)
    core.on_waypoint(out.autopilot[0])  # type: ignore[arg-type]
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
