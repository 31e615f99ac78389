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
every queue: the plan's time, the UAV's time said as it began the leg (`begun`: in the
air of that moment, docs/queues.md) and the time flown, with each one's error and their
median and worst; and, for each leg after a queue's first, `true wind`: the plan's leg
model (its airspeed, the turn its queue makes) in the simulator's true mean wind at the
middle of the leg as flown (`fleet.sim.weather`'s drift, without gusts or the estimate's
lag and bias), which tells the model's error from the wind's change. About 750 / K wall
seconds a run.
"""

from __future__ import annotations

import argparse
import json
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from fleet.consensus.legs import Air, AirLegs, LegGeometry
from fleet.geo.wind import Wind
from fleet.launch.endpoints import free_port
from fleet.mission.messages import MissionTargets
from fleet.recording.mission_log import build_timeline
from fleet.recording.reader import read_recording
from fleet.sim.scenario import shipped_scenario, shipped_scenario_path
from fleet.sim.weather import Weather
from tests.support.processes import start_fleet_up, wait_fleet_up
from tests.support.targets import windy_nine_csv

#: Where each UAV's target lies from it, in the scenario's wind (docs/simulator.md).
WHERE = {"201": "upwind", "202": "downwind", "203": "across"}


def _run(*argv: str, timeout: float) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *argv], capture_output=True, text=True, timeout=timeout, check=False
    )


def fly(dynamics: str, after_s: float, speedup: float) -> dict[str, tuple[float, float]]:
    """One run: each UAV's (predicted s, flown s)."""
    (mission,) = _mission(dynamics, after_s, speedup, nine=False)["missions"]
    return {
        uav: (float(mission["predicted_s"][uav]), float(mission["flown_s"][uav])) for uav in WHERE
    }


def fly_nine(dynamics: str, after_s: float, speedup: float) -> dict[str, list[dict[str, Any]]]:
    """One run of nine targets: each UAV's legs (`fleet report --json`'s), each with
    `true_s`, the leg timed in the true mean wind of its time (None for a first leg)."""
    found = _mission(dynamics, after_s, speedup, nine=True)
    (mission,) = found["missions"]
    legs: dict[str, list[dict[str, Any]]] = {uav: mission["legs"][uav] for uav in WHERE}
    for uav, rows in legs.items():
        for row, true_s in zip(rows, found["true_s"][uav], strict=True):
            row["true_s"] = true_s
    return legs


def true_wind_legs(recording: Path) -> dict[str, list[float | None]]:
    """Each UAV's legs, timed by the plan's model in the scenario's true mean wind at
    the middle of each leg (aircraft clock = the simulator's weather clock)."""
    timeline = build_timeline(read_recording(recording).messages)
    (log,) = timeline.missions
    targets = MissionTargets(log.mission, log.team, log.targets, zones=log.zones)
    geometry = LegGeometry.of(targets.targets, targets.zones)
    weather = Weather(shipped_scenario("windy").weather)
    out: dict[str, list[float | None]] = {}
    for uav in log.team:
        track, queue = timeline.tracks[uav], log.queue_of(uav)
        planned = Air.of(log.results[uav])
        reached = {target: at for at, target in log.arrivals.get(uav, [])}
        origin = AirLegs(geometry, {uav: planned})._origin(planned)
        times: list[float | None] = [None]
        previous = reached.get(queue[0]) if queue else None
        for k in range(1, len(queue)):
            at = reached.get(queue[k])
            start = None if previous is None else track.aircraft_time(previous)
            end = None if at is None else track.aircraft_time(at)
            if start is None or end is None:
                times.append(None)
            else:
                mean = weather._mean(0.5 * (start + end))  # the drift alone
                air = Air(planned.airspeed, Wind(mean.east, mean.north), planned.origin)
                before = queue[k - 2] if k >= 2 else origin
                times.append(
                    AirLegs(geometry, {uav: air}).turning_leg(uav, before, queue[k - 1], queue[k])
                )
            previous = at
        out[str(uav)] = times
    return out


def _mission(dynamics: str, after_s: float, speedup: float, *, nine: bool) -> dict[str, Any]:
    """`fleet report --json` of one run."""
    with tempfile.TemporaryDirectory(prefix="bench-windy-") as folder:
        logs = Path(folder)
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        up = start_fleet_up(
            "windy", "--listen", endpoint, "--speedup", f"{speedup:g}", "--log-dir", folder,
            "--dynamics", dynamics,
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
            until = (1000.0 if nine else 400.0) / speedup + 60.0
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
        if nine:
            found["true_s"] = true_wind_legs(logs / "fleet.mcap")
    return found


def _error(predicted: float | None, flown: float | None) -> float | None:
    if predicted is None or flown is None or flown <= 0.0:
        return None
    return (predicted - flown) / flown


def _cell(seconds: float | None, error: float | None) -> str:
    if seconds is None or error is None:
        return f"{'-':>16}"
    return f"{seconds:>7.1f} {100 * error:>+6.1f}% "


def print_nine(dynamics: str, runs: int, after_s: float, speedup: float) -> None:
    print(f"{'dynamics':<10} {'run':>3} {'UAV':>4} {'leg':>3} {'target':>6} "
          f"{'plan s   error':>16} {'begun s  error':>16} {'true wind error':>16} "
          f"{'flown s':>8}")  # fmt: skip
    predictors = {"plan": "predicted_s", "begun": "begun_s", "true wind": "true_s"}
    errors: dict[str, list[float]] = {name: [] for name in predictors}
    for run in range(runs):
        for uav, rows in fly_nine(dynamics, after_s, speedup).items():
            for leg, row in enumerate(rows):
                flown = row["flown_s"]
                cells = []
                for name, key in predictors.items():
                    error = _error(row.get(key), flown)
                    if error is not None:
                        errors[name].append(abs(error))
                    cells.append(_cell(row.get(key), error))
                flown_text = "-" if flown is None else f"{flown:.1f}"
                print(
                    f"{dynamics:<10} {run:>3} {uav:>4} {leg:>3} {row['target']:>6} "
                    f"{' '.join(cells)} {flown_text:>8}",
                    flush=True,
                )
    for name, values in errors.items():
        if values:
            print(
                f"{dynamics}: {name} vs flown, {len(values)} legs: median "
                f"{100 * statistics.median(values):.1f} %, worst {100 * max(values):.1f} %"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--dynamics", nargs="+", choices=("kinematic", "jsbsim"), default=["kinematic", "jsbsim"]
    )
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--after", type=float, default=0.0, metavar="S")
    parser.add_argument("--speedup", type=float, default=3.0, metavar="K")
    parser.add_argument("--nine", action="store_true", help="nine targets, min-sum queues")
    args = parser.parse_args()
    if args.nine:
        for dynamics in args.dynamics:
            print_nine(dynamics, args.runs, args.after, args.speedup)
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
