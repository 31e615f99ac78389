"""`bench_fleet_scale --whole-tree`: the fleet as a user runs it, `fleet up --uavs N`.

For each N and configuration (`before`: the fleet of a previous revision, extracted with
`git archive`; `after`: this tree), interleaved, it runs `fleet up --uavs N` as a user
does (the embedded router in it, recording on, speedup 1, the simulator's default 20 Hz
telemetry) and measures, per process kind (onboards, the fork server that starts them,
recorder, simulator, `fleet up` with its router):

* ready: from the start to `fleet up` printing that every UAV is alive;
* CPU from /proc/PID/stat over an idle window, once every approach model is built, in
  % of one core; nothing of the benchmark is connected then (it joins as a client
  afterwards, as a ground would), so the router carries the fleet's traffic only;
* PSS from /proc/PID/smaps_rollup (each shared page divided among its mappers) and
  RSS, idle;
* per mission of N targets (MAX_TARGETS at most), sent with the deadline
  `ground-cli send-targets` gives a team of N (fleet.consensus.deadline; the onboards
  plan for half of it): send -> last commit and the consensus window, last result ->
  last commit (router timestamps), and last result -> the median UAV's commit; whether
  the team agreed, and how many approach times came from the model and how many from
  the Dubins fallback;
* telemetry extra latency p99 over a second idle window, the benchmark connected.

Run: .venv/bin/python -m bench.bench_fleet_scale --whole-tree [--sizes 2 10 20 50 100]
Bounded: every start, idle window and mission has a timeout; `fleet up` is stopped with
SIGINT (as Ctrl-C) and its children, by PID, with SIGKILL if it does not stop them.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import zenoh

from bench.bench_fleet_scale import (
    REPO,
    Mission,
    Observer,
    baseline_tree,
    cpu_seconds,
    pss_kb,
    run_missions,
    status_field,
    wait_models_built,
)
from fleet.consensus.deadline import consensus_deadline
from fleet.mission.messages import MAX_TARGETS
from fleet.transport.zenoh_config import make_config

KINDS = ("onboards", "fork server", "recorder", "simulator", "fleet up")
#: How long `fleet up` gets to stop 100 onboards after Ctrl-C before it is killed.
STOP_LIMIT_S = 120.0


def kind_of(pid: int, root: int, parent: int) -> str | None:
    if pid == root:
        return "fleet up"
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return None
    if b"fleet.launch.fork_server" in argv:
        # The server's children (the onboards it forked) keep its command line.
        return "fork server" if parent == root else "onboards"
    if b"onboard.main" in argv:
        return "onboards"
    if b"fleet.recording.commands" in argv:
        return "recorder"
    if b"fleet.sim.command" in argv:
        return "simulator"
    return None


def process_tree(root: int) -> dict[int, str]:
    """`root` and its descendants that are fleet parts, by PID -> kind."""
    parents: dict[int, list[int]] = defaultdict(list)
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
                parents[int(stat[1])].append(int(entry))
    found: dict[int, str] = {}
    todo = [(root, 0)]
    while todo:
        pid, parent = todo.pop()
        kind = kind_of(pid, root, parent)
        if kind is not None:
            found[pid] = kind
        todo.extend((child, pid) for child in parents.get(pid, []))
    return found


def fleet_module(tree: Path) -> str:
    """The `fleet` command's module in `tree`: programs/ now, ground/ in revisions
    before the commands moved above the applications."""
    if (tree / "programs" / "fleet_cli.py").exists():
        return "programs.fleet_cli"
    return "ground.fleet_cli"


@dataclass
class TreeRow:
    n: int
    config: str
    load: float  # 1-minute load average when the fleet started
    ready_s: float | None
    models_s: float | None
    cpu: dict[str, float]  # % of one core, by kind
    pss_mb: dict[str, float]
    rss_mb: dict[str, float]
    latency_p99_ms: float | None
    missions: list[Mission]


class FleetUp:
    """`fleet up --uavs N` of a tree, its stdout read for the ready line."""

    def __init__(self, tree: Path, n: int, port: int, log_dir: Path, timeout_s: float) -> None:
        self.ready = threading.Event()
        self.lines: list[str] = []
        env = {**os.environ, "PYTHONPATH": str(tree)}
        argv = [sys.executable, "-m", fleet_module(tree), "up", "--uavs", str(n)]
        argv += ["--listen", f"tcp/127.0.0.1:{port}", "--log-dir", str(log_dir)]
        argv += ["--start-timeout", f"{timeout_s:g}"]
        # Started in the log folder: `python -m` puts the working directory first on the
        # path, and the tree on PYTHONPATH is the one to import.
        self.process = subprocess.Popen(
            argv,
            cwd=log_dir,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        self.log_dir = log_dir
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for raw in self.process.stdout:
            line = raw.decode(errors="replace").rstrip()
            self.lines.append(line)
            if "UAV(s) alive" in line:
                self.ready.set()
        self.ready.set()  # it exited: stop waiting

    def stop(self) -> None:
        children = [pid for pid in process_tree(self.process.pid) if pid != self.process.pid]
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=STOP_LIMIT_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        for pid in children:  # only if `fleet up` could not stop them
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        self._reader.join(timeout=10.0)
        if self.process.stdout is not None:
            self.process.stdout.close()


def measure_tree(tree: Path, name: str, n: int, args: argparse.Namespace, work: Path) -> TreeRow:
    log_dir = work / f"{name}-{n}"
    log_dir.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()[0]
    started = time.monotonic()
    fleet = FleetUp(tree, n, args.port, log_dir, args.start_timeout)
    connect = f"tcp/127.0.0.1:{args.port}"
    cpu: dict[str, float] = {}
    pss: dict[str, float] = {}
    rss: dict[str, float] = {}
    missions: list[Mission] = []
    latency: float | None = None
    models: float | None = None
    ready: float | None = None
    try:
        fleet.ready.wait(args.start_timeout + 10.0)
        if fleet.process.poll() is not None or not any("UAV(s) alive" in x for x in fleet.lines):
            tail = "\n".join(fleet.lines[-15:])
            print(f"N={n} {name}: fleet up did not become ready:\n{tail}", flush=True)
            return TreeRow(n, name, load, None, None, cpu, pss, rss, None, missions)
        ready = time.monotonic() - started
        team = set(range(101, 101 + n))
        probe = zenoh.open(make_config("client", connect=[connect]))
        try:
            if wait_models_built(probe, team, args.start_timeout):
                models = time.monotonic() - started
        finally:
            probe.close()
        time.sleep(args.settle)
        kinds = process_tree(fleet.process.pid)
        cpu0 = {pid: cpu_seconds(pid) for pid in kinds}
        window0 = time.monotonic()
        time.sleep(args.idle)
        window = time.monotonic() - window0
        for pid, kind in kinds.items():
            cpu[kind] = cpu.get(kind, 0.0) + 100.0 * (cpu_seconds(pid) - cpu0[pid]) / window
            pss[kind] = pss.get(kind, 0.0) + pss_kb(pid) / 1024.0
            rss[kind] = rss.get(kind, 0.0) + status_field(pid, "VmRSS") / 1024.0
        ground = zenoh.open(make_config("client", connect=[connect]))
        observer = Observer(ground)
        try:
            onboards = [pid for pid, kind in kinds.items() if kind == "onboards"]
            sim = next(pid for pid, kind in kinds.items() if kind == "simulator")
            # Telemetry latency over an idle window of its own: the observer's subscription
            # costs the router, and a mission's solves saturate the cores.
            observer.recording = True
            time.sleep(args.idle)
            observer.recording = False
            latency = observer.latency_p99_ms()
            log: list[str] = []
            # The deadline `ground-cli send-targets` gives a team of N (it sets the
            # onboards' planning budget: half of it).
            deadline = consensus_deadline(n)
            missions = run_missions(
                ground, observer, tuple(sorted(team)), args.missions, deadline, (onboards, sim), log
            )
        finally:
            observer.close()
            ground.close()
    finally:
        fleet.stop()
    return TreeRow(n, name, load, ready, models, cpu, pss, rss, latency, missions)


# ---- the table --------------------------------------------------------------------------------
def _median(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def _ms(values: list[float]) -> str:
    if not values:
        return "-"
    low, high = min(values) * 1000, max(values) * 1000
    return f"{low:.0f}" if round(low) == round(high) else f"{low:.0f}-{high:.0f}"


HEADER = (
    "  N config    load  ready  model | CPU %: onb  fork   rec   sim    up  total"
    " | PSS GB: onb  fork   rec   sim    up  total | RSS GB | tel p99 | send->com s"
    " | res->com ms | res->med ms | ok | model:fallback"
)


def format_tree(row: TreeRow) -> str:
    def opt(value: float | None, digits: int = 1) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    cpu = " ".join(f"{row.cpu.get(k, 0.0):5.1f}" for k in KINDS)
    pss = " ".join(f"{row.pss_mb.get(k, 0.0) / 1024:5.3f}" for k in KINDS)
    sends = [m.send_to_commit for m in row.missions if m.send_to_commit is not None]
    windows = [m.result_to_commit for m in row.missions if m.result_to_commit is not None]
    medians = [m.result_to_median_commit for m in row.missions]
    agreed = sum(1 for m in row.missions if m.agreed)
    send = "-" if not sends else f"{min(sends):.2f}-{max(sends):.2f}"
    answers = "/".join("?" if m.model is None else f"{m.model}:{m.fallback}" for m in row.missions)
    return (
        f"{row.n:>3} {row.config:<8} {row.load:5.1f} {opt(row.ready_s):>6} {opt(row.models_s):>6}"
        f" |       {cpu} {sum(row.cpu.values()):6.1f}"
        f" |        {pss} {sum(row.pss_mb.values()) / 1024:6.3f}"
        f" | {sum(row.rss_mb.values()) / 1024:6.2f} | {opt(row.latency_p99_ms, 0):>7}"
        f" | {send:>11} | {_ms(windows):>11}"
        f" | {_ms([m for m in medians if m is not None]):>11} | {agreed}/{len(row.missions)}"
        f" | {answers}"
    )


def tree_ratios(before: TreeRow, after: TreeRow) -> str:
    def ratio(a: float | None, b: float | None) -> str:
        return "-" if a is None or b is None or b == 0 else f"{a / b:.2f}"

    def window(row: TreeRow) -> float | None:
        return _median([m.result_to_commit for m in row.missions if m.result_to_commit])

    by_kind = "  ".join(
        f"{k} {ratio(after.cpu.get(k), before.cpu.get(k))}" for k in KINDS if k in before.cpu
    )
    return (
        f"N={after.n} after/before: CPU {ratio(sum(after.cpu.values()), sum(before.cpu.values()))}"
        f" ({by_kind})  PSS {ratio(sum(after.pss_mb.values()), sum(before.pss_mb.values()))}"
        f"  ready {ratio(after.ready_s, before.ready_s)}"
        f"  result->commit {ratio(window(after), window(before))}"
    )


def run(args: argparse.Namespace) -> None:
    too_many = [n for n in args.sizes if n > MAX_TARGETS]
    if too_many:
        raise SystemExit(f"a mission has at most {MAX_TARGETS} targets: N {too_many}")
    print(
        f"{os.cpu_count()} cores; `fleet up --uavs N` (router, recorder, simulator at 20 Hz, "
        f"N onboards); idle window {args.idle:g} s; {args.missions} mission(s) of N targets; "
        f"before = {args.baseline}",
        flush=True,
    )
    rows: list[TreeRow] = []
    with tempfile.TemporaryDirectory(prefix="bench-tree-") as tmp:
        work = Path(tmp) if args.keep is None else args.keep
        work.mkdir(parents=True, exist_ok=True)
        trees = {"after": REPO}
        if "before" in args.configs:
            trees["before"] = baseline_tree(
                args.baseline, work, ("fleet", "onboard", "ground", "programs")
            )
        print(HEADER, flush=True)
        for n in args.sizes:
            for repeat in range(args.repeat):
                # Interleaved, and the order swapped each repeat, so neither configuration
                # always runs on the machine the other just heated.
                order = [c for c in args.configs if c in trees]
                for name in order if repeat % 2 == 0 else order[::-1]:
                    row = measure_tree(trees[name], name, n, args, work)
                    rows.append(row)
                    print(format_tree(row), flush=True)
    print()
    for n in args.sizes:
        before = [r for r in rows if r.n == n and r.config == "before"]
        after = [r for r in rows if r.n == n and r.config == "after"]
        for b, a in zip(before, after, strict=False):
            print(tree_ratios(b, a))
    sys.stdout.flush()
