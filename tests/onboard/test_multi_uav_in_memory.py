"""Several UAVs agreeing on missions, in the test's process: the real onboard process
logic and simulated autopilots on the in-process bus (tests/support/memory_world.py),
the test as the ground station. The claims are the consensus's (agreement, a result
lost on the bus, a mission superseded 50 ms later or in flight, the targets reached) and
need no process; what does (a UAV killed, frozen or started late) is
tests/onboard/test_multi_uav.py."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import distance_m
from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target
from fleet.sim.scenario import shipped_scenario
from fleet.transport.bus import Bus
from fleet.transport.faulty_bus import FaultRule
from onboard.core import TARGET_WAYPOINT
from tests.onboard.test_multi_uav import assert_agreed
from tests.support.ground_view import GroundView
from tests.support.memory_world import MemoryFleet, memory_fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
#: Simulated seconds per wall second for the flights to the targets.
FLIGHT_SPEEDUP = 60.0
#: ...and while the UAVs plan them: the wall clock's pace, as in flight. Sped up, a
#: planner that gets the CPU late on a loaded machine would plan from a position a
#: minute of flight stale and could take the other UAV's target.
PLANNING_SPEEDUP = 1.0
#: Two missions this far apart: the second supersedes the first on every UAV.
GAP_S = 0.05


def far_targets(count: int) -> tuple[Target, ...]:
    """Targets 8-9 km out: a time computed for a ring target (0.5-2.5 km) is far shorter."""
    near = ring_targets(count, seed=3)
    return tuple(Target(t.lat + 0.075, t.lon, t.alt) for t in near)


@contextmanager
def ring(
    tmp_path: Path, count: int, **options: object
) -> Iterator[tuple[MemoryFleet, Bus, GroundView]]:
    """`count` UAVs on a ring in memory, a ground's bus and what it sees."""
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(count))
    with memory_fleet(str(scenario), **options) as fleet:  # type: ignore[arg-type]
        ground = fleet.bus()
        seen = GroundView.on_bus(ground)
        try:
            yield fleet, ground, seen
        finally:
            seen.close()


def send(ground: Bus, mission: MissionTargets) -> None:
    ground.publish(SPACE.mission_targets(mission.mission), mission)


def test_five_uavs_eight_targets_then_four_uavs_two_targets(tmp_path: Path) -> None:
    with ring(tmp_path, 5) as (fleet, ground, seen):
        team = set(fleet.ids)
        targets = ring_targets(8, seed=5)
        send(ground, MissionTargets(mission=1, team=tuple(sorted(team)), targets=targets))
        wait_until(lambda: len(seen.assignments) == 5, 60.0, "five assignments")
        assert_agreed(dict(seen.assignments), team, 8)
        assert seen.assignments[min(team)].unassigned == ()  # three queued behind others

        # A new mission supersedes the first: four of them, two targets.
        four = sorted(team)[:4]
        seen.assignments.clear()
        send(ground, MissionTargets(mission=2, team=tuple(four), targets=ring_targets(2, seed=6)))
        wait_until(
            lambda: (
                {r.mission for r in seen.assignments.values()} == {2} and len(seen.assignments) == 4
            ),
            60.0,
            "four assignments",
        )
        assert_agreed(dict(seen.assignments), set(four), 2)
        idle = [u for u, r in seen.assignments.items() if r.target is None]
        assert len(idle) == 2
        for uav in idle:

            def says_so(uav: int = uav) -> bool:
                return any("keeping course" in s for s in seen.statuses(uav))

            wait_until(says_so, 10.0, "idle UAVs saying so")


def test_lost_result_is_recovered_by_query(tmp_path: Path) -> None:
    first = 101  # the ring's first UAV (fleet.launch.ring)
    # The fault is the bus's, not the process's: the first publication of each of its
    # results is lost.
    own_results = FaultRule(f"{SPACE.prefix}/mission/*/result/{first}", drop_first=1)
    with ring(tmp_path, 2, faults={first: (own_results,)}) as (fleet, ground, seen):
        assert fleet.ids[0] == first
        second = fleet.ids[1]
        mission = MissionTargets(
            mission=1, team=(first, second), targets=ring_targets(3, seed=8), deadline_s=20.0
        )
        send(ground, mission)
        wait_until(lambda: len(seen.assignments) == 2, 30.0, "both assignments")
        assert first not in seen.results  # its result was never published...
        # ...yet its teammate used it: fetched by query well before the deadline.
        assert seen.assignments[second].team == (first, second)
        assert_agreed(dict(seen.assignments), {first, second}, 3)


@pytest.mark.parametrize("first_count", [3, 2], ids=["equal-counts", "different-counts"])
def test_a_second_mission_50_ms_later_supersedes_the_first_everywhere(
    tmp_path: Path, first_count: int
) -> None:
    with ring(tmp_path, 3) as (fleet, ground, seen):
        team = list(fleet.ids)
        wait_until(lambda: set(team) <= set(seen.telemetry), 30.0, "telemetry from every UAV")
        first = MissionTargets(mission=1, team=tuple(team), targets=ring_targets(first_count, 5))
        second = MissionTargets(mission=2, team=tuple(team), targets=far_targets(3))
        with seen.lock:
            starts = {uav: seen.telemetry[uav][-1].gps for uav in team}
        send(ground, first)
        time.sleep(GAP_S)  # the fault: the next mission, 50 ms later
        send(ground, second)

        def all_on_second() -> bool:
            with seen.lock:
                reports = dict(seen.assignments)
            return len(reports) == 3 and all(r.mission == 2 for r in reports.values())

        wait_until(all_on_second, 60.0, "every UAV committed mission 2")
        assert_agreed(dict(seen.assignments), set(team), 3)
        top_speed = AircraftLimits().max_airspeed
        for uav in team:
            result = seen.results[uav]
            assert result.mission == 2
            start = starts[uav]
            assert start is not None
            for target, time_s in zip(second.targets, result.times, strict=True):
                assert time_s is not None and math.isfinite(time_s)
                # Never a first-mission time: no aircraft covers the distance faster.
                # (0.7: the aircraft flies on, sped up, for a moment before it plans.)
                floor = distance_m((start.lat, start.lon), (target.lat, target.lon)) / top_speed
                assert time_s >= 0.7 * floor, f"UAV {uav}: {time_s:.0f} s < {floor:.0f} s"


def test_head_on_two_uavs_take_distinct_targets_reach_them_and_resume() -> None:
    scenario = shipped_scenario("head_on")
    targets = tuple(scenario.targets())
    # Heard from its start, as the ground hears an onboard process start: its first
    # tracked waypoint is what it resumes.
    with memory_fleet("head_on", speedup=PLANNING_SPEEDUP, ready=False) as fleet:
        ground = fleet.bus()
        seen = GroundView.on_bus(ground)
        try:
            wait_until(
                lambda: all(seen.latest_track(u) is not None for u in (74, 112)), 30.0, "tracks"
            )
            original = {uav: seen.latest_track(uav) for uav in (74, 112)}
            fleet.wait_ready()  # a position to plan from
            send(ground, MissionTargets(mission=1, team=(74, 112), targets=targets))
            wait_until(lambda: len(seen.assignments) == 2, 30.0, "both assignments")
            assert_agreed(dict(seen.assignments), {74, 112}, len(targets))
            pairs = seen.assignments[74].pairs
            assert pairs == {74: 0, 112: 1}  # the contested target goes to the faster UAV
            fleet.clock.set_speedup(FLIGHT_SPEEDUP)

            def back_on_course(uav: int) -> bool:
                tracks = seen.tracks.get(uav, [])
                if TARGET_WAYPOINT not in tracks:
                    return False
                after = tracks[tracks.index(TARGET_WAYPOINT) :]
                return any(t != TARGET_WAYPOINT for t in after)

            wait_until(lambda: back_on_course(74) and back_on_course(112), 90.0, "both resumed")
            for uav in (74, 112):
                target = targets[pairs[uav]]
                assert seen.closest_approach(uav, target.lat, target.lon) <= 75.0
                tracks = seen.tracks[uav]
                assert tracks[tracks.index(TARGET_WAYPOINT) + 1] == original[uav]
            # Target 2, unserved for good with one target each, is queued behind one.
            (holder,) = (uav for uav, queue in seen.assignments[74].queues.items() if 2 in queue)
            wait_until(
                lambda: any(
                    o.target == 2 and o.phase == "reached" for o in seen.outcomes_of(holder)
                ),
                120.0,
                f"UAV {holder} reaching target 2",
            )
            assert seen.closest_approach(holder, targets[2].lat, targets[2].lon) <= 75.0
        finally:
            seen.close()


def test_a_new_mission_in_flight_replaces_the_old_target_without_a_false_arrival(
    tmp_path: Path,
) -> None:
    with ring(tmp_path, 1) as (fleet, ground, seen):
        (uav,) = fleet.ids
        first = MissionTargets(mission=1, team=(uav,), targets=far_targets(1))
        send(ground, first)
        wait_until(
            lambda: any("mission 1: flying to target 0" in s for s in seen.statuses(uav)),
            30.0,
            "flying mission 1's target",
        )
        # The fault: a new mission arrives while the aircraft flies to the old target.
        second = MissionTargets(mission=2, team=(uav,), targets=ring_targets(1, seed=21))
        send(ground, second)
        wait_until(
            lambda: any("mission 2: flying to target 0" in s for s in seen.statuses(uav)),
            30.0,
            "flying mission 2's target",
        )
        statuses = seen.statuses(uav)
        assert not any(s.startswith("reached") for s in statuses), statuses  # 8 km short of it
        assert not any("could not resume" in s for s in statuses), statuses
        assert seen.assignments[uav].mission == 2
