"""Thesis 4.3 in the test's process: the real onboard process logic and the simulated
autopilot on in-memory links and the in-process bus (tests/support/memory_world.py), the
test as the ground station. The claim is the queue flown, which needs no process."""

from __future__ import annotations

import math
from importlib.resources import files

from fleet.files.targets_io import read_targets
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets
from onboard.core import TARGET_WAYPOINT
from tests.support.ground_view import GroundView
from tests.support.memory_world import memory_fleet
from tests.support.waiting import wait_until

SPACE = KeySpace()

ACCEPTANCE_RADIUS_M = 60.0  # the simulator's default
#: Simulated seconds per wall second: the queue is some 10 km of flight.
SPEEDUP = 100.0
#: ...but the wall clock's pace while the UAV plans: sped up, a planner that gets the
#: CPU late on a loaded machine would plan from a position long flown past.
PLANNING_SPEEDUP = 1.0


def test_single_uav_flies_its_queue_fastest_first_reaches_each_and_resumes() -> None:
    targets = tuple(read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin")))
    # Heard from its start, as the ground hears an onboard process start: the first
    # tracked waypoint is the flight plan it resumes.
    with memory_fleet("single_uav", speedup=PLANNING_SPEEDUP, ready=False) as fleet:
        ground = fleet.bus()
        seen = GroundView.on_bus(ground)
        try:
            wait_until(lambda: 112 in seen.telemetry, 30.0, "telemetry from UAV 112 on the bus")
            wait_until(lambda: seen.latest_track(112) is not None, 30.0, "the tracked waypoint")
            original = seen.latest_track(112)
            assert original is not None and original != TARGET_WAYPOINT

            mission = MissionTargets(mission=1, team=(112,), targets=targets, deadline_s=10.0)
            ground.publish(SPACE.mission_targets(mission.mission), mission)

            wait_until(lambda: 112 in seen.assignments, 30.0, "UAV 112's assignment")
            report = seen.assignments[112]
            times = seen.results[112].times
            assert all(t is not None for t in times)
            fastest = min(range(len(times)), key=lambda i: times[i] or math.inf)
            assert report.target == fastest == 1  # the scenario's target ahead, 15 deg right
            # One UAV and three targets: all three in its queue, the fastest first.
            queue = report.queues[112]
            assert report.team == (112,) and report.unassigned == ()
            assert queue[0] == fastest and sorted(queue) == [0, 1, 2]
            fleet.clock.set_speedup(SPEEDUP)

            wait_until(
                lambda: TARGET_WAYPOINT in seen.tracks.get(112, []), 30.0, "tracking the target"
            )
            for index in queue:
                wait_until(
                    lambda index=index: any(
                        f"reached target {index}" in s for s in seen.statuses(112)
                    ),
                    120.0,
                    f"target {index} reached",
                )
                target = targets[index]
                closest = seen.closest_approach(112, target.lat, target.lon)
                # telemetry samples every ~5 m of flight
                assert closest <= ACCEPTANCE_RADIUS_M + 15.0
            # Back on its flight plan: the waypoint after the last target is the one it
            # was tracking before the mission.
            wait_until(lambda: seen.latest_track(112) == original, 60.0, "back on its flight plan")
            assert not fleet.processes[112].stop_requested.is_set()
        finally:
            seen.close()


# Status on change, the periodic report the state: in memory,
# tests/onboard/test_process_in_memory.py.
