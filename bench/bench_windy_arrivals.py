"""Predicted against flown, the whole system: the shipped `windy` scenario end to end.

`fleet up windy` (router, simulator, three onboards) in its 10 m/s westerly that
drifts and gusts, with the reported estimate lagging and biased; the targets of
`windy_targets.bin` sent with `ground-cli send-targets` (one upwind, one downwind, one
across the wind, 3.2 km from each UAV), then `mission --until-reached`; `fleet report`
on the run's recording gives each UAV's published ETA and the time it flew (on the
aircraft's clock, from its commitment to its arrival). Error = (predicted - flown) /
flown. With `--dynamics jsbsim` the aircraft fly on JSBSim's J3Cub (docs/simulator.md).

    python -m bench.bench_windy_arrivals [--dynamics kinematic jsbsim] [--runs N]
                                         [--after S] [--speedup K] [--nine]

`--after S` waits S wall seconds after the fleet is up before sending the targets (the
UAVs fly their racetracks meanwhile, turning in the wind). Each run takes about
300 / K wall seconds.

`--nine` sends nine targets instead (`tests.support.targets.WINDY_NINE`, three about
each UAV) with `--objective min-sum`, so each UAV flies a queue, and prints every leg of
every queue: the time of the plan in force when the leg began (`plan`: the first plan,
or a re-plan in the air of its time, `epoch` > 0: docs/queues.md), the UAV's time said
as it began the leg (`begun`: in the air of that moment) and the time flown, with each
one's error and their median and worst; and, for each leg after a queue's first, `true
wind`: the plan's leg model (its airspeed, the turn its queue makes) in the simulator's
true mean wind at the middle of the leg as flown (`fleet.sim.weather`'s drift, without
gusts or the estimate's lag and bias), which tells the model's error from the wind's
change. About 750 / K wall seconds a run.

`--wind W ...` flies the scenario with its mean wind at each speed W (m/s, from the
west; drift, gusts and the estimate's lag and bias as shipped) and `--airspeeds A A A`
gives UAVs 201, 202, 203 those airspeeds (a scenario written beside the run's logs,
its minimum airspeed lowered below the slowest where a 15 m/s wind with its gusts
needs it); with `--nine` a summary table closes the output, a row per dynamics and
wind. `--estimate` prints, for each UAV, the wind and airspeed its result carried
(what its plan's legs are timed in) against the simulator's at that moment: the true
mean wind (the drift alone), the true wind (gusts too) and the estimate the autopilot
reported (lagging and biased by design), replayed step by step from the scenario.

    python -m bench.bench_windy_arrivals --nine --wind 0 5 10 15 --airspeeds 20 24 28 \
        --dynamics kinematic jsbsim --estimate
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleet.consensus.legs import Air, AirLegs, LegGeometry
from fleet.geo.wind import Wind
from fleet.launch.endpoints import free_port
from fleet.mission.messages import MissionTargets
from fleet.recording.mission_log import Timeline, build_timeline
from fleet.recording.reader import read_recording
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.autopilot import STEP_MS
from fleet.sim.scenario import Scenario, load_scenario, shipped_scenario, shipped_scenario_path
from fleet.sim.weather import Weather
from tests.support.processes import start_fleet_up, wait_fleet_up
from tests.support.targets import windy_nine_csv

#: Where each run's recording is copied (`--keep DIR`); None: not kept.
KEEP: list[str | None] = [None]

#: Where each UAV's target lies from it, in the scenario's wind (docs/simulator.md).
WHERE = {"201": "upwind", "202": "downwind", "203": "across"}


@dataclass(frozen=True, slots=True)
class Air3:
    """The run's air: the mean wind's speed (m/s, from the west; None: the scenario's)
    and the three UAVs' airspeeds (None: the scenario's)."""

    wind: float | None = None
    airspeeds: tuple[float, float, float] | None = None

    @property
    def label(self) -> str:
        wind = "10" if self.wind is None else f"{self.wind:g}"
        speeds = "22" if self.airspeeds is None else "/".join(f"{a:g}" for a in self.airspeeds)
        return f"{wind} m/s, {speeds}"


def _run(*argv: str, timeout: float) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *argv], capture_output=True, text=True, timeout=timeout, check=False
    )


def scenario_file(air: Air3, folder: Path) -> Path:
    """The windy scenario with `air`'s wind and airspeeds, written into `folder` (the
    shipped file itself where `air` changes nothing)."""
    shipped = shipped_scenario_path("windy")
    if air.wind is None and air.airspeeds is None:
        return shipped
    text = shipped.read_text()
    text = text.replace('targets = "windy_targets.bin"',
                        f'targets = "{shipped.with_name("windy_targets.bin")}"')  # fmt: skip
    if air.wind is not None:
        text, count = re.subn(r"(?m)^east = 10\.0$", f"east = {air.wind:.1f}", text)
        assert count == 1, "windy.toml's wind is no longer `east = 10.0`"
    if air.airspeeds is not None:
        speeds = iter(air.airspeeds)
        text, count = re.subn(
            r"(?m)^airspeed = 22\.0$", lambda _: f"airspeed = {next(speeds):.1f}", text
        )
        assert count == 3, "windy.toml no longer has three UAVs at `airspeed = 22.0`"
    weather = shipped_scenario("windy").weather
    if air.wind is not None:
        weather = dataclasses.replace(weather, mean=SimWind(east=air.wind))
    slowest = min(air.airspeeds or (22.0,))
    if weather.strongest >= 15.0:  # the default minimum airspeed (fleet.geo.aircraft)
        least = math.floor(weather.strongest) + 1.0
        if least > slowest:
            raise SystemExit(f"a {weather.strongest:.1f} m/s wind is too strong for {slowest} m/s")
        text = text.replace("[[uav]]", f"[aircraft]\nmin_airspeed = {least:.1f}\n\n[[uav]]", 1)
    path = folder / "windy_variant.toml"
    path.write_text(text)
    load_scenario(path)  # refused here, not by `fleet up`, if it is not valid
    return path


def fly(dynamics: str, after_s: float, speedup: float) -> dict[str, tuple[float, float]]:
    """One run: each UAV's (predicted s, flown s)."""
    found = _mission(dynamics, after_s, speedup, nine=False, air=Air3(), estimate=False)
    (mission,) = found["missions"]
    return {
        uav: (float(mission["predicted_s"][uav]), float(mission["flown_s"][uav])) for uav in WHERE
    }


def fly_nine(
    dynamics: str, after_s: float, speedup: float, air: Air3, estimate: bool
) -> tuple[dict[str, list[dict[str, Any]]], list[str]]:
    """One run of nine targets: each UAV's legs (`fleet report --json`'s), each with
    `true_s`, the leg timed in the true mean wind of its time (None for a first leg);
    and the `--estimate` lines."""
    found = _mission(dynamics, after_s, speedup, nine=True, air=air, estimate=estimate)
    (mission,) = found["missions"]
    legs: dict[str, list[dict[str, Any]]] = {uav: mission["legs"][uav] for uav in WHERE}
    for uav, rows in legs.items():
        for row, true_s in zip(rows, found["true_s"][uav], strict=True):
            row["true_s"] = true_s
    return legs, found["estimate"]


def true_wind_legs(timeline: Timeline, scenario: Scenario) -> dict[str, list[float | None]]:
    """Each UAV's legs (`MissionLog.leg_plans`), timed by the model of the plan in force
    when each began (its airspeed, the turn its queue makes) in the scenario's true mean
    wind at the middle of the leg (aircraft clock = the simulator's weather clock); None
    for a first leg."""
    (log,) = timeline.missions
    targets = MissionTargets(log.mission, log.team, log.targets, zones=log.zones)
    geometry = LegGeometry.of(targets.targets, targets.zones)
    weather = Weather(scenario.weather)
    out: dict[str, list[float | None]] = {}
    for uav in log.team:
        track = timeline.tracks[uav]
        reached = {target: at for at, target in log.arrivals.get(uav, [])}
        legs = log.leg_plans(uav)
        times: list[float | None] = []
        for k, leg in enumerate(legs):
            at = reached.get(leg.target)
            start = None if leg.begun is None else track.aircraft_time(leg.begun)
            end = None if at is None else track.aircraft_time(at)
            result = None if leg.plan is None else log.air_result(uav, leg.plan[1])
            if leg.previous is None or start is None or end is None or result is None:
                times.append(None)
                continue
            planned = Air.of(result)
            mean = weather.mean_at(0.5 * (start + end))  # the drift alone
            true_air = Air(planned.airspeed, Wind(mean.east, mean.north), planned.origin)
            air_legs = AirLegs(geometry, {uav: true_air})
            before = legs[k - 1].previous
            times.append(
                air_legs.turning_leg(
                    uav,
                    air_legs.origin_of(uav) if before is None else before,
                    leg.previous,
                    leg.target,
                )
            )
        out[str(uav)] = times
    return out


def estimate_lines(timeline: Timeline, scenario: Scenario) -> list[str]:
    """Each UAV's result's wind and airspeed against the simulator's at the moment the
    targets were sent (aircraft clock), the weather replayed step by step."""
    (log,) = timeline.missions
    commanded = {uav.piccolo_id: uav.airspeed for uav in scenario.uavs}
    lines = []
    for uav in log.team:
        result, track = log.results.get(uav), timeline.tracks.get(uav)
        at = None if track is None else track.aircraft_time(log.sent)
        if result is None or at is None or result.wind_east is None or result.wind_north is None:
            lines.append(f"  UAV {uav}: no result wind or no clock")
            continue
        weather = Weather(scenario.weather, uav)
        for _ in range(round(at * 1000.0 / STEP_MS)):
            weather.advance(STEP_MS / 1000.0)
        mean, gusty, reported = weather.mean_at(weather.time_s), weather.wind, weather.estimate
        result_wind = Wind(result.wind_east, result.wind_north)

        lines.append(
            f"  UAV {uav} at {at:6.1f} s: result wind ({result_wind.east:5.2f}, "
            f"{result_wind.north:+5.2f}), airspeed {result.airspeed} (flies "
            f"{commanded[uav]:g}); result less true mean {_less(result_wind, mean)}, "
            f"less true wind {_less(result_wind, gusty)}, less reported estimate "
            f"{_less(result_wind, reported)} (east, north m/s)"
        )
    return lines


def _less(a: Wind | SimWind, b: Wind | SimWind) -> str:
    return f"{a.east - b.east:+5.2f} {a.north - b.north:+5.2f}"


def _mission(
    dynamics: str, after_s: float, speedup: float, *, nine: bool, air: Air3, estimate: bool
) -> dict[str, Any]:
    """`fleet report --json` of one run."""
    with tempfile.TemporaryDirectory(prefix="bench-windy-") as folder:
        logs = Path(folder)
        scenario_path = scenario_file(air, logs)
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        up = start_fleet_up(
            str(scenario_path), "--listen", endpoint, "--speedup", f"{speedup:g}",
            "--log-dir", folder, "--dynamics", dynamics,
        )  # fmt: skip
        try:
            wait_fleet_up(up, 120.0)
            time.sleep(after_s)  # the point: targets sent a while after the start
            ground = ("-m", "ground.cli", "--connect", endpoint)
            targets = shipped_scenario_path("windy").with_name("windy_targets.bin")
            how: tuple[str, ...] = ()
            if nine:
                targets, how = windy_nine_csv(logs / "nine.csv"), ("--objective", "min-sum")
            sent = _run(*ground, "send-targets", str(targets), *how, "--wait", "--json",
                        "--timeout", "60", timeout=120.0)  # fmt: skip
            if sent.returncode != 0:
                raise RuntimeError(f"send-targets failed: {sent.stderr[-2000:]}")
            until = (3000.0 if nine else 600.0) / speedup + 60.0
            reached = _run(*ground, "mission", "--until-reached", f"{until:.0f}", "--json",
                           timeout=until + 60.0)  # fmt: skip
            if reached.returncode != 0:
                raise RuntimeError(f"not every target reached: {reached.stdout[-2000:]}")
        finally:
            up.process.send_signal(signal.SIGTERM)
            up.process.wait(60)
        report = _run("-m", "programs.fleet_cli", "report", str(logs / "fleet.mcap"), "--json",
                      timeout=120.0)  # fmt: skip
        if report.returncode != 0:
            raise RuntimeError(f"fleet report failed: {report.stderr[-2000:]}")
        found: dict[str, Any] = json.loads(report.stdout)
        if KEEP[0] is not None:  # the recording kept for a closer look
            kept = Path(KEEP[0]) / f"{dynamics}-{int(time.time())}.mcap"
            kept.parent.mkdir(parents=True, exist_ok=True)
            kept.write_bytes((logs / "fleet.mcap").read_bytes())
            print(f"recording kept: {kept}", flush=True)
        if nine or estimate:
            scenario = load_scenario(scenario_path)
            timeline = build_timeline(read_recording(logs / "fleet.mcap").messages)
            found["true_s"] = true_wind_legs(timeline, scenario) if nine else {}
            found["estimate"] = estimate_lines(timeline, scenario) if estimate else []
    return found


def _error(predicted: float | None, flown: float | None) -> float | None:
    if predicted is None or flown is None or flown <= 0.0:
        return None
    return (predicted - flown) / flown


def _cell(seconds: float | None, error: float | None) -> str:
    if seconds is None or error is None:
        return f"{'-':>16}"
    return f"{seconds:>7.1f} {100 * error:>+6.1f}% "


#: What each leg is predicted by: the plan's time, the UAV's as it began the leg, and
#: the plan's model in the true mean wind of the leg's time.
PREDICTORS = {"plan": "predicted_s", "begun": "begun_s", "true wind": "true_s"}


def print_nine(
    dynamics: str, runs: int, after_s: float, speedup: float, air: Air3, estimate: bool
) -> dict[str, list[float]]:
    """Every leg of every run printed; each predictor's absolute errors returned."""
    print(f"{'dynamics':<10} {'air':<16} {'run':>3} {'UAV':>4} {'leg':>3} {'target':>6} "
          f"{'plan s   error':>16} {'begun s  error':>16} {'true wind error':>16} "
          f"{'flown s':>8} {'epoch':>5}")  # fmt: skip
    errors: dict[str, list[float]] = {name: [] for name in PREDICTORS}
    for run in range(runs):
        legs, said = fly_nine(dynamics, after_s, speedup, air, estimate)
        for uav, rows in legs.items():
            for leg, row in enumerate(rows):
                flown = row["flown_s"]
                cells = []
                for name, key in PREDICTORS.items():
                    error = _error(row.get(key), flown)
                    if error is not None:
                        errors[name].append(abs(error))
                    cells.append(_cell(row.get(key), error))
                flown_text = "-" if flown is None else f"{flown:.1f}"
                print(
                    f"{dynamics:<10} {air.label:<16} {run:>3} {uav:>4} {leg:>3} "
                    f"{row['target']:>6} {' '.join(cells)} {flown_text:>8} "
                    f"{row.get('epoch', 0):>5}",
                    flush=True,
                )
        for line in said:
            print(line, flush=True)
    for name, values in errors.items():
        if values:
            print(
                f"{dynamics} {air.label}: {name} vs flown, {len(values)} legs: median "
                f"{100 * statistics.median(values):.1f} %, worst {100 * max(values):.1f} %"
            )
    return errors


def summary(rows: Sequence[tuple[str, Air3, dict[str, list[float]]]]) -> list[str]:
    """A markdown table: per dynamics and air, each predictor's median and worst."""
    head = "| dynamics | wind, airspeeds (m/s) | legs | " + " | ".join(
        f"{name} median | {name} worst" for name in PREDICTORS
    )
    lines = [head + " |", "|---|---|---:|" + "---:|---:|" * len(PREDICTORS)]
    for dynamics, air, errors in rows:
        cells = []
        for name in PREDICTORS:
            values = errors[name]
            cells += (
                [f"{100 * statistics.median(values):.1f} %", f"{100 * max(values):.1f} %"]
                if values
                else ["-", "-"]
            )
        lines.append(
            f"| {dynamics} | {air.label} | {len(errors['plan'])} | " + " | ".join(cells) + " |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--dynamics", nargs="+", choices=("kinematic", "jsbsim"), default=["kinematic", "jsbsim"]
    )
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--after", type=float, default=0.0, metavar="S")
    parser.add_argument("--speedup", type=float, default=3.0, metavar="K")
    parser.add_argument("--nine", action="store_true", help="nine targets, min-sum queues")
    parser.add_argument(
        "--wind", type=float, nargs="+", metavar="W", help="mean wind speeds (m/s, westerly)"
    )
    parser.add_argument(
        "--airspeeds", type=float, nargs=3, metavar="A", help="airspeeds of UAVs 201, 202, 203"
    )
    parser.add_argument(
        "--estimate", action="store_true", help="each result's wind against the simulator's"
    )
    parser.add_argument("--keep", metavar="DIR", help="copy each run's recording into DIR")
    args = parser.parse_args()
    KEEP[0] = args.keep
    speeds = None if args.airspeeds is None else tuple(args.airspeeds)
    airs = [Air3(wind, speeds) for wind in args.wind] if args.wind else [Air3(None, speeds)]
    if args.nine:
        rows = []
        for dynamics in args.dynamics:
            for air in airs:
                errors = print_nine(
                    dynamics, args.runs, args.after, args.speedup, air, args.estimate
                )
                rows.append((dynamics, air, errors))
        print("\n".join(summary(rows)))
        return
    print(f"{'dynamics':<10} {'run':>3} {'UAV':>4} {'target':<9} {'predicted s':>11} "
          f"{'flown s':>8} {'error':>7}")  # fmt: skip
    for dynamics in args.dynamics:
        for run in range(args.runs):
            for uav, (predicted, flown) in fly(dynamics, args.after, args.speedup).items():
                print(
                    f"{dynamics:<10} {run:>3} {uav:>4} {WHERE[uav]:<9} {predicted:>11.1f} "
                    f"{flown:>8.1f} {100 * (predicted - flown) / flown:>+6.1f}%",
                    flush=True,
                )


if __name__ == "__main__":
    main()
