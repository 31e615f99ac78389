"""Predicted against flown: every leg of a queue, on the simulated aircraft, in wind.

Flies seeded random queues (5 targets 1-5 km apart, the aircraft's heading at the start
random) with the simulator's own guidance and aircraft model (`fleet.sim.guidance.
fly_until_arrival`: the very code `fleet sim` steps) in 0, 5, 10 and 15 m/s winds from
random directions, at airspeeds of 20, 22, 25 and 28 m/s, and compares each leg after
the first target with three predictions:

* `turns`: the plan's arrivals (`fleet.consensus.legs.AirLegs.arrivals`: the UAV's own
  airspeed and wind, the turn each queue makes);
* `pairs`: the same UAV's pairwise table, what the search plans with (a mean turn);
* `still air`: one table for every UAV, still air at 22 m/s plus 15 s (the legs before).

The wind here is steady and known exactly: this measures the model, not the estimate
(`fleet up windy` and its e2e test fly the whole system, gusts and estimate included).

    python -m bench.bench_leg_times [--queues N]
"""

from __future__ import annotations

import argparse
import itertools
import math
import random
import statistics
import time

from fleet.consensus.legs import Air, AirLegs, LegGeometry, leg_times
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.wind import Wind
from fleet.mission.messages import Target
from fleet.sim.aircraft import AircraftState
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.guidance import fly_until_arrival

WINDS = (0.0, 5.0, 10.0, 15.0)
AIRSPEEDS = (20.0, 22.0, 25.0, 28.0)
ORIGIN = (35.72, -120.76)


def fly_queue(
    rng: random.Random, wind_speed: float
) -> tuple[list[float], list[float], list[float], list[float]]:
    """One queue flown: (flown, turns, pairs, still air) seconds of each leg."""
    speed = rng.choice(AIRSPEEDS)
    angle = rng.uniform(0.0, math.tau)
    wind = Wind(wind_speed * math.sin(angle), wind_speed * math.cos(angle))
    points = [(0.0, 0.0)]
    for _ in range(5):
        distance, bearing = rng.uniform(1000.0, 5000.0), rng.uniform(0.0, math.tau)
        x, y = points[-1]
        points.append((x + distance * math.sin(bearing), y + distance * math.cos(bearing)))
    projection = MercatorProjection(*ORIGIN)
    targets = [Target(*projection.to_latlon(x, y), 600.0) for x, y in points[1:]]
    air = Air(speed, wind, ORIGIN)
    legs = AirLegs(LegGeometry.of(targets), {1: air})
    state = AircraftState(0.0, 0.0, 600.0, rng.uniform(0.0, math.tau), speed)
    arrivals = []
    clock = 0.0
    for x, y in points[1:]:
        flown, state = fly_until_arrival(
            state,
            (x, y),
            limits=AircraftLimits(),
            wind=SimWind(north=wind.north, east=wind.east),
            airspeed=speed,
        )
        clock += flown
        arrivals.append(clock)
    queue = list(range(len(targets)))
    turns = legs.arrivals(1, arrivals[0], queue)
    pairs = legs.of(1)
    still = leg_times(targets)
    flown_legs = [b - a for a, b in itertools.pairwise(arrivals)]
    return (
        flown_legs,
        [b - a for a, b in itertools.pairwise(turns)],
        [pairs[i][i + 1] for i in range(len(queue) - 1)],
        [still[i][i + 1] for i in range(len(queue) - 1)],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queues", type=int, default=20, help="queues per wind (5 targets)")
    parser.add_argument("--seed", type=int, default=35)
    args = parser.parse_args()
    started = time.process_time()
    print(f"{args.queues} queues of 5 targets per wind, airspeeds {AIRSPEEDS} m/s")
    print("| wind (m/s) | legs | model | median error | 95th percentile | worst |")
    print("|---|---|---|---|---|---|")
    for wind_speed in WINDS:
        rng = random.Random(f"{args.seed}:{wind_speed}")
        errors: dict[str, list[float]] = {"turns": [], "pairs": [], "still air": []}
        for _ in range(args.queues):
            flown, *models = fly_queue(rng, wind_speed)
            for name, predicted in zip(errors, models, strict=True):
                errors[name] += [abs(p / f - 1.0) for p, f in zip(predicted, flown, strict=True)]
        for name, values in errors.items():
            values.sort()
            p95 = values[min(len(values) - 1, int(0.95 * len(values)))]
            median = 100 * statistics.median(values)
            print(
                f"| {wind_speed:g} | {len(values)} | {name} | {median:.1f} %"
                f" | {100 * p95:.1f} % | {100 * values[-1]:.1f} % |"
            )
    print(f"\n{time.process_time() - started:.0f} CPU s")


if __name__ == "__main__":
    main()
