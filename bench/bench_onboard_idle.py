"""An idle onboard's CPU and wake-ups per thread, two fleets side by side.

Run: .venv/bin/python -m bench.bench_onboard_idle [--uavs 5] [--baseline main]
[--window 30] [--repeat 2] [--port 7611]

Two idle fleets run at once, N UAVs each: *before* (the `--baseline` revision, extracted
as in bench_fleet_scale) and *after* (this tree), so both see the same machine; a
sequential run (bench_fleet_scale's idle window) cannot show a 10 % change on a shared
2-core machine whose load moves by more than that from one minute to the next. For each
window, per onboard: CPU of each thread kind from /proc/PID/task/*/schedstat (run time
in ns, not ticks), and wake-ups (voluntary context switches) a second, by the threads'
kernel names (bench/proc_threads.py): the link loop, the planner, the rest of Python (the
main loop; a previous release's unnamed threads are all "python") and Zenoh's (tx, rx,
net, app).

Each fleet is measured twice: with nobody subscribed to telemetry, then with a
subscriber on each router (as the ground's watch, the page, a recording or
bench_fleet_scale's observer would be): a Zenoh publisher does not send what nobody
subscribes to.
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import time
from pathlib import Path

import zenoh

from bench.bench_fleet_scale import Config, baseline_tree, child_environment
from bench.proc_threads import KINDS, Snapshot, by_kind, snapshot
from fleet.launch.launcher import Fleet, FleetSpec
from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.transport.zenoh_config import make_config

SPACE = KeySpace()


def per_onboard(
    before: Snapshot, after: Snapshot, onboards: int, window: float
) -> dict[str, tuple[float, float]]:
    """{kind: (% of one core, wake-ups/s)} per onboard, and "total"."""
    return {
        name: (100.0 * seconds / window / onboards, wakes / window / onboards)
        for name, (seconds, wakes) in by_kind(before, after).items()
    }


def onboard_pids(fleet: Fleet) -> list[int]:
    return [child.pid for child in fleet.children if child.name.startswith("onboard-")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--uavs", type=int, default=5, help="UAVs per fleet")
    parser.add_argument("--baseline", default="main", help="git revision run as `before`")
    parser.add_argument("--window", type=float, default=30.0, help="seconds per window")
    parser.add_argument("--repeat", type=int, default=2, help="windows per case")
    parser.add_argument("--settle", type=float, default=10.0, help="wait after ready, s")
    parser.add_argument("--port", type=int, default=7611, help="the first router's port")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-idle-") as tmp, contextlib.ExitStack() as stack:
        workdir = Path(tmp)
        scenario = workdir / f"ring-{args.uavs}.toml"
        scenario.write_text(ring_scenario(args.uavs))
        configs = [
            Config("before", pythonpath=baseline_tree(args.baseline, workdir)),
            Config("after"),
        ]
        fleets: dict[str, Fleet] = {}
        routers: dict[str, str] = {}
        for offset, config in enumerate(configs):
            routers[config.name] = f"tcp/127.0.0.1:{args.port + offset}"
            spec = FleetSpec(
                scenario=str(scenario),
                listen=routers[config.name],
                log_dir=workdir / config.name,
                telemetry_hz=20.0,
            )
            with child_environment(config, workdir):
                fleets[config.name] = stack.enter_context(Fleet(spec))
        time.sleep(args.settle)
        print(
            f"{args.uavs} UAVs per fleet, 20 Hz telemetry, {args.window:g} s windows; "
            "per onboard: % of one core (wake-ups/s)"
        )
        print(f"{'case':<14} {'config':<7} " + " ".join(f"{k:>15}" for k in ("total", *KINDS)))
        for subscribed in (False, True):
            subscribers = []
            if subscribed:
                for endpoint in routers.values():
                    session = stack.enter_context(zenoh.open(make_config("client", [endpoint])))
                    subscribers.append(
                        session.declare_subscriber(SPACE.all_telemetry, lambda _: None)
                    )
                time.sleep(1.0)  # the subscriptions reach the publishers
            case = "subscribed" if subscribed else "no subscriber"
            for _ in range(args.repeat):
                pids = {name: onboard_pids(fleet) for name, fleet in fleets.items()}
                first = {name: snapshot(p) for name, p in pids.items()}
                start = time.monotonic()
                time.sleep(args.window)
                window = time.monotonic() - start
                for name, p in pids.items():
                    figures = per_onboard(first[name], snapshot(p), len(p), window)
                    cells = [
                        f"{figures[k][0]:6.3f} ({figures[k][1]:5.1f})" if k in figures else "-"
                        for k in ("total", *KINDS)
                    ]
                    print(f"{case:<14} {name:<7} " + " ".join(f"{c:>15}" for c in cells))
            for subscriber in subscribers:
                subscriber.undeclare()


if __name__ == "__main__":
    main()
