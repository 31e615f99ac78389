"""The decision step's cost with each UAV's own legs (in its air) against one table.

Every UAV runs `plan_queues` once per decision. With each UAV's legs timed in its own
air (`fleet.consensus.legs.AirLegs`: its airspeed and smoothed wind, a row computed when
the search first asks for it, the queue's turns timed in its arrivals), against the one
still-air table every UAV shared before (`leg_times`). A seeded instance of N UAVs x M
targets (uniform in a square of 2 km per sqrt(target)); airspeeds 20-28 m/s, a 10 m/s
wind each UAV estimates 0.5 m/s apart; approach times the straight line at the UAV's
airspeed. Per objective, the median of `--calls` calls, each on fresh tables (so the
rows the search asks for are computed in the call, as in a decision); the geometry
(`LegGeometry.of`, once per mission, while the approach times are planned) on its own.

    python -m bench.bench_air_legs [--uavs 50] [--targets 200] [--calls 5]
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import time

from fleet.consensus.legs import Air, AirLegs, LegGeometry, leg_times
from fleet.consensus.objectives import plan_queues
from fleet.geo.mercator import MercatorProjection
from fleet.geo.wind import Wind
from fleet.mission.messages import Target
from fleet.mission.objective import Objective

ORIGIN = (35.72, -120.76)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--uavs", type=int, default=50)
    parser.add_argument("--targets", type=int, default=200)
    parser.add_argument("--calls", type=int, default=5)
    parser.add_argument("--seed", type=int, default=35)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    side = 2000.0 * math.sqrt(args.targets)
    projection = MercatorProjection(*ORIGIN)
    points = [(rng.uniform(0, side), rng.uniform(0, side)) for _ in range(args.targets)]
    targets = [Target(*projection.to_latlon(x, y), 600.0) for x, y in points]
    air: dict[int, Air] = {}
    times: dict[int, list[float | None]] = {}
    for uav in range(1, args.uavs + 1):
        x, y = rng.uniform(0, side), rng.uniform(0, side)
        speed = rng.uniform(20.0, 28.0)
        wind = Wind(10.0 + rng.gauss(0.0, 0.5), rng.gauss(0.0, 0.5))
        air[uav] = Air(speed, wind, projection.to_latlon(x, y))
        times[uav] = [math.hypot(px - x, py - y) / speed for px, py in points]

    started = time.process_time()
    geometry = LegGeometry.of(targets)
    geometry_s = time.process_time() - started
    started = time.process_time()
    shared = leg_times(targets)
    table_s = time.process_time() - started
    print(f"{args.uavs} UAVs x {args.targets} targets, median of {args.calls} calls (CPU)")
    print(
        f"once per mission: LegGeometry.of {1000 * geometry_s:.0f} ms, "
        f"leg_times {1000 * table_s:.0f} ms"
    )
    print("| objective | one still-air table | each UAV's own air | ratio |")
    print("|---|---|---|---|")
    for objective in (Objective.GREEDY, Objective.MIN_SUM, Objective.MIN_MAX):
        before, after = [], []
        for _ in range(args.calls):
            started = time.process_time()
            plan_queues(times, shared, objective)
            before.append(time.process_time() - started)
            started = time.process_time()
            plan_queues(times, AirLegs(geometry, air, shared), objective)
            after.append(time.process_time() - started)
        b, a = statistics.median(before), statistics.median(after)
        print(f"| {objective.value} | {1000 * b:.0f} ms | {1000 * a:.0f} ms | {a / b:.2f} |")


if __name__ == "__main__":
    main()
