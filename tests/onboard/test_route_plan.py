"""Approach times and flights around no-fly zones (onboard.planner.route_plan, onboard.route_flight,
onboard.zone_watch): the real planner and model, and the core with a recording output."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import legs_time, zone_map
from fleet.geo.wind import Wind, airspeed
from fleet.mission.messages import MissionTargets, NoFlyZone, StatusText, Target, UavResult
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from fleet.transport.bus_codec import DROPPED, DropReason
from onboard.loiter import LOITER_ANCHOR, LOITER_FAR
from onboard.planner.planner_worker import PlannerWorker, PlanRequest, PlanResult
from onboard.planner.route_plan import route_targets
from onboard.route_flight import ROUTE_WAYPOINTS, route_turns, route_writes
from onboard.target_flight import TARGET_WAYPOINT
from tests.onboard.core_harness import TARGETS, make_core, telemetry_at
from tests.onboard.test_planner_worker import wait_result

LIMITS = AircraftLimits()
V = 22.0
#: A box 600 m wide across the line from the origin to (3000, 0).
WALL = ((1200.0, -400.0), (1800.0, -400.0), (1800.0, 400.0), (1200.0, 400.0))
#: Boxes all around (0, -3000), overlapping once inflated: nothing gets in.
PEN = tuple(
    (
        (x - 150.0, y - 150.0),
        (x + 150.0, y - 150.0),
        (x + 150.0, y + 150.0),
        (x - 150.0, y + 150.0),
    )
    for x, y in (
        (600.0 * math.cos(k * math.pi / 4), -3000.0 + 600.0 * math.sin(k * math.pi / 4))
        for k in range(8)
    )
)
OPEN_AIR = (-2500.0, 1500.0)
BEHIND_WALL = (3000.0, 0.0)
PENNED = (0.0, -3000.0)


@pytest.fixture(scope="module")
def worker() -> Iterator[PlannerWorker]:
    with PlannerWorker(LIMITS) as planner:
        yield planner


def plan(worker: PlannerWorker, zones: tuple[tuple[tuple[float, float], ...], ...]) -> PlanResult:
    request = PlanRequest(
        position=(0.0, 0.0),
        velocity=(V, 0.0),
        targets=(OPEN_AIR, BEHIND_WALL, PENNED),
        budget_s=20.0,
        cruise_speed=V,
        zones=zones,
    )
    assert worker.run(request)
    return wait_result(worker)


def test_times_are_those_of_routes_around_the_zones(worker: PlannerWorker) -> None:
    free = plan(worker, ())
    around = plan(worker, (WALL, *PEN))
    # In open air the route is the straight line: the very time without zones.
    assert around.times[0] == pytest.approx(free.times[0], rel=1e-6)
    route = around.routes[1]
    assert route is not None and route.detours
    # Behind the wall: the model to the route's first turn, then straight legs.
    assert around.times[1] > free.times[1]
    assert around.times[1] == pytest.approx(route.length / V, rel=0.1)
    assert around.times[1] >= legs_time(route.points, V)
    # In the pen: no route, no time.
    assert around.routes[2] is None and around.times[2] == math.inf
    assert around.request.targets == (OPEN_AIR, BEHIND_WALL, PENNED)


def test_the_route_flown_is_inflated_exactly_as_the_route_timed_in_a_wind() -> None:
    # 32 m/s over the ground in a 12 m/s tailwind: 20 m/s through the air, the speed
    # whose turn radius both the time and the flight inflate the zones by.
    wind = Wind(east=12.0)
    projection = MercatorProjection(42.0, -71.0)
    gps = GpsBlock(lat=42.0, lon=-71.0, alt=100.0, vel_north=0.0, vel_east=32.0, vel_down=0.0)
    target = Target(*projection.to_latlon(*BEHIND_WALL), 100.0)
    zone = NoFlyZone(ring=tuple(projection.to_latlon(x, y) for x, y in WALL))
    wall = tuple(projection.to_xy(lat, lon) for lat, lon in zone.ring)
    timed = route_targets((0.0, 0.0), (32.0, 0.0), (BEHIND_WALL,), (wall,), LIMITS, wind).routes[0]
    assert timed is not None and timed.detours
    flown = route_turns(gps, target, (zone,), airspeed((32.0, 0.0), wind))
    assert flown is not None
    turns = [projection.to_xy(lat, lon) for lat, lon in flown]
    assert len(turns) == len(timed.points) - 1
    for turn, point in zip(turns, timed.points, strict=False):
        assert turn == pytest.approx(point, abs=0.01)
    # Inflated at the ground speed instead, the turns would be elsewhere.
    by_ground = zone_map((wall,), LIMITS, 32.0).route((0.0, 0.0), BEHIND_WALL)
    assert by_ground is not None
    assert max(math.dist(a, b) for a, b in zip(turns, by_ground.points, strict=False)) > 20.0


def test_a_route_is_written_target_first_then_each_turn_then_tracked() -> None:
    target = Target(42.35, -71.10, 130.0)
    turns = ((42.355, -71.09), (42.352, -71.095))
    writes, first = route_writes(TARGET_WAYPOINT, target, turns, back_to=2)
    assert [(w.index, w.next_index) for w in writes] == [(90, 2), (92, 90), (91, 92)]
    assert first == ROUTE_WAYPOINTS[0] == 91
    assert (writes[2].lat, writes[2].lon) == turns[0]
    assert route_writes(TARGET_WAYPOINT, target, (), back_to=2)[1] == TARGET_WAYPOINT


# A box between the aircraft (42.36, -71.09) and TARGETS[1] (42.35, -71.10).
BOX = NoFlyZone(
    ring=((42.3535, -71.0975), (42.3535, -71.0925), (42.3565, -71.0925), (42.3565, -71.0975)),
    name="box",
)


def test_the_core_flies_the_route_as_a_chain_of_echoed_waypoints() -> None:
    core, out = make_core()  # times (80, 40, 60): target 1 is this UAV's
    mission = MissionTargets(mission=1, team=(112,), targets=TARGETS, zones=(BOX,))
    core.on_targets(mission, 1.0)
    core.tick(1.1)
    now = 1.5
    written: list[Waypoint] = []
    while True:
        command = out.autopilot[-1]
        if isinstance(command, Track):
            break
        assert isinstance(command, Waypoint) and command not in written
        written.append(command)
        core.on_waypoint(command, now)  # the autopilot's echo: only then the next write
        now += 0.1
    assert command == Track(ROUTE_WAYPOINTS[0])
    # With zones the target leads to a loiter clear of them, never back to the course
    # (waypoint 2), which the module cannot see: written first, the far end first.
    loiter, written = written[:2], written[2:]
    pairs = [(w.index, w.next_index) for w in loiter]
    assert pairs == [(LOITER_FAR, LOITER_ANCHOR), (LOITER_ANCHOR, LOITER_FAR)]
    assert written[0].index == TARGET_WAYPOINT and written[0].next_index == LOITER_ANCHOR
    turns = written[1:]
    assert turns and all(w.index in ROUTE_WAYPOINTS for w in turns)
    # The chain: 91 -> ... -> 90 -> the loiter.
    chain = {w.index: w.next_index for w in written}
    index, seen = ROUTE_WAYPOINTS[0], []
    while index != LOITER_ANCHOR:
        seen.append(index)
        index = chain[index]
    assert seen[-1] == TARGET_WAYPOINT and len(seen) == len(written)
    core.on_track(Track(ROUTE_WAYPOINTS[0]), now)
    assert any("flying to target 1" in s for s in out.statuses())


def test_a_target_no_route_reaches_is_answered_none() -> None:
    core, out = make_core(times=(80.0, math.inf, 60.0))
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS, zones=(BOX,)), 1.0)
    core.tick(1.1)
    (result,) = [m for _, m in out.published if isinstance(m, UavResult)]
    assert result.times == (80.0, None, 60.0)


def test_an_incursion_is_an_error_status_and_leaving_is_said() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS, zones=(BOX,)), 1.0)
    core.on_telemetry(telemetry_at(42.355, -71.095), 2.0)
    core.on_telemetry(telemetry_at(42.355, -71.096), 2.2)  # still inside: said once
    core.on_telemetry(telemetry_at(42.36, -71.09), 3.0)
    statuses = [m for _, m in out.published if isinstance(m, StatusText)]
    kinds = [
        s.kind for s in statuses if s.kind in (StatusKind.ZONE_INCURSION, StatusKind.ZONE_LEFT)
    ]
    assert kinds == [StatusKind.ZONE_INCURSION, StatusKind.ZONE_LEFT]
    incursion = next(s for s in statuses if s.kind is StatusKind.ZONE_INCURSION)
    assert "no-fly zone 0 (box)" in incursion.text and incursion.mission == 1


def test_a_mission_with_a_bad_zone_or_a_target_inside_one_is_refused_and_counted() -> None:
    core, out = make_core()
    bowtie = NoFlyZone(ring=((42.0, -71.0), (42.1, -70.9), (42.1, -71.0), (42.0, -70.9)))
    around_target = NoFlyZone(
        ring=((42.34, -71.11), (42.34, -71.09), (42.355, -71.09), (42.355, -71.11))
    )
    before = DROPPED.counts().get(DropReason.INVALID, 0)
    for mission, zone in ((1, bowtie), (2, around_target)):
        core.on_targets(MissionTargets(mission, (112,), TARGETS, zones=(zone,)), 1.0)
    refusals = [
        m for _, m in out.published
        if isinstance(m, StatusText) and m.kind is StatusKind.MISSION_REFUSED
    ]  # fmt: skip
    assert [r.mission for r in refusals] == [1, 2]
    assert "edges 0 and 2 cross" in refusals[0].text
    assert "target 1 is inside no-fly zone 0" in refusals[1].text
    assert DROPPED.counts().get(DropReason.INVALID, 0) == before + 2
    assert core.round is None  # neither started


def test_leaving_the_route_at_a_turn_is_noticed_and_moving_along_it_is_not() -> None:
    core, out = make_core()
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS, zones=(BOX,)), 1.0)
    core.tick(1.1)
    now = 1.5
    while not isinstance(out.autopilot[-1], Track):
        command = out.autopilot[-1]
        assert isinstance(command, Waypoint)
        core.on_waypoint(command, now)
        now += 0.1
    core.on_track(Track(ROUTE_WAYPOINTS[0]), now)
    assert core.phase == "flying"
    if len(core.flight.route) > 1:
        core.on_track(Track(ROUTE_WAYPOINTS[1]), now + 1)  # the autopilot's own sequencing
        assert core.phase == "flying"
    core.on_track(Track(3), now + 2)  # somewhere else: off the route, far from the target
    assert core.phase == "preempted"
    assert any("target not reached" in s for s in out.statuses())


def test_a_routes_legs_are_timed_in_the_wind_of_the_plan() -> None:
    """The legs after the route's first point fly in the plan's wind: into a headwind
    they take longer than in still air, and the airspeed is the ground speed less it."""
    calm = route_targets((0.0, 0.0), (V, 0.0), (BEHIND_WALL,), (WALL,), LIMITS)
    # A 6 m/s wind from the east; the aircraft holds 22 m/s through the air.
    headwind = Wind(-6.0, 0.0)
    windy = route_targets((0.0, 0.0), (V - 6.0, 0.0), (BEHIND_WALL,), (WALL,), LIMITS, headwind)
    route = calm.routes[0]
    assert route is not None and route.detours
    assert windy.routes[0] == route
    assert windy.rest_s[0] > calm.rest_s[0]
    assert windy.rest_s[0] == pytest.approx(legs_time(route.points, V, headwind))


def test_the_planner_routes_at_the_airspeed_of_its_request_as_the_flight_does() -> None:
    # The air data says 28 m/s; the GPS less the wind would say 20: the route is timed,
    # and flown, inflated at the request's 28.
    at_request = route_targets(
        (0.0, 0.0), (32.0, 0.0), (BEHIND_WALL,), (WALL,), LIMITS, Wind(east=12.0), speed=28.0
    ).routes[0]
    fast = zone_map((WALL,), LIMITS, 28.0).route((0.0, 0.0), BEHIND_WALL)
    slow = zone_map((WALL,), LIMITS, 20.0).route((0.0, 0.0), BEHIND_WALL)
    assert at_request is not None and fast is not None and slow is not None
    assert at_request.points == fast.points != slow.points
