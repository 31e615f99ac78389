"""Predicted approach time against the time the simulator's aircraft actually flies.

For each case the onboard model (what a UAV publishes as its result) predicts the time
to a target; the simulator's own aircraft and guidance (`fleet.sim.guidance`, 20 ms
steps, roll-rate and airspeed limits, the guidance law the simulated autopilot flies)
then fly it from the same state, arriving within 10 m. Bearings every 15 degrees, 1-3 km,
at the shipped scenarios' 22 m/s and at 28 m/s, no wind.

Run: .venv/bin/python -m bench.bench_prediction
"""

from __future__ import annotations

import math
import statistics
import time

from fleet.geo.aircraft import AircraftLimits, turn_radius
from fleet.geo.dubins import dubins_time_to_point
from fleet.sim.aircraft import AircraftState
from fleet.sim.guidance import fly_to_point
from onboard.approach_model import ApproachTimeModel

ARRIVAL_RADIUS_M = 10.0


def cases() -> list[tuple[float, float]]:
    return [(bearing, distance) for bearing in range(0, 360, 15) for distance in (1000, 2000, 3000)]


def main() -> None:
    print(
        f"{'speed':>6} {'predictor':<28} {'median err':>10} {'p90 err':>8} {'worst err':>9} "
        f"{'bias':>7}"
    )
    for speed in (22.0, 28.0):
        model = ApproachTimeModel(AircraftLimits(max_airspeed=speed))
        radius = turn_radius(speed, 30.0)
        rows: dict[str, list[float]] = {"onboard model (published)": [], "Dubins alone": []}
        started = time.perf_counter()
        for bearing, distance in cases():
            # Aircraft at the origin heading north; the target at `bearing` from it.
            target = (
                distance * math.sin(math.radians(bearing)),
                distance * math.cos(math.radians(bearing)),
            )
            state = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=speed)
            flown = fly_to_point(state, target, airspeed=speed, acceptance_radius=ARRIVAL_RADIUS_M)
            (predicted,) = model.solve((0.0, 0.0), (0.0, speed), [target])
            assert predicted is not None
            dubins = dubins_time_to_point((0.0, 0.0), (0.0, speed), target, radius)
            rows["onboard model (published)"].append((predicted - flown) / flown)
            rows["Dubins alone"].append((dubins - flown) / flown)
        for name, errors in rows.items():
            magnitudes = sorted(abs(e) for e in errors)
            print(
                f"{speed:>6.0f} {name:<28} {100 * statistics.median(magnitudes):>9.1f}% "
                f"{100 * magnitudes[int(0.9 * len(magnitudes))]:>7.1f}% "
                f"{100 * magnitudes[-1]:>8.1f}% {100 * statistics.mean(errors):>+6.1f}%"
            )
        print(f"       ({len(cases())} cases in {time.perf_counter() - started:.1f} s)")


if __name__ == "__main__":
    main()
