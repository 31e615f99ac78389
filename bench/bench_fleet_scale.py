"""A whole simulated fleet on this machine, N UAVs and M = N targets: what it costs.

For each N and each configuration it starts the fleet the way `fleet up --uavs N` does
(fleet.launch.launcher: embedded router, one simulator at 20 Hz telemetry, one onboard
process per UAV), then measures:

* ready: from the start to every UAV's liveliness token (what `fleet up` waits for);
* CPU: the fleet's children (simulator + onboards), summed over their PIDs from
  /proc/PID/stat during an idle window, in % of one core (the machine has `nproc` x 100 %);
  the router and the observer (a client of the router, as a ground is) run in this
  process and are shown apart;
* RSS: the children's resident memory summed from /proc/PID/status, idle and after the
  missions; this counts every shared library (Zenoh's 12 MB, libpython, HiGHS) once per
  process. PSS (/proc/PID/smaps_rollup: each shared page divided among the processes
  that map it) summed over the children is the memory the fleet really holds;
* telemetry extra latency p99: for every telemetry sample seen on the bus, its arrival
  minus the simulator time it carries, less the smallest such offset of that UAV;
  arrivals are the router's timestamps (`arrival`), taken before this process's Python
  callbacks run, so its own load does not count;
* per mission: send -> last commit, last result -> last commit and last result -> the
  median UAV's commit (router timestamps too), and how many
  approach times came from the model and how many from the Dubins fallback (from the
  results' `model_times`/`fallback_times`, or from the status text of a release that did
  not report them);
* per mission, the CPU seconds from the send to the last commitment, by where they went
  (the onboards' planners, link loops, main loops and Zenoh threads by their kernel
  names, bench/proc_threads.py; the simulator; this process's router and observer):
  send -> last commit is their sum over the cores when the machine is the limit.

Configurations: `before` runs the onboard and the simulator of a previous revision
(`--baseline REV`, extracted with `git archive`, default `main`) with its default
settings; `after` runs this tree, with the planning budget following the team size
(`--budget`, see `team_budget`) and the mission deadline after it. The same run prints
after/before ratios.

Run: .venv/bin/python -m bench.bench_fleet_scale [--sizes 2 10 20 50] [--configs before after]
`--whole-tree` measures instead `fleet up --uavs N` as a user runs it, with its router and
recorder, per process kind (bench/fleet_tree.py).
Bounded: every fleet start, idle window and mission has a timeout; every process this
starts is stopped (Fleet.stop), whatever happens.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import msgspec
import zenoh

from bench.proc_threads import by_kind, snapshot
from fleet.launch.launcher import Fleet, FleetSpec
from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    StatusText,
    UavResult,
    UavState,
)
from fleet.transport.bus_codec import ENCODING, encode
from fleet.transport.zenoh_bus import direct
from fleet.transport.zenoh_config import make_config
from tests.support.targets import ring_targets

SPACE = KeySpace()

REPO = Path(__file__).resolve().parent.parent
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
CORES = os.cpu_count() or 1
TELEMETRY_HZ = 20.0
_FALLBACK_STATUS = re.compile(
    r"mission (\d+): approach times in [\d.]+ s(?:; (\d+) by the Dubins)?"
)


class _Stamp(msgspec.Struct):
    system_time_ms: int


@dataclass
class Config:
    name: str
    pythonpath: Path | None = None  # a baseline tree, or None for this one
    onboard_args: tuple[str, ...] = ()
    env: dict[str, str] = field(default_factory=dict)
    team_budget: bool = False  # planning budget and deadline follow the team size


@dataclass
class Mission:
    send_to_commit: float | None
    result_to_commit: float | None
    #: last result -> the median UAV's commitment: a delay every UAV shares (the machine's
    #: run queue) against a few late ones
    result_to_median_commit: float | None
    model: int | None
    fallback: int | None
    agreed: bool
    #: CPU seconds from the send until every commitment was seen, by where they went:
    #: the onboards' thread kinds (bench/proc_threads.py), "sim", and "router" (this
    #: process: the router and the observer)
    cpu: dict[str, float] = field(default_factory=dict)


@dataclass
class Row:
    n: int
    config: str
    ready_s: float
    models_s: float | None  # until every UAV says its model is built (None: cannot say)
    cpu_pct: float
    sim_cpu_pct: float
    ground_cpu_pct: float
    rss_idle_mb: float
    rss_after_mb: float
    pss_idle_mb: float
    pss_after_mb: float
    threads: float  # per onboard, mean
    latency_p99_ms: float | None
    missions: list[Mission]
    solve_s: float  # one UAV's uncontended solve of M targets, in this process
    budget_s: float | None
    defects: int  # "approach model defect" lines in the onboards' logs


# ---- /proc ----------------------------------------------------------------------------------
def cpu_seconds(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS  # utime, stime


def status_field(pid: int, name: str) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(name + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def pss_kb(pid: int) -> int:
    """Proportional set size: resident pages, each shared one divided among its mappers."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


# ---- what the ground sees -------------------------------------------------------------------
def arrival(sample: zenoh.Sample) -> float:
    """When the router took `sample` in (its timestamp, wall clock), else now.

    The router stamps every sample it routes; its time is taken before any Python code
    of this process sees the sample, so a busy benchmark process delays no figure.
    """
    stamp = sample.timestamp
    return stamp.get_time().timestamp() if stamp is not None else time.time()


class Observer:
    """Telemetry offsets, results, commits and status texts, timed on arrival."""

    def __init__(self, session: zenoh.Session) -> None:
        self.lock = threading.Lock()
        self.recording = False
        self.offsets: dict[int, list[float]] = {}
        self.results: dict[tuple[int, int], tuple[float, UavResult]] = {}
        self.commits: dict[tuple[int, int], tuple[float, AssignmentReport]] = {}
        self.fallbacks: dict[tuple[int, int], tuple[int, int]] = {}  # from status texts
        self.subscribers = [
            session.declare_subscriber(SPACE.all_telemetry, direct(self.on_telemetry)),
            session.declare_subscriber(SPACE.all_mission_results, direct(self.on_result)),
            session.declare_subscriber(SPACE.all_mission_assignments, direct(self.on_commit)),
            session.declare_subscriber(SPACE.all_status, direct(self.on_status)),
        ]

    def on_telemetry(self, sample: zenoh.Sample) -> None:
        now = arrival(sample)
        if not self.recording:
            return
        stamp = msgspec.json.decode(sample.payload.to_bytes(), type=_Stamp)
        uav = uav_id_of(str(sample.key_expr))
        with self.lock:
            self.offsets.setdefault(uav, []).append(now - stamp.system_time_ms / 1000.0)

    def on_result(self, sample: zenoh.Sample) -> None:
        now = arrival(sample)
        result = msgspec.json.decode(sample.payload.to_bytes(), type=UavResult)
        with self.lock:
            self.results.setdefault((result.mission, result.uav), (now, result))

    def on_commit(self, sample: zenoh.Sample) -> None:
        now = arrival(sample)
        report = msgspec.json.decode(sample.payload.to_bytes(), type=AssignmentReport)
        with self.lock:
            self.commits.setdefault((report.mission, report.uav), (now, report))

    def on_status(self, sample: zenoh.Sample) -> None:
        text = msgspec.json.decode(sample.payload.to_bytes(), type=StatusText).text
        match = _FALLBACK_STATUS.search(text)
        if match is None:
            return
        uav = uav_id_of(str(sample.key_expr))
        with self.lock:
            self.fallbacks[(int(match[1]), uav)] = (0, int(match[2] or 0))

    def latency_p99_ms(self) -> float | None:
        with self.lock:
            extra = [o - min(offsets) for offsets in self.offsets.values() for o in offsets]
        if len(extra) < 2:
            return None
        return 1000.0 * statistics.quantiles(extra, n=100)[98]

    def close(self) -> None:
        for subscriber in self.subscribers:
            subscriber.undeclare()


# ---- one fleet ------------------------------------------------------------------------------
@contextlib.contextmanager
def child_environment(config: Config, workdir: Path) -> Iterator[None]:
    """The children inherit this process's environment: set it for the time of the start.

    They also inherit its working directory, which `python -m` puts first on the path:
    they start in the work directory, so a baseline on PYTHONPATH is what they import.
    """
    changes = dict(config.env)
    if config.pythonpath is not None:
        changes["PYTHONPATH"] = str(config.pythonpath)
    saved = {name: os.environ.get(name) for name in changes}
    os.environ.update(changes)
    cwd = Path.cwd()
    os.chdir(workdir)
    try:
        yield
    finally:
        os.chdir(cwd)
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def uncontended_solve_s(n_targets: int) -> float:
    """One UAV's solve of `n_targets` (ring targets, from the ring's centre) in this process."""
    from fleet.geo.aircraft import AircraftLimits
    from fleet.geo.mercator import MercatorProjection
    from fleet.launch.ring import GENERATED_CENTRE
    from onboard.planner.approach_model import ApproachTimeModel

    projection = MercatorProjection(*GENERATED_CENTRE)
    targets = [projection.to_xy(t.lat, t.lon) for t in ring_targets(n_targets, seed=99)]
    model = ApproachTimeModel(AircraftLimits(max_airspeed=22.0))
    started = time.perf_counter()
    model.solve((0.0, 0.0), (22.0, 0.0), targets)
    return time.perf_counter() - started


def team_budget(n: int, solve_s: float) -> float:
    """A planning budget that follows the team size: every UAV solving on `CORES` cores,
    with room for the machine's other load (x2), never under the default 2 s."""
    return max(2.0, 2.0 * n * solve_s / CORES)


def wait_models_built(session: zenoh.Session, team: set[int], limit_s: float) -> bool:
    """Poll every UAV's state until each says its approach model is built.

    False at once if a UAV's state has no `model_speed` (a revision that cannot say), or
    after `limit_s`.
    """
    give_up = time.monotonic() + limit_s
    while time.monotonic() < give_up:
        built = set()
        for reply in session.get(SPACE.all_state, timeout=5.0):
            if reply.ok is not None:
                raw = msgspec.json.decode(reply.ok.payload.to_bytes())
                if isinstance(raw, dict) and "model_speed" not in raw:
                    return False
                state = msgspec.json.decode(reply.ok.payload.to_bytes(), type=UavState)
                if state.model_speed is not None:
                    built.add(state.uav)
        if team <= built:
            return True
        time.sleep(0.5)
    return False


def run_missions(
    session: zenoh.Session,
    observer: Observer,
    team: tuple[int, ...],
    count: int,
    deadline_s: float,
    processes: tuple[list[int], int],
    log: list[str],
) -> list[Mission]:
    """Send `count` missions one after the other; `processes`: the onboards' PIDs and the
    simulator's, whose CPU is counted from each send to its last commitment."""
    onboards, sim = processes
    missions = []
    for mission in range(1, count + 1):
        message = MissionTargets(mission, team, ring_targets(len(team), seed=mission), deadline_s)
        threads0, sim0, own0 = snapshot(onboards), snapshot([sim]), time.process_time()
        sent = time.time()
        session.put(SPACE.mission_targets(mission), encode(message), encoding=ENCODING)
        limit = time.monotonic() + deadline_s + 30.0
        while time.monotonic() < limit:
            with observer.lock:
                if all((mission, uav) in observer.commits for uav in team):
                    break
            time.sleep(0.01)
        spent = by_kind(threads0, snapshot(onboards))
        cpu = {kind: seconds for kind, (seconds, _) in spent.items()}
        cpu["sim"] = by_kind(sim0, snapshot([sim]))["total"][0]
        cpu["router"] = time.process_time() - own0
        missions.append(summarise(observer, mission, team, sent, cpu))
        log.append(f"mission {mission}: {missions[-1]}")
        time.sleep(1.0)
    return missions


def summarise(
    observer: Observer, mission: int, team: tuple[int, ...], sent: float, cpu: dict[str, float]
) -> Mission:
    with observer.lock:
        commits = [observer.commits[(mission, u)] for u in team if (mission, u) in observer.commits]
        results = [observer.results[(mission, u)] for u in team if (mission, u) in observer.results]
        statuses = [observer.fallbacks.get((mission, u)) for u in team]
    complete = len(commits) == len(team)
    last_commit = max(t for t, _ in commits) if complete else None
    last_result = max(t for t, _ in results) if len(results) == len(team) else None
    model: int | None = 0
    fallback: int | None = 0
    for _, result in results:
        if result.model_times is not None and result.fallback_times is not None:
            model = None if model is None else model + result.model_times
            fallback = None if fallback is None else fallback + result.fallback_times
        else:
            model = fallback = None
    if model is None and all(s is not None for s in statuses):
        fallback = sum(s[1] for s in statuses if s is not None)
        model = len(team) * len(team) - fallback
    return Mission(
        send_to_commit=None if last_commit is None else last_commit - sent,
        result_to_commit=(
            None if last_commit is None or last_result is None else last_commit - last_result
        ),
        result_to_median_commit=(
            None
            if last_commit is None or last_result is None
            else statistics.median(t for t, _ in commits) - last_result
        ),
        model=model,
        fallback=fallback,
        agreed=complete and len({r.digest for _, r in commits}) == 1,
        cpu=cpu,
    )


def measure(config: Config, n: int, args: argparse.Namespace, workdir: Path) -> Row:
    scenario = workdir / f"ring-{n}.toml"
    scenario.write_text(ring_scenario(n))
    solve_s = uncontended_solve_s(n)
    budget = team_budget(n, solve_s) if config.team_budget else None
    onboard_args = config.onboard_args
    if budget is not None:
        onboard_args = (*onboard_args, "--budget", f"{budget:.2f}")
    spec = FleetSpec(
        scenario=str(scenario),
        listen=f"tcp/127.0.0.1:{args.port}",
        telemetry_hz=TELEMETRY_HZ,
        log_dir=workdir / f"{config.name}-{n}",
        start_timeout_s=args.start_timeout,
        onboard_args=onboard_args,
    )
    fleet = Fleet(spec)
    log: list[str] = []
    started = time.monotonic()
    with child_environment(config, workdir), fleet:
        ready = time.monotonic() - started
        assert fleet.router is not None
        session = fleet.router.session
        # The observer is a client of the router, as a ground is: its Python callbacks
        # run on the client's threads. On the router's own session they ran on the
        # routing threads, which then waited for this process's GIL before stamping
        # and routing the next sample (the last commit came ~100 ms later at N = 50).
        ground = zenoh.open(make_config("client", connect=[spec.listen]))
        observer = Observer(ground)
        try:
            models: float | None = None
            # The idle window starts once every model is built, where the UAVs say so
            # (`UavState.model_speed`): otherwise a build would count as idle CPU.
            if wait_models_built(session, set(fleet.uav_ids), args.start_timeout):
                models = time.monotonic() - started
            time.sleep(args.settle)
            pids = [child.pid for child in fleet.children]
            onboards = [c.pid for c in fleet.children if c.name.startswith("onboard-")]
            sim = next(c.pid for c in fleet.children if c.name == "sim")
            cpu0 = sum(cpu_seconds(pid) for pid in pids)
            sim0 = cpu_seconds(sim)
            own0 = time.process_time()
            observer.recording = True
            window0 = time.monotonic()
            time.sleep(args.idle)
            observer.recording = False
            window = time.monotonic() - window0
            cpu = 100.0 * (sum(cpu_seconds(pid) for pid in pids) - cpu0) / window
            sim_cpu = 100.0 * (cpu_seconds(sim) - sim0) / window
            own = 100.0 * (time.process_time() - own0) / window
            rss_idle = sum(status_field(pid, "VmRSS") for pid in pids) / 1024.0
            pss_idle = sum(pss_kb(pid) for pid in pids) / 1024.0
            threads = statistics.mean(status_field(pid, "Threads") for pid in onboards)
            team = tuple(sorted(fleet.uav_ids))
            deadline_s = 10.0 if budget is None else budget + 10.0
            missions = run_missions(
                session, observer, team, args.missions, deadline_s, (onboards, sim), log
            )
            rss_after = sum(status_field(pid, "VmRSS") for pid in pids) / 1024.0
            pss_after = sum(pss_kb(pid) for pid in pids) / 1024.0
        finally:
            observer.close()
            ground.close()
    return Row(
        n=n,
        config=config.name,
        ready_s=ready,
        models_s=models,
        cpu_pct=cpu,
        sim_cpu_pct=sim_cpu,
        ground_cpu_pct=own,
        rss_idle_mb=rss_idle,
        rss_after_mb=rss_after,
        pss_idle_mb=pss_idle,
        pss_after_mb=pss_after,
        threads=threads,
        latency_p99_ms=observer.latency_p99_ms(),
        missions=missions,
        solve_s=solve_s,
        budget_s=budget,
        defects=sum(
            path.read_text(errors="replace").count("approach model defect")
            for path in fleet.log_dir.glob("onboard-*.log")
        ),
    )


# ---- configurations and the table -----------------------------------------------------------
def baseline_tree(
    revision: str, workdir: Path, paths: tuple[str, ...] = ("fleet", "onboard")
) -> Path:
    """`paths` of this repository at `revision`, extracted (no checkout is touched); a
    path the revision does not have is left out (a package added or moved since)."""
    target = workdir / "baseline"
    target.mkdir()
    listed = subprocess.run(
        ["git", "-C", str(REPO), "ls-tree", "--name-only", revision, *paths],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", revision, *listed],
        check=True,
        capture_output=True,
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive, check=True)
    return target


def configs(names: list[str], baseline: str, workdir: Path) -> list[Config]:
    known = {
        "before": lambda: Config("before", pythonpath=baseline_tree(baseline, workdir)),
        "after": lambda: Config("after", team_budget=True),
        "after-2s": lambda: Config("after-2s"),
        "after-1hz": lambda: Config(
            "after-1hz", onboard_args=("--telemetry-hz", "1"), team_budget=True
        ),
    }
    unknown = [name for name in names if name not in known]
    if unknown:
        raise SystemExit(f"unknown configuration(s) {unknown}: expected {sorted(known)}")
    return [known[name]() for name in names]


def _range(values: list[float], scale: float, digits: int) -> str:
    if not values:
        return "-"
    low, high = min(values) * scale, max(values) * scale
    return f"{low:.{digits}f}" if math.isclose(low, high) else f"{low:.{digits}f}-{high:.{digits}f}"


def format_row(row: Row) -> str:
    sends = [m.send_to_commit for m in row.missions if m.send_to_commit is not None]
    consensus = [m.result_to_commit for m in row.missions if m.result_to_commit is not None]
    medians = [
        m.result_to_median_commit for m in row.missions if m.result_to_median_commit is not None
    ]
    answers = "/".join("?" if m.model is None else f"{m.model}:{m.fallback}" for m in row.missions)
    failed = sum(1 for m in row.missions if m.send_to_commit is None or not m.agreed)
    bound = row.n * row.solve_s / CORES + 0.5
    latency = "-" if row.latency_p99_ms is None else f"{row.latency_p99_ms:.0f}"
    models = "-" if row.models_s is None else f"{row.models_s:.1f}"
    return (
        f"{row.n:>3} {row.config:<9} {row.ready_s:>6.1f} {models:>6} {row.cpu_pct:>6.1f} "
        f"{row.sim_cpu_pct:>5.1f} "
        f"{row.ground_cpu_pct:>6.1f} {row.rss_idle_mb / 1024:>6.2f} "
        f"{row.rss_after_mb / 1024:>6.2f} {row.pss_idle_mb / 1024:>6.2f} "
        f"{row.pss_after_mb / 1024:>6.2f} "
        f"{row.threads:>5.1f} {latency:>6} {_range(sends, 1.0, 2):>10} {bound:>6.2f} "
        f"{_range(consensus, 1000.0, 0):>9} {_range(medians, 1000.0, 0):>9} {answers:>12} "
        f"{failed:>4} {row.defects:>4}"
    )


HEADER = (
    "  N config     ready  model    CPU   sim ground  RSS-i  RSS-m  PSS-i  PSS-m  thr/ tel-p99"
    "  send->com  bound"
    "  res->com  res->med  model:fallb fail  def\n"
    "                  s      s  %core %core  %core     GB     GB     GB     GB   onb      ms"
    "          s      s        ms        ms   (per msn)     "
)


CPU_COLUMNS = (
    ("planner", ("planner",)),
    ("link", ("link",)),
    ("main", ("python",)),
    ("zenoh", ("tx", "rx", "net", "app", "acc")),
    ("sim", ("sim",)),
    ("router", ("router",)),
)
CPU_HEADER = (
    "  N config    "
    + "".join(f"{name:>8}" for name, _ in CPU_COLUMNS)
    + "   other  (planner+other)/cores  send->com"
)


def format_cpu(row: Row) -> str:
    """Where a mission's CPU went from the send to the last commitment (CPU seconds, the
    mean of the missions): the planners' solves, and all the rest, which shares the cores
    with them; a previous release's unnamed threads all count as "main"."""
    missions = [m for m in row.missions if m.cpu and m.send_to_commit is not None]
    if not missions:
        return f"{row.n:>3} {row.config:<9} -"

    def mean(kinds: tuple[str, ...]) -> float:
        return statistics.mean(sum(m.cpu.get(k, 0.0) for k in kinds) for m in missions)

    cells = {name: mean(kinds) for name, kinds in CPU_COLUMNS}
    other = sum(cells.values()) - cells["planner"]
    send = statistics.mean(m.send_to_commit or 0.0 for m in missions)
    return (
        f"{row.n:>3} {row.config:<9} "
        + "".join(f"{cells[name]:>8.2f}" for name, _ in CPU_COLUMNS)
        + f"{other:>8.2f}  {(cells['planner'] + other) / CORES:>21.2f}  {send:>9.2f}"
    )


def ratios(before: Row, after: Row) -> str:
    def ratio(a: float | None, b: float | None) -> str:
        return "-" if a is None or b is None or b == 0 else f"{a / b:.2f}"

    def median(row: Row, attr: str) -> float | None:
        values = [getattr(m, attr) for m in row.missions if getattr(m, attr) is not None]
        return statistics.median(values) if values else None

    return (
        f"N={after.n} {after.config}/{before.config}: ready {ratio(after.ready_s, before.ready_s)}"
        f"  CPU {ratio(after.cpu_pct, before.cpu_pct)}"
        f"  RSS idle {ratio(after.rss_idle_mb, before.rss_idle_mb)}"
        f"  RSS after missions {ratio(after.rss_after_mb, before.rss_after_mb)}"
        f"  PSS idle {ratio(after.pss_idle_mb, before.pss_idle_mb)}"
        f"  telemetry p99 {ratio(after.latency_p99_ms, before.latency_p99_ms)}"
        f"  send->commit {ratio(median(after, 'send_to_commit'), median(before, 'send_to_commit'))}"
        "  result->commit "
        + ratio(median(after, "result_to_commit"), median(before, "result_to_commit"))
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 10, 20, 50])
    parser.add_argument("--configs", nargs="+", default=["before", "after"])
    parser.add_argument("--baseline", default="main", help="git revision run as `before`")
    parser.add_argument("--missions", type=int, default=2, help="missions per fleet")
    parser.add_argument("--idle", type=float, default=10.0, help="idle window, s")
    parser.add_argument("--settle", type=float, default=3.0, help="wait after ready, s")
    parser.add_argument("--start-timeout", type=float, default=180.0)
    parser.add_argument("--port", type=int, default=7461, help="the router's port")
    parser.add_argument(
        "--keep", type=Path, help="keep every fleet's logs in this folder (default: removed)"
    )
    parser.add_argument(
        "--whole-tree",
        action="store_true",
        help="run `fleet up --uavs N` whole (router, recorder, simulator, onboards) and "
        "measure each process kind (bench/fleet_tree.py)",
    )
    parser.add_argument("--repeat", type=int, default=1, help="--whole-tree: runs per N")
    args = parser.parse_args()
    if args.whole_tree:
        from bench import fleet_tree  # it imports this module's measures

        fleet_tree.run(args)
        return
    print(
        f"{CORES} cores; telemetry {TELEMETRY_HZ:g} Hz; M = N targets; bound = N x solve / "
        "cores + 0.5 s",
        flush=True,
    )
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as tmp:
        workdir = Path(tmp) if args.keep is None else args.keep
        workdir.mkdir(parents=True, exist_ok=True)
        chosen = configs(args.configs, args.baseline, workdir)
        print(HEADER, flush=True)
        for n in args.sizes:
            for config in chosen:
                row = measure(config, n, args, workdir)
                rows.append(row)
                print(format_row(row), flush=True)
    print()
    print("CPU seconds from the send to the last commitment, mean of the missions")
    print(CPU_HEADER)
    for row in rows:
        print(format_cpu(row))
    print()
    for n in args.sizes:
        of_n = {row.config: row for row in rows if row.n == n}
        if "before" in of_n:
            for name, row in of_n.items():
                if name != "before":
                    print(ratios(of_n["before"], row))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
