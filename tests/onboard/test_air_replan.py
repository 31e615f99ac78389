"""A re-plan in the air of now, as two UAVs' modules run it (onboard.air_watch,
fleet.consensus.membership `asked`): the wind one UAV flies in moves away from the wind
its plan timed its legs in, it asks once, its teammate takes the ask from its standing,
and both commit one plan solved again from their fresh times and air; gusts ask
nothing."""

from __future__ import annotations

import math
from collections.abc import Callable

import msgspec

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    StatusText,
    UavResult,
)
from fleet.mission.objective import Objective
from fleet.mission.phase import Phase
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.air_watch import AIR_INTERVAL_S
from onboard.core import TARGET_WAYPOINT, OnboardCore
from tests.onboard.core_harness import TARGETS, Recorder, ScriptedPlanner, make_core
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()
TEAM = (74, 112)


def _telemetry(
    clock_s: float, wind_east: float, where: tuple[float, float] | None = None
) -> Telemetry:
    """The sample telemetry at `clock_s` on the aircraft's clock, its autopilot's wind
    estimate blowing `wind_east` m/s to the east (at `where`, latitude and longitude,
    instead of the sample's position)."""
    sample = sample_telemetry(round(clock_s * 1000))
    assert sample.sensor is not None and sample.gps is not None
    sensor = msgspec.structs.replace(sample.sensor, wind_west=-wind_east)
    gps = sample.gps
    if where is not None:
        gps = msgspec.structs.replace(gps, lat=where[0], lon=where[1])
    return msgspec.structs.replace(sample, sensor=sensor, gps=gps)


class Pair:
    """Two modules whose every put reaches the other, as the bus would carry it."""

    def __init__(self) -> None:
        self.cores: dict[int, tuple[OnboardCore, Recorder]] = {}
        self._seen: dict[int, int] = {}
        times = {74: (10.0, 90.0, 95.0), 112: (80.0, 40.0, 60.0)}
        for uav in TEAM:
            core, out = make_core(uav=uav, times=times[uav], fresh_replans=True)
            self.cores[uav] = (core, out)
            self._seen[uav] = 0
        for uav, (core, _) in self.cores.items():
            for other in TEAM:
                if other != uav:
                    core.on_alive(other, True, 0.0)

    def relay(self, now: float) -> None:
        """Hand every put since the last relay to the other module."""
        moved = True
        while moved:
            moved = False
            for uav, (_, out) in self.cores.items():
                fresh = out.published[self._seen[uav] :]
                self._seen[uav] = len(out.published)
                for key, message in fresh:
                    moved = True
                    for other, (core, _) in self.cores.items():
                        if other == uav:
                            continue
                        if isinstance(message, UavResult):
                            core.on_result(message, now)
                        elif isinstance(message, AssignmentReport) and "/replan/" in key:
                            core.on_assignment(message, now)

    def fly(
        self,
        start: float,
        end: float,
        wind: Callable[[int, float], float],
        where: dict[int, tuple[float, float]] | None = None,
    ) -> None:
        """Both modules from `start` to `end` (s), telemetry each second with the
        autopilots' wind `wind(uav, t)` (at `where[uav]`, else the sample's position),
        their clocks the same as `now`."""
        now = start
        while now < end:
            now += 1.0
            for uav, (core, _) in self.cores.items():
                at = (where or {}).get(uav)
                core.on_telemetry(_telemetry(now, wind(uav, now), at), now)
                core.tick(now)
            self.relay(now)

    def replans(self, uav: int) -> list[AssignmentReport]:
        _, out = self.cores[uav]
        return [m for m in out.on(SPACE.mission_replan(1, uav)) if isinstance(m, AssignmentReport)]

    def standings(self, uav: int) -> list[UavResult]:
        _, out = self.cores[uav]
        results = out.on(SPACE.mission_result(1, uav))
        return [m for m in results if isinstance(m, UavResult) and m.basis is not None]


def _committed_pair() -> Pair:
    """Mission 1 of three targets, min-sum: 74 flies targets 0 then 2, 112 target 1."""
    pair = Pair()
    mission = MissionTargets(mission=1, team=TEAM, targets=TARGETS, objective=Objective.MIN_SUM)
    for core, _ in pair.cores.values():
        core.on_targets(mission, 1.0)
    for core, _ in pair.cores.values():
        core.tick(1.1)
    pair.relay(1.1)
    for core, _ in pair.cores.values():
        core.tick(1.2)
    pair.relay(1.2)
    for uav, (core, out) in pair.cores.items():
        assert core.round is not None and core.round.committed is not None, uav
        assert core.round.committed.queues == {74: (0, 2), 112: (1,)}
        (waypoint,) = out.autopilot  # the autopilot echoes its target and tracks it
        assert isinstance(waypoint, Waypoint)
        core.on_waypoint(waypoint, 1.3)
        core.on_track(Track(TARGET_WAYPOINT), 1.4)
        assert core.phase == Phase.FLYING
    return pair


def test_a_wind_change_beyond_the_threshold_makes_one_re_plan_from_fresh_times_and_air() -> None:
    pair = _committed_pair()
    core_74, out_74 = pair.cores[74]
    assert core_74.round is not None
    epoch0 = core_74.round.committed
    assert epoch0 is not None
    # The wind 74 flies in turns 1.5 m/s away from the calm its result carried; 112's
    # stays calm. New times from here on: the fresh standings must carry them.
    for core, _ in pair.cores.values():
        assert isinstance(core.planner, ScriptedPlanner)
        core.planner.times = tuple(t - 5.0 for t in core.planner.times)

    def turned(uav: int, t: float) -> float:
        return 1.5 if uav == 74 else 0.0

    pair.fly(1.2, 2.5 * AIR_INTERVAL_S, turned)
    for uav in TEAM:
        (replan,) = pair.replans(uav)  # exactly one re-plan, solved again
        assert replan.epoch == 1 and replan.released == ()
        assert replan.asked == {74: 1} and replan.basis is not None
    plans = [pair.replans(uav)[0] for uav in TEAM]
    assert len({(p.digest, str(p.queues), str(p.arrivals)) for p in plans}) == 1
    plan = plans[0]
    assert plan.digest != epoch0.digest
    # 74 asked, in its standing (its count, its wind of now); 112 stood for the same epoch.
    (asking,) = pair.standings(74)
    (standing_112,) = pair.standings(112)
    assert asking.asked == 1 and standing_112.asked == 0
    assert asking.basis == standing_112.basis == plan.basis
    assert asking.wind_east is not None and asking.wind_east > 1.0
    assert standing_112.wind_east == 0.0
    # Its first arrival is its fresh time to the target it flies, kept first, not the
    # time of the start; its next leg is timed in its wind of now.
    assert epoch0.arrivals[74][0] == 10.0
    assert plan.queues[74] == (0, 2)
    assert plan.arrivals[74][0] == asking.times[0] == 5.0
    assert plan.arrivals[74][1] - 5.0 != epoch0.arrivals[74][1] - 10.0
    said = [m.text for _, m in out_74.published if isinstance(m, StatusText)]
    assert any("asking the team to re-plan in the air of now" in text for text in said)
    _, out_112 = pair.cores[112]
    said_112 = [m.text for _, m in out_112.published if isinstance(m, StatusText)]
    assert any("UAV 74 asks for a re-plan in the air of now" in text for text in said_112)
    # The plan in force is timed in that air now: a wind that stays there asks no more.
    pair.fly(2.5 * AIR_INTERVAL_S, 5 * AIR_INTERVAL_S, turned)
    assert [len(pair.replans(uav)) for uav in TEAM] == [1, 1]


def test_gusts_below_the_threshold_or_shorter_than_the_dwell_make_no_re_plan() -> None:
    pair = _committed_pair()

    def gusty(uav: int, t: float) -> float:
        # 0.6 m/s of wander, and a 4 m/s gust for 8 s every 90 s: the 20 s average lifts
        # over 1 m/s for ~20 s each time, shorter than the dwell.
        return 4.0 if t % 90 < 8 else 0.6 * math.sin(t / 11.0)

    pair.fly(1.2, 6 * AIR_INTERVAL_S, gusty)
    assert [pair.replans(uav) for uav in TEAM] == [[], []]
    assert [pair.standings(uav) for uav in TEAM] == [[], []]


def test_a_smaller_change_makes_one_re_plan_just_before_a_leg_begins_not_in_flight() -> None:
    """0.6 m/s off the plan's air (under the in-flight threshold, over the one just
    before a leg): nothing while 74's target is minutes away; one re-plan once 74 is
    within a minute of its target 0, with target 2 after it (onboard.air_watch)."""
    pair = _committed_pair()

    def drifted(uav: int, t: float) -> float:
        return 0.6 if uav == 74 else 0.0

    pair.fly(1.2, 2.5 * AIR_INTERVAL_S, drifted)  # 1.4 km from target 0: over a minute
    assert [pair.replans(uav) for uav in TEAM] == [[], []]
    near = {74: (42.366, -71.084)}  # ~600 m from target 0 (42.37, -71.08): ~30 s
    pair.fly(2.5 * AIR_INTERVAL_S, 3 * AIR_INTERVAL_S, drifted, near)
    for uav in TEAM:
        (replan,) = pair.replans(uav)
        assert replan.asked == {74: 1} and replan.epoch == 1
    assert len({pair.replans(uav)[0].digest for uav in TEAM}) == 1
