"""Predicted approach time against the time the simulator's aircraft actually flies.

For each case the onboard model (what a UAV publishes as its result) predicts the time
to a target; the simulator's own aircraft and guidance (`fleet.sim.guidance`, 20 ms
steps, roll-rate and airspeed limits, the guidance law the simulated autopilot flies)
then fly it from the same state, arriving within 10 m.

1. Still air: bearings every 15 degrees, 1-3 km, at the shipped scenarios' 22 m/s and
   at 28 m/s.
2. Wind: 22 m/s airspeed, winds of 0, 5, 10 and 15 m/s blowing east, the
   aircraft heading north, targets at bearings every 15 degrees and 1, 3 and 5 km (72
   cases a wind). Predictors: the published time (the model in the wind, or its
   fallback where the model gives none, as `onboard.planner.planner_worker` does), the
   closed-form Dubins time in the wind (the fallback alone), and the still-air Dubins
   time at the airspeed (what a plan that ignores the wind says). A last row flies the
   same cases in the shipped `windy` scenario's weather (10 m/s that drifts and gusts),
   planned in its biased reported estimate.
3. Assignment: random teams and targets in a 10 m/s wind; the greedy assignment on
   still-air times and on wind times, each flown by the simulator: total and last
   arrival, same instances, same run.
4. Speed: the model's solve time for 50 targets in calm air and in a 10 m/s wind,
   interleaved in the same run (the ratio is the figure; the machine is shared).
5. JSBSim (`--part jsbsim`, needs `pip install '.[jsbsim]'`): the wind cases of 2 flown
   on JSBSim's J3Cub behind the same guidance (`fleet sim --dynamics jsbsim`): the
   published time and the kinematic simulator's flight, each against the JSBSim flight;
   and JSBSim's cost, simulated seconds per CPU second of one aircraft.

Run: .venv/bin/python -m bench.bench_prediction [--part still|wind|assignment|speed|jsbsim]
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import time

from fleet.consensus.assignment import greedy_assign
from fleet.geo.aircraft import AircraftLimits, turn_radius
from fleet.geo.dubins import dubins_time_in_wind, dubins_time_to_point
from fleet.geo.wind import Wind
from fleet.sim.aircraft import AircraftState
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.aircraft import step as aircraft_step
from fleet.sim.guidance import STEP_S, GuidanceSettings, command_toward, fly_to_point
from fleet.sim.scenario import shipped_scenario
from fleet.sim.weather import Weather
from onboard.planner.approach_model import ApproachTimeModel
from onboard.planner.planner_worker import MODEL_STATED_ERROR, fallback_time

ARRIVAL_RADIUS_M = 10.0
AIRSPEED = 22.0
WINDS = (0.0, 5.0, 10.0, 15.0)
#: Where every wind case starts: the origin, 600 m up, heading north at AIRSPEED.
START = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=AIRSPEED)


def cases() -> list[tuple[float, float]]:
    return [(bearing, distance) for bearing in range(0, 360, 15) for distance in (1000, 2000, 3000)]


def wind_cases() -> list[tuple[float, float]]:
    return [(bearing, distance) for bearing in range(0, 360, 15) for distance in (1000, 3000, 5000)]


def polar(bearing_deg: float, distance: float) -> tuple[float, float]:
    """(east, north) of a point `distance` m away at `bearing_deg` clockwise from north."""
    b = math.radians(bearing_deg)
    return distance * math.sin(b), distance * math.cos(b)


def row(label: str, errors: list[float]) -> str:
    magnitudes = sorted(abs(e) for e in errors)
    return (
        f"{label} {100 * statistics.median(magnitudes):>9.1f}% "
        f"{100 * magnitudes[int(0.9 * len(magnitudes))]:>7.1f}% "
        f"{100 * magnitudes[-1]:>8.1f}% {100 * statistics.mean(errors):>+6.1f}%"
    )


def print_wind_rows(speed: float, rows: dict[str, list[float]]) -> None:
    """One row a predictor for the wind `speed`: its errors against the flights."""
    for name, errors in rows.items():
        print(row(f"{speed:>5.0f} {name:<32}", errors))


def fly_kinematic(target: tuple[float, float], wind: SimWind) -> float:
    """Arrival s of the kinematic simulator flying from START to `target` in a steady `wind`."""
    return fly_to_point(
        START, target, wind=wind, acceptance_radius=ARRIVAL_RADIUS_M, max_time=3600.0
    )


def still_air() -> None:
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
            target = polar(bearing, distance)
            state = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=speed)
            flown = fly_to_point(state, target, airspeed=speed, acceptance_radius=ARRIVAL_RADIUS_M)
            (predicted,) = model.solve((0.0, 0.0), (0.0, speed), [target])
            assert predicted is not None
            dubins = dubins_time_to_point((0.0, 0.0), (0.0, speed), target, radius)
            rows["onboard model (published)"].append((predicted - flown) / flown)
            rows["Dubins alone"].append((dubins - flown) / flown)
        for name, errors in rows.items():
            print(row(f"{speed:>6.0f} {name:<28}", errors))
        print(f"       ({len(cases())} cases in {time.perf_counter() - started:.1f} s)")


def published(
    model: ApproachTimeModel,
    limits: AircraftLimits,
    velocity: tuple[float, float],
    targets: list[tuple[float, float]],
    wind: Wind,
) -> tuple[list[float], int, float]:
    """The planner's answer: the model's times, the fallback's where it has none; and how
    far below the Dubins time (a share) the LP came at most (the sanity check's figure)."""
    solutions = model.solve_detailed((0.0, 0.0), velocity, targets, wind=wind)
    times = []
    fallbacks = 0
    below = 0.0
    for sol, target in zip(solutions, targets, strict=True):
        if sol.lp_time is not None and sol.dubins_time:
            below = max(below, 1.0 - sol.lp_time / sol.dubins_time)
        if sol.time is None:
            fallbacks += 1
            times.append(fallback_time(limits, (0.0, 0.0), velocity, target, wind))
        else:
            times.append(sol.time)
    return times, fallbacks, below


def in_wind() -> None:
    limits = AircraftLimits(max_airspeed=AIRSPEED)
    model = ApproachTimeModel(limits)
    radius = turn_radius(AIRSPEED, limits.bank_limit_deg)
    print(
        f"{'wind':>5} {'predictor':<32} {'median err':>10} {'p90 err':>8} {'worst err':>9} "
        f"{'bias':>7}"
    )
    for speed in WINDS:
        wind = Wind(east=speed, north=0.0)
        # Heading north through the air; over the ground it drifts east.
        velocity = (speed, AIRSPEED)
        rows: dict[str, list[float]] = {
            "model in the wind (published)": [],
            "Dubins in the wind (fallback)": [],
            "still-air Dubins": [],
        }
        worst = (0.0, 0.0, 0.0)
        started = time.perf_counter()
        fallbacks = 0
        below = 0.0
        solve_s = 0.0
        for bearing, distance in wind_cases():
            target = polar(bearing, distance)
            flown = fly_kinematic(target, SimWind(north=0.0, east=speed))
            solving = time.perf_counter()
            (predicted,), fell, under = published(model, limits, velocity, [target], wind)
            solve_s += time.perf_counter() - solving
            fallbacks += fell
            below = max(below, under)
            closed = dubins_time_in_wind((0.0, 0.0), (0.0, AIRSPEED), target, radius, wind)
            still = dubins_time_to_point((0.0, 0.0), (0.0, AIRSPEED), target, radius)
            error = (predicted - flown) / flown
            rows["model in the wind (published)"].append(error)
            rows["Dubins in the wind (fallback)"].append((closed - flown) / flown)
            rows["still-air Dubins"].append((still - flown) / flown)
            if abs(error) > abs(worst[0]):
                worst = (error, bearing, distance)
        print_wind_rows(speed, rows)
        print(
            f"      ({len(wind_cases())} cases in {time.perf_counter() - started:.1f} s; "
            f"model {1000 * solve_s / len(wind_cases()):.1f} ms a target, {fallbacks} beyond "
            f"its 600 s horizon by the fallback; worst {100 * worst[0]:+.1f} % at bearing "
            f"{worst[1]:.0f}, {worst[2] / 1000:.0f} km; the LP at most {100 * below:.1f} % "
            f"below the Dubins time, the sanity check flags {100 * MODEL_STATED_ERROR:.1f} %)"
        )


#: The gusty row's weather: the shipped windy scenario's (10 m/s blowing east).
GUSTY = shipped_scenario("windy").weather


def fly_in_weather(target: tuple[float, float], weather: Weather) -> float:
    """`fly_to_point` in changing weather: the simulated autopilot's own loop."""
    limits = AircraftLimits()
    settings = GuidanceSettings(acceptance_radius=ARRIVAL_RADIUS_M)
    state = START
    for count in range(round(3600.0 / STEP_S)):
        if math.hypot(target[0] - state.x, target[1] - state.y) <= ARRIVAL_RADIUS_M:
            return count * STEP_S
        wind = weather.wind
        command = command_toward(state, target, 600.0, AIRSPEED, limits, wind, settings)
        state = aircraft_step(state, command, limits, wind, STEP_S)
        weather.advance(STEP_S)
    raise RuntimeError(f"{target} not reached in an hour")


def in_weather() -> None:
    """10 m/s that drifts and gusts, planned with the reported (biased) estimate."""
    limits = AircraftLimits(max_airspeed=AIRSPEED)
    model = ApproachTimeModel(limits)
    errors = []
    for index, (bearing, distance) in enumerate(wind_cases()):
        target = polar(bearing, distance)
        weather = Weather(GUSTY, piccolo_id=index)  # each case its own gusts and bias
        reported = weather.estimate
        wind = Wind(east=reported.east, north=reported.north)
        true = weather.wind
        velocity = (true.east, AIRSPEED + true.north)
        (predicted,), _, _ = published(model, limits, velocity, [target], wind)
        flown = fly_in_weather(target, weather)
        errors.append((predicted - flown) / flown)
    print(row(f"{'10+':>5} {'model, gusts, estimate off':<32}", errors))
    print(
        f"      (gusts {GUSTY.gust:g} m/s, drift {GUSTY.drift_speed:g} m/s and "
        f"{GUSTY.drift_direction_deg:g} deg, the plan in the reported estimate: bias of "
        f"standard deviation {GUSTY.estimate_error:g} m/s a component)"
    )


def assignment(instances: int, seed: int) -> None:
    """Greedy on still-air times vs on wind times, both flown in the wind."""
    limits = AircraftLimits(max_airspeed=AIRSPEED)
    model = ApproachTimeModel(limits)
    radius = turn_radius(AIRSPEED, limits.bank_limit_deg)
    rng = random.Random(seed)
    print(f"{'team':>6} {'plan on':<16} {'total flown s':>13} {'last arrival s':>14}")
    for uavs, targets in ((3, 5), (5, 8)):
        totals: dict[str, list[float]] = {"still-air times": [], "wind times": []}
        lasts: dict[str, list[float]] = {"still-air times": [], "wind times": []}
        changed = 0
        for _ in range(instances):
            bearing = rng.uniform(0.0, 360.0)
            wind = Wind(*polar(bearing, 10.0))
            sim_wind = SimWind(north=wind.north, east=wind.east)
            starts = [(rng.uniform(-3000, 3000), rng.uniform(-3000, 3000)) for _ in range(uavs)]
            headings = [rng.uniform(0.0, math.tau) for _ in range(uavs)]
            points = [(rng.uniform(-5000, 5000), rng.uniform(-5000, 5000)) for _ in range(targets)]
            still: dict[int, list[float | None]] = {}
            windy: dict[int, list[float | None]] = {}
            for uav, ((x, y), h) in enumerate(zip(starts, headings, strict=True)):
                air = (AIRSPEED * math.sin(h), AIRSPEED * math.cos(h))
                local = [(px - x, py - y) for px, py in points]
                still[uav] = [dubins_time_to_point((0.0, 0.0), air, p, radius) for p in local]
                ground = (air[0] + wind.east, air[1] + wind.north)
                windy[uav] = list(published(model, limits, ground, local, wind)[0])
            plans = {
                "still-air times": greedy_assign(still, targets).pairs,
                "wind times": greedy_assign(windy, targets).pairs,
            }
            changed += plans["still-air times"] != plans["wind times"]
            for name, pairs in plans.items():
                flown = []
                for uav, target in pairs.items():
                    x, y = starts[uav]
                    state = AircraftState(
                        x=x, y=y, alt=600.0, heading=headings[uav] % math.tau, airspeed=AIRSPEED
                    )
                    flown.append(
                        fly_to_point(
                            state,
                            points[target],
                            wind=sim_wind,
                            acceptance_radius=ARRIVAL_RADIUS_M,
                            max_time=3600.0,
                        )
                    )
                totals[name].append(sum(flown))
                lasts[name].append(max(flown))
        for name in totals:
            print(
                f"{uavs}x{targets:<4} {name:<16} {statistics.mean(totals[name]):>13.1f} "
                f"{statistics.mean(lasts[name]):>14.1f}"
            )
        total_gain = 1 - statistics.mean(totals["wind times"]) / statistics.mean(
            totals["still-air times"]
        )
        last_gain = 1 - statistics.mean(lasts["wind times"]) / statistics.mean(
            lasts["still-air times"]
        )
        print(
            f"       wind times: total {100 * total_gain:+.1f} %, last arrival "
            f"{100 * last_gain:+.1f} % shorter; the assignment differs in {changed} of "
            f"{instances} instances"
        )


def fly_on_jsbsim(target: tuple[float, float], wind: SimWind) -> tuple[float, float]:
    """(arrival s, CPU s) of the guidance flying JSBSim's J3Cub from the origin, heading
    north at AIRSPEED, to within ARRIVAL_RADIUS_M of `target` in a steady `wind`."""
    from fleet.geo.mercator import MercatorProjection
    from fleet.sim.jsbsim_model import JSBSimModel

    limits = AircraftLimits()
    settings = GuidanceSettings(acceptance_radius=ARRIVAL_RADIUS_M)
    started = time.process_time()
    model = JSBSimModel(START, limits, MercatorProjection(35.72, -120.765), wind)
    for count in range(round(3600.0 / STEP_S)):
        state = model.state
        if math.hypot(target[0] - state.x, target[1] - state.y) <= ARRIVAL_RADIUS_M:
            return count * STEP_S, time.process_time() - started
        command = command_toward(state, target, 600.0, AIRSPEED, limits, wind, settings)
        model.step(command, wind, STEP_S)
    raise RuntimeError(f"{target} not reached on JSBSim in an hour")


def on_jsbsim() -> None:
    """The wind cases flown on JSBSim: the prediction and the kinematic simulator
    against it."""
    limits = AircraftLimits(max_airspeed=AIRSPEED)
    model = ApproachTimeModel(limits)
    print(
        f"{'wind':>5} {'against the JSBSim flight':<32} {'median err':>10} {'p90 err':>8} "
        f"{'worst err':>9} {'bias':>7}"
    )
    simulated = cpu = 0.0
    for speed in WINDS:
        wind = Wind(east=speed, north=0.0)
        sim_wind = SimWind(north=0.0, east=speed)
        velocity = (speed, AIRSPEED)
        rows: dict[str, list[float]] = {
            "model in the wind (published)": [],
            "kinematic simulator": [],
        }
        for bearing, distance in wind_cases():
            target = polar(bearing, distance)
            flown, seconds = fly_on_jsbsim(target, sim_wind)
            simulated += flown
            cpu += seconds
            kinematic = fly_kinematic(target, sim_wind)
            (predicted,), _, _ = published(model, limits, velocity, [target], wind)
            rows["model in the wind (published)"].append((predicted - flown) / flown)
            rows["kinematic simulator"].append((kinematic - flown) / flown)
        print_wind_rows(speed, rows)
    print(
        f"      ({len(WINDS) * len(wind_cases())} JSBSim flights, {simulated:.0f} simulated s "
        f"in {cpu:.1f} CPU s: {simulated / cpu:.0f} simulated s per CPU s of one aircraft, "
        f"its guidance and inner loops included)"
    )
    autopilot_cost()
    airspeed_spread()


def airspeed_spread(seconds: int = 300) -> None:
    """The true airspeed the onboard reads from the air data (what it plans at), over
    `seconds` of the windy scenario's first UAV (gusts 0.8 m/s), on either model."""
    from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
    from fleet.sim.flight_model import Dynamics

    scenario = shipped_scenario("windy")
    for dynamics in Dynamics:
        settings = AutopilotSettings(wind=scenario.wind, limits=scenario.limits, dynamics=dynamics)
        autopilot = SimulatedAutopilot(scenario.uavs[0], settings, scenario.weather)
        autopilot.advance_to(10_000)  # past the start
        readings: list[float] = []
        for _ in range(seconds * 10):  # 10 Hz
            autopilot.advance_to(autopilot.time_ms + 100)
            sensor = autopilot.telemetry().sensor
            reading = None if sensor is None else sensor.true_airspeed()
            assert reading is not None
            readings.append(reading)
        print(
            f"air data true airspeed, {dynamics.value:<9} in the windy scenario's gusts: "
            f"mean {statistics.mean(readings):.2f} m/s, standard deviation "
            f"{statistics.pstdev(readings):.2f}, {min(readings):.1f} to {max(readings):.1f}"
        )


def autopilot_cost(seconds: int = 120, repeats: int = 3) -> None:
    """CPU per simulated second of a whole simulated autopilot (the windy scenario's
    three, gusts and 20 Hz telemetry to an open program port), kinematic vs JSBSim,
    interleaved in the same run: the ratio is the figure."""
    from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
    from fleet.sim.flight_model import Dynamics

    scenario = shipped_scenario("windy")
    costs: dict[Dynamics, list[float]] = {dynamics: [] for dynamics in Dynamics}
    for _ in range(repeats):
        for dynamics in Dynamics:
            settings = AutopilotSettings(
                wind=scenario.wind, limits=scenario.limits, dynamics=dynamics
            )
            autopilots = [
                SimulatedAutopilot(uav, settings, scenario.weather) for uav in scenario.uavs
            ]
            for autopilot in autopilots:
                autopilot.open_program()
            started = time.process_time()
            for autopilot in autopilots:
                autopilot.advance_to(seconds * 1000)
            costs[dynamics].append((time.process_time() - started) / (len(autopilots) * seconds))
    kinematic = min(costs[Dynamics.KINEMATIC])
    for dynamics, values in costs.items():
        best = min(values)
        print(
            f"simulated autopilot, {dynamics.value:<9}: {1000 * best:.2f} ms CPU per simulated "
            f"second ({1 / best:.0f} simulated s per CPU s), x{best / kinematic:.1f} the kinematic"
        )


def speed(repeats: int = 7) -> None:
    """Solve time of 50 targets, calm vs a 10 m/s wind, interleaved."""
    limits = AircraftLimits(max_airspeed=AIRSPEED)
    model = ApproachTimeModel(limits)
    rng = random.Random(50)
    targets = [polar(rng.uniform(0.0, 360.0), rng.uniform(500.0, 5000.0)) for _ in range(50)]
    winds = {"calm": Wind(), "10 m/s": Wind(east=10.0)}
    seconds: dict[str, list[float]] = {name: [] for name in winds}
    lps: dict[str, int] = {}
    for _ in range(repeats):
        for name, wind in winds.items():
            velocity = (wind.east, AIRSPEED)
            started = time.perf_counter()
            solutions = model.solve_detailed((0.0, 0.0), velocity, targets, wind=wind)
            seconds[name].append(time.perf_counter() - started)
            lps[name] = sum(sol.lps for sol in solutions)
    radius = turn_radius(AIRSPEED, limits.bank_limit_deg)
    for name, wind in winds.items():
        started = time.perf_counter()
        for target in targets * 20:
            dubins_time_in_wind((0.0, 0.0), (0.0, AIRSPEED), target, radius, wind)
        closed = (time.perf_counter() - started) / (20 * len(targets))
        print(f"closed-form Dubins time, {name:<7}: {1e6 * closed:.0f} us a target")
    calm = statistics.median(seconds["calm"])
    for name in winds:
        median = statistics.median(seconds[name])
        print(
            f"50 targets, {name:<7}: median {median:.3f} s ({1000 * median / 50:.1f} ms a "
            f"target), {lps[name] / 50:.2f} LPs a target, x{median / calm:.2f} the calm time"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--part", choices=("still", "wind", "assignment", "speed", "jsbsim"), default=None
    )
    parser.add_argument("--instances", type=int, default=40)
    parser.add_argument("--seed", type=int, default=24)
    args = parser.parse_args()
    if args.part in (None, "still"):
        still_air()
    if args.part in (None, "wind"):
        in_wind()
        in_weather()
    if args.part in (None, "assignment"):
        assignment(args.instances, args.seed)
    if args.part in (None, "speed"):
        speed()
    if args.part == "jsbsim":
        on_jsbsim()


if __name__ == "__main__":
    main()
