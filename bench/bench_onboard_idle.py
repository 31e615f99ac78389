"""An idle onboard's CPU and wake-ups per thread, two fleets side by side (issue 14).

Run: .venv/bin/python -m bench.bench_onboard_idle [--uavs 5] [--baseline main]
[--window 30] [--repeat 2] [--port 7611]

Two idle fleets run at once, N UAVs each: *before* (the `--baseline` revision, extracted
as in bench_fleet_scale) and *after* (this tree), so both see the same machine; a
sequential run (bench_fleet_scale's idle window) cannot show a 10 % change on a shared
2-core machine whose load moves by more than that from one minute to the next. For each
window, per onboard: CPU of each thread kind from /proc/PID/task/*/schedstat (run time
in ns, not ticks), and wake-ups (voluntary context switches) a second. Python's threads
(main loop, link loop, planner worker) are one kind, Zenoh's by name (tx, rx, net, app).

Each fleet is measured twice: with nobody subscribed to telemetry, then with a
subscriber on each router (as the ground's watch, the page, a recording or
bench_fleet_scale's observer would be): a Zenoh publisher does not send what nobody
subscribes to.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import os
import tempfile
import time
from pathlib import Path

import zenoh

from bench.bench_fleet_scale import Config, baseline_tree, child_environment
from fleet.launch.launcher import Fleet, FleetSpec, ring_scenario
from fleet.mission import keys
from fleet.transport.zenoh_config import make_config

#: (pid, tid) -> (thread kind, run time ns, voluntary switches)
Snapshot = dict[tuple[int, int], tuple[str, int, int]]
KINDS = ("python", "tx", "rx", "net", "app", "acc")


def kind_of(comm: str) -> str:
    head = comm.split("-", 1)[0]
    return head if head in KINDS else "python"


def snapshot(pids: list[int]) -> Snapshot:
    found: Snapshot = {}
    for pid in pids:
        with contextlib.suppress(OSError):
            for tid in os.listdir(f"/proc/{pid}/task"):
                task = f"/proc/{pid}/task/{tid}"
                try:
                    comm = Path(f"{task}/comm").read_text().strip()
                    run_ns = int(Path(f"{task}/schedstat").read_text().split()[0])
                    status = Path(f"{task}/status").read_text()
                except OSError:
                    continue  # the thread ended
                switches = next(
                    int(line.split()[1])
                    for line in status.splitlines()
                    if line.startswith("voluntary_ctxt_switches")
                )
                found[(pid, int(tid))] = (kind_of(comm), run_ns, switches)
    return found


def per_onboard(
    before: Snapshot, after: Snapshot, onboards: int, window: float
) -> dict[str, tuple[float, float]]:
    """{kind: (% of one core, wake-ups/s)} per onboard, and "total"."""
    sums: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0])
    for key, (kind, run_ns, switches) in after.items():
        if key not in before:
            continue
        _, run0, switches0 = before[key]
        for name in (kind, "total"):
            sums[name][0] += run_ns - run0
            sums[name][1] += switches - switches0
    return {
        name: (100.0 * ns / 1e9 / window / onboards, wakes / window / onboards)
        for name, (ns, wakes) in sums.items()
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
                        session.declare_subscriber(f"{keys.PREFIX}/uav/*/telemetry", lambda _: None)
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
