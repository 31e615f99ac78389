"""Start and stop `fleet up` in a loop, and count what goes wrong.

    python -m bench.bench_stress [--cycles 20] [--uavs 4] [--fly 5] [--kill-every 3]

For each mode (onboards forked from the fork server, and `--no-fork-server`), `--cycles`
times: start `fleet up --uavs N --speedup 10` on a free port, wait until it is ready,
let it fly `--fly` seconds, then stop it: with SIGTERM, or every `--kill-every`-th cycle
with SIGKILL. Counted:

* starts that failed, and crashes: a process of the fleet that died of a signal or left
  a "Fatal Python error" (faulthandler's dump) in its log or output;
* after each SIGKILL of the launcher, the processes of its tree still running 10 s
  later (orphans; they are then killed), and how long the tree took to go;
* after each SIGTERM, the recording's telemetry samples per UAV: the smallest UAV's
  count over the median UAV's.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from fleet.launch.endpoints import free_port
from fleet.recording.reader import RecordingError, read_recording
from tests.support.processes import descendants, running

READY_S = 180.0
STOP_S = 60.0
#: After a SIGKILL of the launcher, a process of its tree still running this long
#: later is an orphan.
ORPHAN_S = 10.0
CRASH_MARK = "Fatal Python error"


@dataclass
class ModeResult:
    mode: str
    cycles: int = 0
    ready: int = 0
    start_failures: list[str] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    kills: int = 0
    orphans: int = 0
    gone_s: list[float] = field(default_factory=list)
    ratios: list[float] = field(default_factory=list)


def telemetry_counts(path: Path) -> Counter[int]:
    counts: Counter[int] = Counter()
    try:
        recording = read_recording(path)
    except RecordingError:
        return counts
    for topic, count in recording.counts().items():
        parts = topic.split("/")
        if len(parts) == 4 and parts[1] == "uav" and parts[3] == "telemetry":
            counts[int(parts[2])] += count
    return counts


def crashes_in(log_dir: Path, output: str) -> list[str]:
    found = [f"fleet up output: {CRASH_MARK}"] if CRASH_MARK in output else []
    for log in sorted(log_dir.glob("*.log")):
        if CRASH_MARK in log.read_text(errors="replace"):
            found.append(f"{log.name}: {CRASH_MARK}")
    return found


def cycle(result: ModeResult, args: argparse.Namespace, kill: bool, work: Path) -> None:
    result.cycles += 1
    log_dir = work / f"{result.mode}-{result.cycles}"
    log_dir.mkdir()
    out_path = log_dir / "fleet-up.out"
    argv = [sys.executable, "-m", "programs.fleet_cli", "up", "--uavs", str(args.uavs)]
    argv += ["--speedup", "10", "--listen", f"tcp/127.0.0.1:{free_port()}"]
    argv += ["--log-dir", str(log_dir)]
    if result.mode == "no-fork-server":
        argv.append("--no-fork-server")
    with open(out_path, "w") as out:
        up = subprocess.Popen(
            argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True,
        )  # fmt: skip
    deadline = time.monotonic() + READY_S
    while "stops the fleet" not in out_path.read_text() and up.poll() is None:
        if time.monotonic() > deadline:
            break
        time.sleep(0.2)
    output = out_path.read_text(errors="replace")
    if "stops the fleet" not in output:
        up.kill()
        up.wait()
        result.start_failures.append(f"cycle {result.cycles}: status {up.returncode}")
        result.crashes += [f"cycle {result.cycles}: {c}" for c in crashes_in(log_dir, output)]
        return
    result.ready += 1
    time.sleep(args.fly)
    tree = descendants(up.pid)
    if kill:
        result.kills += 1
        up.send_signal(signal.SIGKILL)
        up.wait()
        killed = time.monotonic()
        while any(running(pid) for pid in tree) and time.monotonic() - killed < ORPHAN_S:
            time.sleep(0.05)
        left = [pid for pid in tree if running(pid)]
        if left:
            result.orphans += len(left)
            for pid in left:
                os.kill(pid, signal.SIGKILL)
        else:
            result.gone_s.append(time.monotonic() - killed)
        return
    up.send_signal(signal.SIGTERM)
    try:
        status = up.wait(STOP_S)
    except subprocess.TimeoutExpired:
        up.kill()
        status = up.wait()
    output = out_path.read_text(errors="replace")
    if status < 0:
        result.crashes.append(f"cycle {result.cycles}: fleet up died of signal {-status}")
    result.crashes += [f"cycle {result.cycles}: {c}" for c in crashes_in(log_dir, output)]
    counts = telemetry_counts(log_dir / "fleet.mcap")
    samples = [counts[uav] for uav in range(101, 101 + args.uavs)]
    median = statistics.median(samples)
    if median > 0:
        result.ratios.append(min(samples) / median)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=20, help="cycles per mode")
    parser.add_argument("--uavs", type=int, default=4)
    parser.add_argument("--fly", type=float, default=5.0, help="seconds flown once ready")
    parser.add_argument("--kill-every", type=int, default=3, help="SIGKILL every Nth cycle")
    parser.add_argument("--modes", default="fork-server,no-fork-server")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-stress-") as folder:
        for mode in args.modes.split(","):
            result = ModeResult(mode)
            for n in range(1, args.cycles + 1):
                cycle(result, args, args.kill_every > 0 and n % args.kill_every == 0, Path(folder))
            report(result)


def report(result: ModeResult) -> None:
    gone = f"max {max(result.gone_s):.2f} s" if result.gone_s else "-"
    ratios = sorted(result.ratios)
    print(f"{result.mode}: {result.cycles} cycles, {result.ready} ready")
    print(f"  start failures: {len(result.start_failures)} {result.start_failures}")
    print(f"  crashes: {len(result.crashes)} {result.crashes}")
    print(f"  SIGKILLs of fleet up: {result.kills}, orphans 10 s later: {result.orphans}, "
          f"tree gone after {gone}")  # fmt: skip
    if ratios:
        within = sum(ratio >= 0.95 for ratio in ratios)
        print(
            f"  recordings: {len(ratios)}; smallest UAV / median UAV telemetry: "
            f"min {ratios[0]:.3f}, median {statistics.median(ratios):.3f}; "
            f"{within} of {len(ratios)} with every UAV within 5 % of the median"
        )
    sys.stdout.flush()


if __name__ == "__main__":
    main()
