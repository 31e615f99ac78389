"""Serial outages, end to end. At the commitment: the target writes are retried across
it and confirmed by the autopilot's echo once the link is back; the UAV reaches its
target and never reports the mission failed. Just before the arrival: the autopilot
moving on from the target waypoint is the arrival, reported as reached."""

from __future__ import annotations

import math
import time
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from fleet.geo.mercator import MercatorProjection
from fleet.launch.ring import ring_scenario
from fleet.mission.messages import MissionTargets, Target
from fleet.mission.phase import Phase
from fleet.mission.target_checks import REACHED_RADIUS_M
from fleet.sim.flight_plan import racetrack
from onboard.core import CONFIRM_LIMIT_S, LINK_LOST_S, TARGET_WAYPOINT
from tests.conftest import Ground
from tests.onboard.test_multi_uav import wait_for_telemetry
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.tcp_proxy import CuttableProxy, cuttable_proxy
from tests.support.waiting import wait_until

#: Longer than the old give-up (4 attempts, 2 s) and than LINK_LOST_S; shorter than
#: the limit after which the target is given up.
OUTAGE_S = 8.0
#: How long an outage lasts after the simulator logged an arrival (wall seconds).
PAST_S = 4.0


@contextmanager
def one_uav_behind_a_proxy(
    fleet: Fleet, ground: Ground, tmp_path: Path, speedup: float
) -> Iterator[tuple[int, CuttableProxy]]:
    """One simulated UAV whose onboard reaches its autopilot through a proxy the test
    can cut; yielded once its telemetry flows."""
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(1))
    ((uav, where),) = fleet.sim(str(scenario), speedup, 5.0).items()
    with cuttable_proxy(where.program) as proxy:
        fleet.onboard(uav, replace(where, program=proxy.url), ground.router)
        wait_for_telemetry(ground, [uav])
        yield uav, proxy


def cut_near(
    ground: Ground, uav: int, proxy: CuttableProxy, target: Target, near_m: float, within_s: float
) -> None:
    """Send `uav` the one `target`, and cut its autopilot link once it flies to it and is
    within `near_m` of it (the fault: the link drops just before the arrival)."""
    seen = ground.seen
    ground.send(MissionTargets(mission=1, team=(uav,), targets=(target,)))
    wait_until(lambda: any("flying to target 0" in s for s in seen.statuses(uav)), 30.0, "flying")
    wait_until(
        lambda: seen.closest_approach(uav, target.lat, target.lon) < near_m,
        within_s,
        f"{near_m:g} m from the target",
    )
    proxy.cut()


def test_target_writes_are_retried_across_a_serial_outage_at_the_commitment(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    assert LINK_LOST_S < OUTAGE_S < CONFIRM_LIMIT_S
    seen = ground.seen
    with one_uav_behind_a_proxy(fleet, ground, tmp_path, 2.0) as (uav, proxy):
        targets = ring_targets(1, seed=4)
        ground.send(MissionTargets(mission=1, team=(uav,), targets=targets))
        proxy.cut()  # the fault: the link drops as the UAV plans and commits
        wait_until(lambda: uav in seen.assignments, 30.0, "the commitment")
        assert seen.latest_track(uav) != TARGET_WAYPOINT  # not echoed: the link is down
        # The outage lasts until the module has seen it (LINK_LOST_S without telemetry),
        # well within the confirm limit; the module keeps retrying meanwhile.
        wait_until(
            lambda: any("autopilot link lost" in s for s in seen.statuses(uav)),
            OUTAGE_S,
            "the outage seen by the module",
        )
        proxy.restore()
        wait_until(
            lambda: any("flying to target 0" in s for s in seen.statuses(uav)),
            60.0,
            "flying once the echo arrives",
        )
        wait_until(
            lambda: any("reached target 0" in s for s in seen.statuses(uav)), 120.0, "reached"
        )
    statuses = seen.statuses(uav)
    assert any("autopilot link lost" in s for s in statuses)  # the outage was seen
    assert not any("cannot fly" in s or "not confirmed" in s for s in statuses), statuses
    target = targets[0]
    assert seen.closest_approach(uav, target.lat, target.lon) <= 75.0


def test_a_target_reached_during_a_link_outage_is_reported_reached(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    seen = ground.seen
    with one_uav_behind_a_proxy(fleet, ground, tmp_path, 3.0) as (uav, proxy):
        # A target 1.5 km dead ahead: the route to it is straight.
        gps = seen.telemetry[uav][-1].gps
        assert gps is not None
        course = math.atan2(gps.vel_north, gps.vel_east)
        lat, lon = MercatorProjection(gps.lat, gps.lon).to_latlon(
            1500.0 * math.cos(course), 1500.0 * math.sin(course)
        )
        cut_near(ground, uav, proxy, Target(lat, lon, gps.alt), 400.0, 60.0)
        # The outage lasts until the simulator's own log says the aircraft arrived and
        # its autopilot moved on (60 m short of the target), and then for as long as it
        # takes to fly on past it: PAST_S at 66 m/s is 200 m beyond the telemetry's
        # 75 m radius. The module has noticed the link lost meanwhile.
        sim = fleet.children[0]
        arrived = f"uav {uav}: reached waypoint {TARGET_WAYPOINT}"
        wait_until(lambda: any(arrived in line for line in sim.history), 30.0, "the arrival")
        arrived_at = time.monotonic()
        wait_until(
            lambda: (
                time.monotonic() - arrived_at > PAST_S
                and any("autopilot link lost" in s for s in seen.statuses(uav))
            ),
            30.0,
            "the aircraft past its target, unseen",
        )
        proxy.restore()
        wait_until(
            lambda: any("reached target 0" in s for s in seen.statuses(uav)), 60.0, "reached"
        )
    statuses = seen.statuses(uav)
    assert not any("target not reached" in s for s in statuses), statuses
    reached = next(s for s in statuses if "reached target 0" in s)
    assert "during a link outage" in reached  # the autopilot's word: no fix was near it
    assert seen.closest_approach(uav, lat, lon) > REACHED_RADIUS_M  # telemetry never saw it
    assert any(o.phase == Phase.REACHED for o in seen.outcomes_of(uav))


#: How far short of the course's waypoint 0 the target lies (m): the autopilot reaches
#: the target, its `next` (waypoint 0) 150 m on, and moves on to waypoint 1, all unseen.
SHORT_OF_WAYPOINT_M = 150.0


def test_an_arrival_hidden_by_an_outage_that_also_hid_the_next_waypoint_is_reached(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    seen = ground.seen
    with one_uav_behind_a_proxy(fleet, ground, tmp_path, 3.0) as (uav, proxy):
        # The ring's one UAV starts at corner 3 of its racetrack, tracking corner 0 3 km
        # dead ahead (fleet.sim.flight_plan.racetrack).
        (spec,) = tomllib.loads(ring_scenario(1))["uav"]
        corners = racetrack(spec["lat"], spec["lon"], spec["alt"], spec["heading"])
        course = MercatorProjection(spec["lat"], spec["lon"])
        x0, y0 = course.to_xy(corners[0][0], corners[0][1])
        along = 1.0 - SHORT_OF_WAYPOINT_M / math.hypot(x0, y0)
        lat, lon = course.to_latlon(x0 * along, y0 * along)
        cut_near(ground, uav, proxy, Target(lat, lon, 600.0), 500.0, 120.0)
        # The simulator's own log: the target, then waypoint 0, both passed unseen.
        sim = fleet.children[0]
        wait_until(
            lambda: any(f"uav {uav}: reached waypoint 0, on to 1" in s for s in sim.history),
            60.0,
            "the autopilot past the target and its next waypoint",
        )
        assert any(f"reached waypoint {TARGET_WAYPOINT}, on to 0" in s for s in sim.history)
        wait_until(
            lambda: any("autopilot link lost" in s for s in seen.statuses(uav)),
            30.0,
            "the outage seen by the module",
        )
        proxy.restore()
        wait_until(
            lambda: any("reached target 0" in s or "not reached" in s for s in seen.statuses(uav)),
            60.0,
            "the module's reading of the outage",
        )
    statuses = seen.statuses(uav)
    assert not any("target not reached" in s for s in statuses), statuses
    reached = next(s for s in statuses if "reached target 0" in s)
    assert "moved on to waypoint 1 during a link outage" in reached, reached
    assert seen.closest_approach(uav, lat, lon) > REACHED_RADIUS_M  # telemetry never saw it
    assert any(o.phase == Phase.REACHED for o in seen.outcomes_of(uav))
