"""Thesis 4.3 end to end: the simulated autopilot over a real serial link (socket://),
the onboard module as its own process, a real Zenoh router, and the test as the ground.
"""

from __future__ import annotations

import math
from importlib.resources import files

from fleet.files.targets_io import read_targets
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets
from onboard.core import TARGET_WAYPOINT
from tests.conftest import Ground
from tests.support.processes import Fleet
from tests.support.waiting import wait_until

SPACE = KeySpace()

ACCEPTANCE_RADIUS_M = 60.0  # the simulator's default


def test_single_uav_flies_its_queue_fastest_first_reaches_each_and_resumes(
    fleet: Fleet, ground: Ground
) -> None:
    targets = tuple(read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin")))
    seen, router = ground.seen, ground.router
    endpoints = fleet.sim("single_uav", speedup=10.0, telemetry_hz=5.0)
    onboard = fleet.onboard(112, endpoints[112], router)
    wait_until(lambda: 112 in seen.telemetry, 30.0, "telemetry from UAV 112 on Zenoh")
    wait_until(lambda: seen.latest_track(112) is not None, 30.0, "the tracked waypoint")
    original = seen.latest_track(112)
    assert original is not None and original != TARGET_WAYPOINT

    mission = MissionTargets(mission=1, team=(112,), targets=targets, deadline_s=10.0)
    ground.send(mission)

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

    wait_until(lambda: TARGET_WAYPOINT in seen.tracks.get(112, []), 30.0, "tracking the target")
    for index in queue:
        wait_until(
            lambda index=index: any(
                f"reached target {index}" in s for s in seen.status.get(112, [])
            ),
            120.0,
            f"target {index} reached",
        )
        target = targets[index]
        closest = seen.closest_approach(112, target.lat, target.lon)
        assert closest <= ACCEPTANCE_RADIUS_M + 15.0  # telemetry samples every ~5 m of flight
    # Back on its flight plan: the waypoint after the last target is the one it was
    # tracking before the mission.
    wait_until(lambda: seen.latest_track(112) == original, 60.0, "back on its flight plan")
    assert onboard.process.poll() is None
    assert onboard.stop() == 0


# Status on change, the periodic report the state: in memory,
# tests/onboard/test_process_in_memory.py.
