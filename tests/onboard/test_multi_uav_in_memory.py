"""Several UAVs agreeing on missions, in the test's process: the real onboard process
logic and simulated autopilots on the in-process bus (tests/support/memory_world.py),
the test as the ground station. The claims are the consensus's (agreement, a result
lost on the bus, a mission superseded 50 ms later) and need no process; what does (a
UAV killed, frozen or started late, flying over serial links to the targets) is
tests/onboard/test_multi_uav.py and tests/onboard/test_quick_succession.py."""

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
from fleet.mission.messages import MissionTargets
from fleet.transport.bus import Bus
from fleet.transport.faulty_bus import FaultRule
from tests.onboard.test_multi_uav import assert_agreed
from tests.onboard.test_quick_succession import GAP_S, far_targets
from tests.support.ground_view import GroundView
from tests.support.memory_world import MemoryFleet, memory_fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()


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
