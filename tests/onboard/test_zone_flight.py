"""A target behind a no-fly zone, flown in memory: the real onboard process logic and the
real simulated autopilot (tests/onboard/test_in_memory.py's world), the simulator logging
incursions from its own positions."""

from __future__ import annotations

import threading
from importlib.resources import files

import msgspec

from fleet.files.targets_io import read_targets
from fleet.geo.mercator import MercatorProjection
from fleet.mission.messages import MissionTargets, NoFlyZone, TargetOutcome
from fleet.mission.phase import Phase
from fleet.transport.bus import BusSample
from onboard.route_flight import ROUTE_WAYPOINTS
from onboard.target_flight import TARGET_WAYPOINT
from tests.onboard.test_in_memory import SPACE, UAV, running_world
from tests.support.waiting import wait_until

#: The single-UAV scenario's local plane: 112 starts at (-2000, 0) flying east, its
#: target 1 is at (-68, -518).
PLANE = MercatorProjection(35.72, -120.765)
#: A box across the straight line from the start to target 1, and across the course.
BOX = NoFlyZone(
    ring=tuple(
        PLANE.to_latlon(x, y) for x, y in ((-800, -700), (-400, -700), (-400, 100), (-800, 100))
    ),
    name="box",
)


def test_a_target_behind_a_zone_is_reached_around_it_with_no_incursion() -> None:
    targets = tuple(read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin")))
    with running_world(zones=(BOX,)) as world:
        outcomes: list[TargetOutcome] = []
        lock = threading.Lock()

        def on_outcome(sample: BusSample) -> None:
            with lock:
                outcomes.append(msgspec.json.decode(sample.payload, type=TargetOutcome))

        world.ground.subscribe(SPACE.mission_outcome(1, UAV), on_outcome)
        wait_until(lambda: len(world.seen.telemetry) >= 2, 30.0, "telemetry")
        mission = MissionTargets(mission=1, team=(UAV,), targets=(targets[1],), zones=(BOX,))
        world.ground.publish(SPACE.mission_targets(1), mission)
        autopilot = world.aircraft.autopilot
        wait_until(lambda: autopilot.tracked in ROUTE_WAYPOINTS, 60.0, "the route's first turn")
        wait_until(lambda: autopilot.tracked == TARGET_WAYPOINT, 120.0, "the last leg")
        wait_until(
            lambda: any(o.phase == Phase.REACHED for o in outcomes), 120.0, "the target reached"
        )
        assert autopilot.zone_log.incursions == 0
        time_s = world.seen.results[UAV].times[0]
        assert time_s is not None
        # The straight line (2 km) would take about 90 s; around the box it is longer.
        assert time_s > 2000.0 / 22.0
