"""When the air watch asks for a re-plan in the air of now: on the weather's drift,
never on its gusts alone (onboard.air_watch).

Replays a scenario's weather (`fleet.sim.weather`: drift, gusts, the reported
estimate's lag and bias) for each of its UAVs, step by step on the aircraft's clock,
through the onboard's own averages (`WindEstimate`, the watch's) and `AirWatch`, with
the plan's air the smoothed wind at `--plan-at` seconds; after each ask the reference
becomes the air of that moment (the team re-planned). Just-before-a-leg windows
(`BEFORE_LEG_S` long) open every `--leg-every` seconds, as a queue's legs would. Prints,
per UAV, the asks with the scenario's drift (in flight / before a leg), and the asks
with the drift set to 0 (gusts alone) over `--seeds` weather seeds. No processes, no
bus: the same code the onboard runs, fed the simulator's weather.

    python -m bench.bench_air_watch [--scenario windy] [--seconds 700] [--seeds 6]
"""

from __future__ import annotations

import argparse
import dataclasses

from fleet.geo.wind import Wind
from fleet.sim.scenario import shipped_scenario
from fleet.sim.weather import Weather, WeatherSpec
from onboard.air_watch import BEFORE_LEG_S, AirWatch, FlyingAir
from onboard.planner.wind_estimate import WindEstimate

STEP_S = 0.25


@dataclasses.dataclass
class Asks:
    in_flight: list[float] = dataclasses.field(default_factory=list)
    before_leg: list[float] = dataclasses.field(default_factory=list)

    def __len__(self) -> int:
        return len(self.in_flight) + len(self.before_leg)


def replay(spec: WeatherSpec, uav: int, seconds: float, plan_at: float, leg_every: float) -> Asks:
    """The asks one UAV's watch makes in `seconds` of `spec`'s weather."""
    weather, estimate, watch, asks = Weather(spec, uav), WindEstimate(), AirWatch(), Asks()
    t = 0.0
    while t < seconds:
        weather.advance(STEP_S)
        t += STEP_S
        reported = weather.estimate
        estimate.update(Wind(reported.east, reported.north), t)
        now = FlyingAir(None, estimate.value)
        if t < plan_at:
            continue
        if watch.reference is None:
            watch.follow(now, t)
            continue
        before_leg = leg_every > 0 and (t - plan_at) % leg_every >= leg_every - BEFORE_LEG_S
        if watch.check(now, t, before_leg):
            (asks.before_leg if before_leg else asks.in_flight).append(t)
            watch.follow(now, t)  # the team re-planned in the air of now
    return asks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="windy")
    parser.add_argument("--seconds", type=float, default=700.0)
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--plan-at", type=float, default=5.0, metavar="S")
    parser.add_argument("--leg-every", type=float, default=220.0, metavar="S")
    args = parser.parse_args()
    scenario = shipped_scenario(args.scenario)
    spec = scenario.weather
    uavs = [uav.piccolo_id for uav in scenario.uavs]

    def times(found: list[float]) -> str:
        return ", ".join(f"{t:.0f}" for t in found) or "-"

    print(f"{args.scenario}: {args.seconds:.0f} s, plan at {args.plan_at:.0f} s, "
          f"a leg every {args.leg_every:.0f} s")  # fmt: skip
    print(f"{'UAV':>4}  {'asks in flight (s)':<24} {'asks before a leg (s)':<24}")
    for uav in uavs:
        asks = replay(spec, uav, args.seconds, args.plan_at, args.leg_every)
        print(f"{uav:>4}  {times(asks.in_flight):<24} {times(asks.before_leg):<24}")
    calm = dataclasses.replace(spec, drift_speed=0.0, drift_direction_deg=0.0)
    flight = leg = 0
    for seed in range(spec.seed, spec.seed + args.seeds):
        for uav in uavs:
            asks = replay(dataclasses.replace(calm, seed=seed), uav, args.seconds,
                          args.plan_at, args.leg_every)  # fmt: skip
            flight += len(asks.in_flight)
            leg += len(asks.before_leg)
    runs = args.seeds * len(uavs)
    windows = runs * int((args.seconds - args.plan_at) // args.leg_every)
    print(f"gusts alone ({args.seeds} seeds x {len(uavs)} UAVs, {runs * args.seconds:.0f} s): "
          f"{flight} asks in flight, {leg} before a leg (in {windows} leg starts)")  # fmt: skip


if __name__ == "__main__":
    main()
