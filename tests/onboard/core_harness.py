"""The core's test harness: a recording Outputs, scripted planners, and the steps the
role tests share (onboard.core and its roles)."""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec

from fleet.mission.messages import (
    MissionTargets,
    StatusText,
    Target,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.autopilot_commands import AutopilotCommand
from onboard.core import (
    TARGET_WAYPOINT,
    OnboardCore,
)
from onboard.planner.planner_worker import PlanRequest, PlanResult
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
    outcome_fetches: list[tuple[int, tuple[int, ...]]] = field(default_factory=list)
    standing_fetches: list[tuple[int, tuple[int, ...], str | None]] = field(default_factory=list)

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

    def fetch_outcomes(self, mission: int, uavs: tuple[int, ...]) -> None:
        self.outcome_fetches.append((mission, uavs))

    def fetch_standings(self, mission: int, uavs: tuple[int, ...], basis: str | None) -> None:
        self.standing_fetches.append((mission, uavs, basis))

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
    vouch_teammates: bool = False,  # the secure profile: a token counts once its UAV spoke
    fresh_replans: bool = False,
    propose: bool = False,  # `--propose`: it proposes plans for missions naming it
) -> tuple[OnboardCore, Recorder]:
    """A core on a scripted planner. Its scripted teammates give no standings, so the
    role tests of the re-plan check the append rule, committed at once (what a re-plan
    commits when standings are missing); `fresh_replans` for the tests of re-plans solved
    again from standings (test_fresh_replan.py)."""
    recorder = Recorder()
    core = OnboardCore(
        uav_id=uav,
        outputs=recorder,
        planner=ScriptedPlanner(times),
        liveliness_grace_s=liveliness_grace_s,
        vouch_teammates=vouch_teammates,
        fresh_replans=fresh_replans,
        propose=propose,
    )
    core.on_telemetry(sample_telemetry(), 0.0)
    core.on_track(Track(2), 0.0)
    return core, recorder


def round_of_three(
    core: OnboardCore, times_74: tuple[float, ...], times_200: tuple[float, ...]
) -> None:
    """Mission 1's TARGETS to a team of 74, 112 (the core) and 200, whose results are
    `times_74` and `times_200`, heard before the core's first tick."""
    for uav in (74, 200):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=1, team=(74, 112, 200), targets=TARGETS), 1.0)
    core.on_result(UavResult(1, 74, times_74), 1.05)
    core.on_result(UavResult(1, 200, times_200), 1.06)
    core.tick(1.1)


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


def run_with_telemetry(core: OnboardCore, start: float, end: float, step: float = 0.25) -> float:
    """Tick the module from `start` to `end` with telemetry flowing; returns the end time."""
    now = start
    while now < end:
        now += step
        core.on_telemetry(sample_telemetry(), now)
        core.tick(now)
    return now


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


FOUR_TEAM = (10, 20, 30, 40)


def commit_four_uav_team(
    core: OnboardCore, times_40: tuple[float | None, ...] = (32.0, 60.0)
) -> None:
    """UAV 30 (this core, times (30, 35)) with 10 (holds 0), 20 (holds 1) and 40 (idle,
    `times_40`).

    Once 20 is lost, 30 takes target 1; once 10 is lost too, the append rule gives 30
    target 0 (30 s) and 40 target 1, unless 30 is done with its queue by then (a finished
    UAV takes an orphan only when no other survivor can reach it).
    """
    for uav in (10, 20, 40):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MissionTargets(mission=5, team=FOUR_TEAM, targets=TWO_TARGETS), 0.0)
    core.on_result(UavResult(5, 10, (10.0, 50.0)), 0.1)
    core.on_result(UavResult(5, 20, (40.0, 20.0)), 0.1)
    core.on_result(UavResult(5, 40, times_40), 0.1)
    core.tick(0.2)
    core.on_telemetry(sample_telemetry(), 1.0)
    core.on_alive(20, False, 1.0)
    assert core.phase == Phase.COMMITTED and core.round is not None
    assert core.round.committed is not None and core.round.committed.target == 1


def tick_without_telemetry(core: OnboardCore, start: float, end: float) -> float:
    now = start
    while now < end:
        now += 0.25
        core.tick(now)
    return now
