"""One mission's burst as one UAV absorbs it: the CPU the consensus step costs per UAV.

At N UAVs every onboard process receives N-1 teammates' results and N-1 assignment
reports per mission, and all N processes absorb them at once on the same cores: what
each spends decides the fleet's "last result -> last commit". This runs one real
`OnboardProcess` (its Zenoh node's decoders, its main loop's event handling, the core)
on a bus that only hands it bytes: no Zenoh, no threads, no planner. Per burst (one
new mission of N targets, the UAV's own result already published):

* results in: the N-1 teammates' results arrive as bytes, through the node's
  subscription callback and the main loop's event handler;
* commit: then one tick commits (the plan, the digest, the report published, i.e.
  encoded, the waypoint handed to the autopilot link): what each UAV spends between the
  last result and its commitment, the consensus window's share per UAV (times N over
  the cores). Its parts, each this thread's CPU in the function the code calls
  (`Meter`; nested, so they do not add up): `MissionRound.decide` and, within it, the
  target-to-target legs (`leg_times`, 0 where the mission's arrival computed them), the
  queues (`plan_queues`), the digests; `publish` (every message the tick encodes and
  puts) and `autopilot` (the waypoint handed to the link);
* reports: the N-1 teammates' assignment reports of that mission (the same pairs and
  digest, as the ground sees them) arrive after this UAV committed; 0 where the onboard
  does not subscribe to them (since teammates hear re-plans only, on their own key).

CPU is this thread's CPU time (`time.thread_time`), per burst; each round runs
`--bursts` bursts and keeps their median, and the rounds' range is printed. Also timed
at N=50 (median of `--calls` calls): the legs, the greedy, the queues, the digest and
`MissionRound.decide` (its legs computed beforehand). No signature is checked or made:
`fleet up` runs the open profile unless `--secure` (then docs/benchmarks.md, "Signed
commands", gives each message's cost).

`--baseline REV` runs this same script against revision REV (default none) from a
temporary folder (`git archive`) in the same run, alternating with this tree round by round,
and prints after/before ratios of the medians.

Run: .venv/bin/python -m bench.bench_burst [--sizes 20 50] [--bursts 30] [--rounds 4]
     [--baseline main]
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import cast

import msgspec

from bench.bench_fleet_scale import baseline_tree
from fleet.consensus import mission_round
from fleet.consensus.assignment import greedy_assign, results_digest
from fleet.consensus.legs import leg_times
from fleet.consensus.mission_round import MissionRound
from fleet.consensus.objectives import plan_queues
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, UavResult
from fleet.piccolo.track import Track
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusQuery, BusReply, BusSample, Declaration, Queryable
from fleet.transport.memory import memory_link_pair
from onboard.bus_edge import PresenceEvent
from onboard.planner.planner_worker import PlanRequest, PlanResult
from onboard.process import OnboardProcess, OnboardSettings
from tests.support.link_samples import sample_telemetry
from tests.support.targets import ring_targets

SPACE = KeySpace()

#: The UAV measured; its teammates are 2..N (Piccolo IDs 1..N).
OWN = 1
SEED = 14


# ---- a bus that only hands bytes over ---------------------------------------------------
class _Nothing(Declaration):
    def undeclare(self) -> None:
        pass


class _NoQueries(Queryable):
    def try_recv(self) -> BusQuery | None:
        return None

    def undeclare(self) -> None:
        pass


class BytesBus(Bus):
    """Subscriptions by key expression; a publication is encoded (as on Zenoh), kept."""

    def __init__(self) -> None:
        self.subscriptions: dict[str, Callable[[BusSample], None]] = {}
        self.published: list[tuple[str, bytes]] = []

    def put(self, key: str, payload: bytes) -> None:
        self.published.append((key, payload))

    def subscribe(
        self, key_expr: str, callback: Callable[[BusSample], None], *, details: bool = False
    ) -> Declaration:
        self.subscriptions[key_expr] = callback
        return _Nothing()

    def get(
        self,
        selector: str,
        callback: Callable[[BusSample], None],
        timeout: float,
        payload: bytes = b"",
    ) -> None:
        pass

    def query(
        self, selector: str, timeout: float, payload: bytes = b"", *, every_reply: bool = False
    ) -> list[BusReply]:
        return []

    def declare_queryable(
        self, key_expr: str, notify: Callable[[], None] | None = None
    ) -> Queryable:
        return _NoQueries()

    def declare_token(self, key: str) -> Declaration:
        return _Nothing()

    def live_tokens(self, key_expr: str, timeout: float) -> list[str]:
        return []

    def subscribe_presence(
        self, key_expr: str, callback: Callable[[str, bool], None]
    ) -> Declaration:
        return _Nothing()

    def close(self) -> None:
        pass


class _InstantPlanner:
    """Answers every request at once with the times it is given."""

    def __init__(self) -> None:
        self.times: tuple[float, ...] = ()
        self._done: PlanResult | None = None

    def run(self, request: PlanRequest) -> bool:
        n = len(request.targets)
        self._done = PlanResult(request, self.times[:n], (False,) * n, 0.01)
        return True

    def result(self) -> PlanResult | None:
        done, self._done = self._done, None
        return done


# ---- one mission's traffic --------------------------------------------------------------
def _times(rng: random.Random, n: int) -> tuple[float | None, ...]:
    # Full-precision floats as the planner yields them: a time for every target (the
    # Dubins fallback answers where the model did not).
    return tuple(rng.uniform(40.0, 400.0) for _ in range(n))


def mission_traffic(
    n: int, mission: int
) -> tuple[bytes, list[tuple[str, bytes]], list[tuple[str, bytes]], tuple[float | None, ...]]:
    """The mission's targets, the teammates' results and reports (as bytes), own times."""
    rng = random.Random(SEED * 1_000_003 + mission * 101 + n)
    team = tuple(range(1, n + 1))
    targets = MissionTargets(mission, team, ring_targets(n, seed=mission), deadline_s=30.0)
    results = {uav: UavResult(mission, uav, _times(rng, n), n, 0) for uav in team}
    consensus = MissionRound(targets, OWN, 0.0)
    for result in results.values():
        consensus.add_result(result)
    decided = consensus.decide(set(team))
    reports = []
    for uav in team[1:]:
        target = decided.pairs.get(uav)
        times = results[uav].times
        report = msgspec.structs.replace(
            decided,
            uav=uav,
            target=target,
            eta_s=times[target] if target is not None else None,
        )
        reports.append((SPACE.mission_assignment(mission, uav), bus_codec.encode(report)))
    result_bytes = [
        (SPACE.mission_result(mission, uav), bus_codec.encode(results[uav])) for uav in team[1:]
    ]
    return bus_codec.encode(targets), result_bytes, reports, results[OWN].times


class Meter:
    """This thread's CPU (s) in named functions, counted only while `active` (a burst's
    results + commit), wrapped where the code under test looks them up: the parts of
    the burst, found the same way in this tree and in a baseline's."""

    def __init__(self) -> None:
        self.active = False
        self.spent: dict[str, float] = dict.fromkeys(PARTS, 0.0)
        self._undo: list[tuple[object, str, object]] = []

    def wrap(self, owner: object, name: str, part: str) -> None:
        """Count `owner.name`'s CPU under `part` (skipped where this tree has no such name)."""
        inner = getattr(owner, name, None)
        if inner is None:
            return
        meter = self

        def timed(*args: object, **kwargs: object) -> object:
            if not meter.active:
                return inner(*args, **kwargs)
            start = time.thread_time()
            try:
                return inner(*args, **kwargs)
            finally:
                meter.spent[part] += time.thread_time() - start

        self._undo.append((owner, name, inner))
        setattr(owner, name, timed)

    def take(self) -> dict[str, float]:
        spent, self.spent = self.spent, dict.fromkeys(PARTS, 0.0)
        return spent

    def close(self) -> None:
        for owner, name, inner in reversed(self._undo):
            setattr(owner, name, inner)


#: The commit's parts: `decide` holds legs, queues and digest; `publish` is every
#: message the tick encodes and puts (the report, the status); `autopilot` the waypoint
#: handed to the link. Nested parts are not subtracted from their caller.
PARTS = ("decide", "legs", "queues", "digest", "publish", "autopilot")


def _metered(process: OnboardProcess) -> Meter:
    """A meter on the commit's parts, looked up by name as the code under test calls them."""
    meter = Meter()
    meter.wrap(MissionRound, "decide", "decide")
    meter.wrap(mission_round, "leg_times", "legs")
    meter.wrap(mission_round, "plan_queues", "queues")
    meter.wrap(mission_round, "results_digest", "digest")
    meter.wrap(mission_round, "plan_digest", "digest")
    meter.wrap(process.node, "publish", "publish")
    meter.wrap(process.link, "send_autopilot", "autopilot")
    return meter


def measure_bursts(n: int, bursts: int, first_mission: int) -> dict[str, list[float]]:
    """Per burst, this thread's CPU (s): the results in, the commit (and its parts), the
    reports."""
    bus = BytesBus()
    link_a, _ = memory_link_pair("program")
    link_b, _ = memory_link_pair("payload")
    process = OnboardProcess(
        OnboardSettings(uav_id=OWN, program_url="", payload_url=""),
        links=(link_a, link_b),
        bus=bus,
    )
    planner = _InstantPlanner()
    core = process.core
    # The approach times come from `planner` at once: the plan asks the one it holds.
    core.planner = core.mission.plan.planner = planner
    core.status_rate_hz = 0.0  # the periodic state is not the burst's
    meter = _metered(process)
    try:
        now = time.monotonic()
        core.on_telemetry(sample_telemetry(), now)
        core.on_track(Track(2), now)
        for uav in range(2, n + 1):
            process._on_event(PresenceEvent(uav, True), now)
        on_targets = bus.subscriptions[SPACE.all_mission_targets]
        on_result = bus.subscriptions[SPACE.all_mission_results]
        # None since the onboard hears its teammates' re-plans only (a baseline may).
        on_report = bus.subscriptions.get(SPACE.all_mission_assignments)
        events = process.events
        handle = process._on_event
        figures: dict[str, list[float]] = {
            name: [] for name in ("results in", "commit", *PARTS, "reports")
        }
        traffic = [mission_traffic(n, first_mission + i) for i in range(bursts)]
        for mission_index, (targets, results, reports, own_times) in enumerate(traffic):
            mission = first_mission + mission_index
            # The own result as the teammates' reports counted it (None included).
            planner.times = cast(tuple[float, ...], own_times)
            now = time.monotonic()
            on_targets(BusSample(SPACE.mission_targets(mission), targets))
            handle(events.get_nowait(), now)
            core.tick(now)  # the own result, published
            assert core.round is not None and OWN in core.round.results
            assert core.round.committed is None, "committed before the teammates' results"

            start = time.thread_time()
            for key, payload in results:
                on_result(BusSample(key, payload))
                handle(events.get_nowait(), now)
            received = time.thread_time()
            meter.active = True
            core.tick(now)
            meter.active = False
            committed_at = time.thread_time()
            for key, payload in reports:
                if on_report is not None:
                    on_report(BusSample(key, payload))
                while not events.empty():  # none if the node dropped it on its header
                    handle(events.get_nowait(), now)
            end = time.thread_time()

            committed = core.round.committed
            heard = msgspec.json.decode(reports[0][1], type=AssignmentReport)
            assert committed is not None and committed.digest == heard.digest
            figures["results in"].append(received - start)
            figures["commit"].append(committed_at - received)
            for part, spent in meter.take().items():
                figures[part].append(spent)
            figures["reports"].append(end - committed_at)
            bus.published.clear()
        return figures
    finally:
        meter.close()
        process.planner.close()


def time_calls(calls: int) -> dict[str, float]:
    """Median seconds per call, N=50 x 50 targets: the legs, the greedy, the queues, the
    digest, and `MissionRound.decide` with the legs already computed (as the mission's
    arrival computes them where the code does so; a baseline's decide would otherwise be
    charged for them twice)."""
    n = 50
    rng = random.Random(SEED)
    team = tuple(range(1, n + 1))
    results = {uav: UavResult(1, uav, _times(rng, n)) for uav in team}
    rows = {uav: r.times for uav, r in results.items()}
    targets = MissionTargets(1, team, ring_targets(n, seed=1))
    legs = leg_times(targets.targets)

    def fresh_round() -> Callable[[], object]:
        consensus = MissionRound(targets, OWN, 0.0)
        for result in results.values():
            consensus.add_result(result)
        assert len(consensus.legs) == n
        return lambda: consensus.decide(set(team))

    timed: dict[str, Callable[[], Callable[[], object]]] = {
        "legs": lambda: lambda: leg_times(targets.targets),
        "greedy": lambda: lambda: greedy_assign(rows, n),
        "queues": lambda: lambda: plan_queues(rows, legs),
        "digest": lambda: lambda: results_digest(rows),
        "decide": fresh_round,
    }
    figures = {}
    for name, setup in timed.items():
        samples = []
        for _ in range(calls):
            call = setup()
            start = time.thread_time()
            call()
            samples.append(time.thread_time() - start)
        figures[name] = statistics.median(samples)
    return figures


def run_round(sizes: list[int], bursts: int, calls: int) -> dict[str, float]:
    """One round: the median per burst of each figure, and the calls' medians (s)."""
    figures: dict[str, float] = {}
    for n in sizes:
        of_n = measure_bursts(n, bursts, first_mission=1)
        both = [a + b for a, b in zip(of_n["results in"], of_n["commit"], strict=True)]
        figures[f"N={n} results+commit"] = statistics.median(both)
        figures[f"N={n} {n - 1} results in"] = statistics.median(of_n["results in"])
        figures[f"N={n} commit"] = statistics.median(of_n["commit"])
        for part in PARTS:
            figures[f"N={n}  {part}"] = statistics.median(of_n[part])
        figures[f"N={n} {n - 1} reports"] = statistics.median(of_n["reports"])
    figures.update(time_calls(calls))
    return figures


# ---- the baseline and the table -------------------------------------------------------------
class Baseline:
    """This script run against another revision, extracted to a temporary folder."""

    def __init__(self, revision: str) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="bench-burst-"))
        self.tree = baseline_tree(revision, self.tmp, ("fleet", "onboard", "tests", "bench"))
        shutil.copy(Path(__file__), self.tree / "bench" / "bench_burst.py")

    def round(self, args: argparse.Namespace) -> dict[str, float]:
        command = [
            sys.executable,
            "-m",
            "bench.bench_burst",
            "--json",
            "--rounds",
            "1",
            "--bursts",
            str(args.bursts),
            "--calls",
            str(args.calls),
            "--sizes",
            *map(str, args.sizes),
        ]
        out = subprocess.run(
            command,
            cwd=self.tree,
            env={"PYTHONPATH": str(self.tree), "PATH": "/usr/bin:/bin"},
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        figures: dict[str, float] = json.loads(out.splitlines()[-1])
        return figures

    def close(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


def _unit(name: str) -> tuple[float, str]:
    return (1e3, "ms") if name.startswith("N=") else (1e6, "us")


def _span(values: list[float], scale: float) -> str:
    low, high = min(values) * scale, max(values) * scale
    return f"{statistics.median(values) * scale:8.3f} ({low:.3f}-{high:.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 50])
    parser.add_argument("--bursts", type=int, default=30, help="missions per round and N")
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--calls", type=int, default=200, help="calls per timed function")
    parser.add_argument("--baseline", default=None, help="git revision run as `before`")
    parser.add_argument("--json", action="store_true", help="one round's figures as JSON")
    args = parser.parse_args()
    if args.json:
        print(json.dumps(run_round(args.sizes, args.bursts, args.calls)))
        return
    baseline = Baseline(args.baseline) if args.baseline else None
    after: list[dict[str, float]] = []
    before: list[dict[str, float]] = []
    try:
        for index in range(args.rounds):
            # Alternate, so that the machine's other load falls on both alike.
            if baseline is not None:
                before.append(baseline.round(args))
            after.append(run_round(args.sizes, args.bursts, args.calls))
            print(f"round {index + 1}/{args.rounds} done", file=sys.stderr, flush=True)
    finally:
        if baseline is not None:
            baseline.close()
    print(
        f"CPU per UAV per burst (median of {args.bursts} bursts; median of {args.rounds} "
        "rounds, range)"
    )
    header = f"{'':24} {'after':>26}"
    if before:
        header += f" {'before (' + str(args.baseline) + ')':>26} {'after/before':>12}"
    print(header)
    for name in after[0]:
        scale, unit = _unit(name)
        line = f"{name + ' ' + unit:24} {_span([f[name] for f in after], scale):>26}"
        if before:
            old = [f[name] for f in before]
            ratio = statistics.median(f[name] for f in after) / statistics.median(old)
            line += f" {_span(old, scale):>26} {ratio:12.2f}"
        print(line)


if __name__ == "__main__":
    main()
