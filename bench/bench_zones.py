"""Routes around no-fly zones: planned by the onboard, flown by the simulator.

Three octagonal zones (8 vertices each, radius 450-500 m) lie around an aircraft at the
origin flying north at 22 m/s; targets every 15 degrees at 2, 3.5 and 5 km (those inside
a zone's inflation left out). For each case:

* the onboard's planner (`onboard.planner.planner_worker.PlannerWorker`, the real model on
  HiGHS, routes by `onboard.planner.route_plan`) predicts the time, as a UAV publishes it;
* the simulator's own autopilot (`fleet.sim.autopilot.SimulatedAutopilot`: 20 ms steps,
  its guidance, its 60 m acceptance radius at each turn) flies the route as the
  autopilot is given it (the turns, then the target), its incursion log
  (`fleet.sim.zone_log`) checking every step against the zones; the flight ends at its
  closest approach to the target (within 10 m, or as the autopilot moves on from it at
  its acceptance radius after a route's turns: then 10-20 m);
* lengths: the flown path, the planned route (around the zones inflated by the turn
  radius and the margin) and the shortest path around the zones themselves (the
  visibility graph on the uninflated zones: the lower bound of any route).

Then the solve time per target with the three zones: the whole plan (model + routes)
and the route search alone, against the plan of the same targets without zones, in the
same run; and the route search in the largest mission allowed (16 zones of 16 vertices).

Run: .venv/bin/python -m bench.bench_zones   (about a minute on 2 shared cores)
"""

from __future__ import annotations

import math
import statistics
import time

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import ZoneMap, zone_map
from fleet.geo.zones import ZONE_MARGIN_M
from fleet.mission.messages import NoFlyZone
from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
from fleet.sim.uav_spec import UavSpec
from onboard.planner.planner_worker import PlannerWorker, PlanRequest, PlanResult
from onboard.planner.route_plan import route_targets

SPEED = 22.0
LIMITS = AircraftLimits()
REF = (35.72, -120.765)
PLANE = MercatorProjection(*REF)
ARRIVAL_M = 10.0
MAX_FLIGHT_MS = 1_500_000
CENTRES = ((1300.0, 700.0, 450.0), (-1100.0, 1500.0, 450.0), (200.0, 2300.0, 500.0))


def octagon(cx: float, cy: float, r: float) -> tuple[tuple[float, float], ...]:
    return tuple(
        (cx + r * math.cos(k * math.pi / 4 + 0.2), cy + r * math.sin(k * math.pi / 4 + 0.2))
        for k in range(8)
    )


ZONES = tuple(octagon(*c) for c in CENTRES)
NO_FLY = tuple(
    NoFlyZone(ring=tuple(PLANE.to_latlon(x, y) for x, y in z), name=f"z{i}")
    for i, z in enumerate(ZONES)
)


def cases() -> list[tuple[float, float]]:
    inflation = LIMITS.turn_radius(SPEED) + ZONE_MARGIN_M
    blocked = ZoneMap(ZONES, inflation)
    found = []
    for bearing in range(0, 360, 15):
        for distance in (2000.0, 3500.0, 5000.0):
            b = math.radians(bearing)
            target = (distance * math.sin(b), distance * math.cos(b))
            if not blocked.containing(target):
                found.append(target)
    return found


def plan(worker: PlannerWorker, targets: list[tuple[float, float]], zones: bool) -> PlanResult:
    request = PlanRequest(
        position=(0.0, 0.0),
        velocity=(0.0, SPEED),
        targets=tuple(targets),
        budget_s=60.0,
        cruise_speed=SPEED,
        zones=ZONES if zones else (),
    )
    worker.run(request)
    while worker.is_running():
        time.sleep(0.002)
    result = worker.result()
    assert result is not None
    return result


def fly(
    turns: tuple[tuple[float, float], ...], target: tuple[float, float]
) -> tuple[float, float, int]:
    """Flown seconds and metres to the closest approach to `target` (within ARRIVAL_M,
    or where the autopilot moves on from it at its acceptance radius), and incursions."""
    points = [(*PLANE.to_latlon(x, y), 600.0) for x, y in (*turns, target)]
    spec = UavSpec(1, REF[0], REF[1], 600.0, 0.0, SPEED, tuple(points))
    autopilot = SimulatedAutopilot(spec, AutopilotSettings(telemetry_hz=1.0, zones=NO_FLY))
    last_index = len(points) - 1
    length, last = 0.0, (0.0, 0.0)
    closest = (math.inf, 0.0, 0.0)  # metres from the target, when, metres flown
    while autopilot.time_ms < MAX_FLIGHT_MS:
        autopilot.step()
        here = (autopilot.state.x, autopilot.state.y)
        length += math.dist(last, here)
        last = here
        gap = math.dist(here, target)
        if gap < closest[0]:
            closest = (gap, autopilot.time_ms / 1000.0, length)
        if gap <= ARRIVAL_M or (last_index and autopilot.tracked == 0 and closest[0] < 100.0):
            break  # over it, or past it and on to the next waypoint
    return closest[1], closest[2], autopilot.zone_log.incursions


def percent(values: list[float]) -> str:
    ordered = sorted(abs(v) for v in values)
    return (
        f"median {100 * statistics.median(ordered):.1f} %, "
        f"worst {100 * ordered[-1]:.1f} %, bias {100 * statistics.mean(values):+.1f} %"
    )


def main() -> None:
    targets = cases()
    with PlannerWorker(LIMITS) as worker:
        plan(worker, targets[:1], zones=False)  # the model built
        started = time.perf_counter()
        free = plan(worker, targets, zones=False)
        free_s = time.perf_counter() - started
        started = time.perf_counter()
        around = plan(worker, targets, zones=True)
        around_s = time.perf_counter() - started
    started = time.perf_counter()
    reps = 20
    for _ in range(reps):
        route_targets((0.0, 0.0), (0.0, SPEED), targets, ZONES, LIMITS)
    routes_s = (time.perf_counter() - started) / reps
    shortest = ZoneMap(ZONES, 0.0)

    errors, detour_errors, flown_vs_shortest, planned_vs_shortest = [], [], [], []
    detour_flown: list[float] = []
    detour_planned: list[float] = []
    incursions, detours, unreachable = 0, 0, 0
    for index, target in enumerate(targets):
        route = around.routes[index]
        if route is None:
            unreachable += 1
            continue
        flown_s, flown_m, count = fly(route.points[:-1], target)
        incursions += count
        error = (around.times[index] - flown_s) / flown_s
        errors.append(error)
        bound = shortest.route((0.0, 0.0), target)
        assert bound is not None
        flown_vs_shortest.append(flown_m / bound.length - 1.0)
        planned_vs_shortest.append(route.length / bound.length - 1.0)
        if route.detours:
            detours += 1
            detour_errors.append(error)
            detour_flown.append(flown_vs_shortest[-1])
            detour_planned.append(planned_vs_shortest[-1])

    radius = LIMITS.turn_radius(SPEED)
    print(f"zones: 3 octagons (8 vertices), inflation {radius:.0f} m turn radius + "
          f"{ZONE_MARGIN_M:g} m margin; {len(targets)} targets at {SPEED:g} m/s")  # fmt: skip
    print(f"flights: {len(errors)} ({detours} around a zone, {unreachable} unreachable); "
          f"incursions: {incursions}")  # fmt: skip
    print(f"predicted vs flown, every flight:     {percent(errors)}")
    print(f"predicted vs flown, detours only:     {percent(detour_errors)}")
    print(f"flown length vs shortest path:       {percent(flown_vs_shortest)} longer")
    print(f"planned route vs shortest path:      {percent(planned_vs_shortest)} longer")
    print(f"flown length vs shortest, detours:   {percent(detour_flown)} longer")
    print(f"planned route vs shortest, detours:  {percent(detour_planned)} longer")
    n = len(targets)
    print(f"solve per target, with zones:        {1000 * around_s / n:.2f} ms "
          f"(without zones {1000 * free_s / n:.2f} ms, ratio {around_s / free_s:.2f}); "
          f"of which routes alone {1000 * routes_s / n:.3f} ms")  # fmt: skip
    print(f"plan CPU per target, with zones:     {1000 * around.cpu_seconds / n:.2f} ms "
          f"(without {1000 * free.cpu_seconds / n:.2f} ms)")  # fmt: skip
    largest()


def largest() -> None:
    """The largest mission allowed: 16 zones of 16 vertices (MAX_MISSION_ZONE_VERTICES),
    on a 4 x 4 grid, routes across it to 50 targets."""
    grid = [
        tuple(
            (3000.0 * (k % 4) + 800.0 * math.cos(i * math.tau / 16),
             3000.0 * (k // 4) + 800.0 * math.sin(i * math.tau / 16))
            for i in range(16)
        )
        for k in range(16)
    ]  # fmt: skip
    targets = [(-2000.0 + 320.0 * i, 11500.0) for i in range(50)]
    started = time.thread_time()
    zone_map(grid, LIMITS, SPEED)
    build_s = time.thread_time() - started
    started = time.thread_time()
    routed = route_targets((1500.0, -2000.0), (0.0, SPEED), targets, grid, LIMITS)
    all_s = time.thread_time() - started
    turns = statistics.median(len(r.points) - 1 for r in routed.routes if r is not None)
    print(f"largest mission (16 zones x 16 vertices): sightlines {1000 * build_s:.0f} ms CPU, "
          f"{1000 * all_s / len(targets):.1f} ms CPU per target with them "
          f"(50 targets across the grid, median {turns:g} turns)")  # fmt: skip


if __name__ == "__main__":
    main()
