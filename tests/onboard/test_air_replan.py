"""A re-plan in the air of now, as two UAVs' modules run it (onboard.air_watch,
fleet.consensus.membership `asked`): the wind one UAV flies in moves away from the wind
its plan timed its legs in, it asks once, its teammate takes the ask from its standing,
and both commit one plan solved again from their fresh times and air; gusts ask
nothing."""

from __future__ import annotations

import math
from collections.abc import Callable

import msgspec
import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    StatusText,
    Target,
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
#: A fourth target, 150 m from target 0.
NEAR_0 = Target(TARGETS[0].lat + 0.00135, TARGETS[0].lon, TARGETS[0].alt)


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
    """Modules whose every put reaches the others, as the bus would carry it (two by
    default), but for the links `cut` (from, to)."""

    def __init__(self, times: dict[int, tuple[float, ...]] | None = None) -> None:
        times = times or {74: (10.0, 90.0, 95.0), 112: (80.0, 40.0, 60.0)}
        team = tuple(times)
        self.team = team
        self.cores: dict[int, tuple[OnboardCore, Recorder]] = {}
        self._seen: dict[int, int] = {}
        self.cut: set[tuple[int, int]] = set()
        for uav in team:
            core, out = make_core(uav=uav, times=times[uav], fresh_replans=True)
            self.cores[uav] = (core, out)
            self._seen[uav] = 0
        for uav, (core, _) in self.cores.items():
            for other in team:
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
                        if other == uav or (uav, other) in self.cut:
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


def _committed_pair(
    times: dict[int, tuple[float, ...]] | None = None,
    queues: dict[int, tuple[int, ...]] | None = None,
) -> Pair:
    """Mission 1 of three targets, min-sum: 74 flies targets 0 then 2, 112 target 1
    (or, with `times`, of as many targets, to plan `queues`)."""
    pair = Pair(times)
    expected = queues or {74: (0, 2), 112: (1,)}
    targets = TARGETS if times is None else (*TARGETS, NEAR_0)
    mission = MissionTargets(
        mission=1, team=pair.team, targets=targets, objective=Objective.MIN_SUM
    )
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
        assert core.round.committed.queues == expected
        if uav not in expected:
            continue
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


THREE = (74, 112, 200)
#: Three UAVs, four targets: 74 flies 0 then 3 (legs ahead: it may ask), 112 flies 1 and
#: 200 flies 2.
TIMES_OF_THREE: dict[int, tuple[float, ...]] = {
    74: (10.0, 90.0, 95.0, 12.0),
    112: (80.0, 40.0, 60.0, 82.0),
    200: (95.0, 85.0, 30.0, 97.0),
}
QUEUES_OF_THREE = {74: (0, 3), 112: (1,), 200: (2,)}


def test_an_ask_is_believed_from_the_asker_alone_not_from_a_teammate_that_says_it_asked() -> None:
    """A report by 112 that says 74 asked for a re-plan in changed air (112 a captured
    identity, say) makes no epoch on 74 or 200; 200 asks 74 for its own word, which it
    has not got to give; 112's own ask, in its own report, is believed."""
    pair = _committed_pair(TIMES_OF_THREE, QUEUES_OF_THREE)
    core_112, _ = pair.cores[112]
    assert core_112.round is not None and core_112.round.committed is not None
    forged = msgspec.structs.replace(
        core_112.round.committed, epoch=1, asked={74: 1}, digest="f" * 16
    )
    for uav in (74, 200):
        core, _ = pair.cores[uav]
        core.on_assignment(forged, 2.0)
        core.tick(2.1)
        assert core.round is not None and core.round.membership.asked == {}, uav
        assert core.round.membership.epoch == 0 and core.round.awaiting is None, uav
        assert pair.replans(uav) == [] and pair.standings(uav) == [], uav
    _, out_200 = pair.cores[200]
    assert out_200.standing_fetches == [(1, (74,), "f" * 16)]  # 74's word asked for, once
    core_200, _ = pair.cores[200]
    core_200.on_assignment(forged, 2.2)
    assert out_200.standing_fetches == [(1, (74,), "f" * 16)]
    # Its own ask, in its own report: believed, an epoch like any other.
    own = msgspec.structs.replace(forged, asked={112: 1}, digest="e" * 16)
    core_200.on_assignment(own, 2.3)
    assert core_200.round is not None and core_200.round.membership.asked == {112: 1}
    assert core_200.round.membership.epoch == 1


@pytest.mark.parametrize("answerer", [74, 112], ids=["the asker", "a teammate relaying it"])
def test_a_uav_that_missed_the_askers_standing_takes_the_ask_from_the_askers_own_word(
    answerer: int,
) -> None:
    """74's wind turns and it asks; 200 hears nothing from 74 (a link cut one way), only
    112's re-plan, which says 74 asked: 200 makes no epoch of it but asks for 74's
    standing, and once 74's own word is in (from 74, or relayed by 112 as 74 signed it:
    74 may be gone), the three commit one plan, solved again."""
    pair = _committed_pair(TIMES_OF_THREE, QUEUES_OF_THREE)
    pair.cut.add((74, 200))

    def turned(uav: int, t: float) -> float:
        return 1.5 if uav == 74 else 0.0

    now = 1.2
    while not pair.replans(112):
        assert now < 2.5 * AIR_INTERVAL_S, "74 never asked"
        pair.fly(now, now + 1.0, turned)
        now += 1.0
    # 112 waited for 200's standing in vain, and committed the epoch's append plan.
    (replan_112,) = pair.replans(112)
    assert replan_112.asked == {74: 1} and replan_112.basis is None
    core_200, out_200 = pair.cores[200]
    assert core_200.round is not None and core_200.round.membership.asked == {}
    assert pair.replans(200) == [] and pair.standings(200) == []
    assert out_200.standing_fetches == [(1, (74,), replan_112.digest)]
    # 74 answers the query with its standing for that plan, as it put it; 112 relays
    # the one it holds, 74's own (in a process, with 74's signature).
    core, _ = pair.cores[answerer]
    if answerer == 74:
        answer = core.own_standing(1, replan_112.digest)
    else:
        answer = core.teammate_standing(1, 74, replan_112.digest)
    assert answer is not None and answer.uav == 74 and answer.asked == 1
    core_200.on_result(answer, now)
    pair.fly(now, now + 3.0, turned)
    assert core_200.round.membership.asked == {74: 1}
    latest = [pair.replans(uav)[-1] for uav in THREE]
    assert len({(p.digest, str(p.queues)) for p in latest}) == 1
    assert latest[0].asked == {74: 1} and latest[0].basis == replan_112.digest
