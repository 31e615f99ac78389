"""What `fleet record` costs under a fleet's telemetry, before and after.

An embedded router in this process; a client of it putting N UAVs' telemetry at 20 Hz
(the onboards' message, each on its UAV's key, at telemetry QoS); and a `fleet record`
process of each tree (`before`: a previous revision extracted with `git archive`;
`after`: this tree), one after the other, alternating. The recorder's CPU, by thread
kind (bench/proc_threads.py), its wake-ups and PSS are read from /proc over a window;
the recording is then read back to count the telemetry in it against what was put.

Run: .venv/bin/python -m bench.bench_recorder_load [--uavs 50] [--window 10] [--repeat 2]
Bounded: every wait has a timeout; each recorder is stopped with SIGINT, then killed.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import zenoh

from bench.bench_fleet_scale import REPO, baseline_tree, pss_kb
from bench.proc_threads import by_kind, snapshot
from fleet.launch.endpoints import free_port
from fleet.mission.key_space import DEFAULT_SPACE
from fleet.piccolo.telemetry import GpsBlock, MagnetometerBlock, RawBlock, SensorBlock, Telemetry
from fleet.recording.reader import read_recording
from fleet.transport.bus_codec import encode
from fleet.transport.bus_qos import TELEMETRY, declare
from fleet.transport.router import Router
from fleet.transport.zenoh_config import make_config
from tests.support.processes import end_process

HZ = 20.0
READY = "fleet record: recording"


def telemetry(uav: int, tick: int) -> bytes:
    """An onboard's telemetry (its fields and size, ~680 bytes of JSON) at `tick`."""
    return encode(
        Telemetry(
            system_time_ms=int(1000 * tick / HZ),
            gps=GpsBlock(35.72 + uav * 1e-4, -120.765, 600.0, 0.0, -22.0, 0.0, 1.0, 12, 10),
            sensor=SensorBlock(0.5, 1.0, 270.0, 22.0),
            raw=RawBlock(0.1, 0.2, 0.3, 0.0, 0.0, -9.8),
            magnetometer=MagnetometerBlock(0.2, 0.1, 0.4),
            agl=400.0,
            actuators=(1500,) * 8,
        )
    )


def publish(session: zenoh.Session, uavs: int, stop: threading.Event, put: list[int]) -> None:
    publishers = [
        declare(session, DEFAULT_SPACE.telemetry(101 + i), TELEMETRY) for i in range(uavs)
    ]
    tick, started = 0, time.monotonic()
    while not stop.is_set():
        # Each UAV at its own phase of the period, as independent onboards put.
        for i, publisher in enumerate(publishers):
            delay = started + (tick + i / uavs) / HZ - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            publisher.put(telemetry(101 + i, tick))
            put[0] += 1
        tick += 1
    for publisher in publishers:
        publisher.undeclare()


def measure(tree: Path, name: str, args: argparse.Namespace, work: Path) -> str:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = work / f"{name}-{time.monotonic_ns()}.mcap"
    with Router([endpoint]), zenoh.open(make_config("client", [endpoint])) as session:
        recorder = subprocess.Popen(
            [sys.executable, "-m", "fleet.recording.commands", "record", str(out),
             "--connect", endpoint],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=work,
            env={**os.environ, "PYTHONPATH": str(tree)},
        )  # fmt: skip
        stop, put = threading.Event(), [0]
        publisher = threading.Thread(target=publish, args=(session, args.uavs, stop, put))
        try:
            assert recorder.stdout is not None
            if READY not in recorder.stdout.readline():
                return f"{name}: the recorder did not start"
            publisher.start()
            time.sleep(2.0)  # every channel registered
            threads0, window0 = snapshot([recorder.pid]), time.monotonic()
            time.sleep(args.window)
            spent = by_kind(threads0, snapshot([recorder.pid]))
            window = time.monotonic() - window0
            pss = pss_kb(recorder.pid) / 1024
        finally:
            stop.set()
            if publisher.is_alive():
                publisher.join(timeout=10.0)
            time.sleep(1.0)  # the last samples reach the recorder
            end_process(recorder, signal.SIGINT, 30.0)
    recording = read_recording(out)
    heard = sum(1 for m in recording.messages if m.topic.endswith("/telemetry"))
    fixes = sum(1 for m in recording.messages if m.topic.endswith("/location_fix"))
    total, wakes = spent["total"]
    kinds = "  ".join(
        f"{kind} {100 * seconds / window:.1f}"
        for kind, (seconds, _) in sorted(spent.items())
        if kind != "total" and seconds > 0.005 * window
    )
    return (
        f"| {name} | {100 * total / window:.1f} | {wakes / window:.0f} | {pss:.0f} "
        f"| {heard} / {put[0]} | {fixes} | {out.stat().st_size / 1e6:.1f} | {kinds} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--uavs", type=int, default=50)
    parser.add_argument("--window", type=float, default=10.0, help="measured window, s")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--baseline", default="main", help="git revision run as `before`")
    args = parser.parse_args()
    print(
        f"{args.uavs} UAVs' telemetry at {HZ:g} Hz ({args.uavs * HZ:g} samples/s); "
        f"window {args.window:g} s; load average {os.getloadavg()[0]:.1f}"
    )
    print(
        "| config | CPU % of a core | wake-ups/s | PSS MB | telemetry recorded / put "
        "| map fixes | MB | CPU % by thread |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory(prefix="bench-rec-") as tmp:
        work = Path(tmp)
        trees = {"before": baseline_tree(args.baseline, work), "after": REPO}
        for repeat in range(args.repeat):
            for name in ("before", "after") if repeat % 2 == 0 else ("after", "before"):
                print(measure(trees[name], name, args, work), flush=True)


if __name__ == "__main__":
    main()
