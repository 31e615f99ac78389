"""A partition campaign: missions flown while the team's network splits and heals, measured
from outside against the simulator's true positions.

Four UAVs (101-104), each a host of its own: a Linux network namespace holding its
simulated autopilot (`fleet sim --uav N --truth-log`), its onboard module and its own Zenoh
router. The ground (its router, `ground-cli`, and this script's observer session) is the
host's namespace. The routers are linked as `fleet up --topology router-per-uav` links them
(fleet.launch.topology): each UAV's router to the ground's and to the next UAV's on a ring,
each link one veth pair, so cutting a veth (link down: packets go nowhere, no reset, as a
radio out of range) cuts exactly that Zenoh link.

Each mission (8 targets, greedy, min-sum or min-max in turn) meets one fault, injected at
commit (right after the ground delivered the mission, while the UAVs agree) or mid-queue
(at the first target any UAV reaches):

* split 2|2 or 1|3 for 10, 30 or 60 s (the ground stays with 101's side);
* the ground's router frozen (SIGSTOP) for 15 s, or killed and restarted 15 s later.

The `star-` scenarios (`star-freeze-15-mid`, ...) fly the same missions on `fleet up`'s
default star topology instead: no UAV routers, every onboard (still in its namespace,
with its simulator) a client of the ground's router over its veth, the one router
everyone goes through. There the ground's router frozen or restarted (on the same port)
cuts every UAV from every other. Star and ring scenarios cannot share a run (the layout
is set up once per run).

Measured, per mission, from the simulators' truth logs (fleet.sim.truth_log): the targets
some UAV truly came within the reached radius of, those two UAVs flew, those none flew;
each onboard's "reached target N" claims (its log) that its own true track does not bear
out; and the seconds from the heal until every onboard's committed plan has one digest
again (each onboard asked for its assignment, every 0.5 s).

Needs root and `ip netns`. Every process started is stopped by PID and every namespace
deleted at the end, on Ctrl-C or an error too.

Run: sudo .venv/bin/python -m bench.bench_partition_campaign [--missions 24] [--speedup 5]
     [--scenarios split22-10-mid,freeze-15-commit] [--quick]
     sudo .venv/bin/python -m bench.bench_partition_campaign --missions 8 --scenarios \
     star-freeze-15-mid,star-freeze-15-commit,star-restart-15-mid,star-restart-15-commit
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import signal
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

import zenoh

from fleet.files.targets_io import write_targets
from fleet.launch.endpoints import free_port
from fleet.launch.ring import ring_scenario
from fleet.launch.topology import ring_links
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, Target
from fleet.mission.objective import Objective
from fleet.mission.target_checks import REACHED_RADIUS_M
from fleet.sim.truth_log import closest_approaches, read_truth
from fleet.transport.bus_codec import decode_json
from fleet.transport.zenoh_config import make_config
from tests.support.ground_cli import ground_cli
from tests.support.netns import check_ip, in_namespace, ip, namespaces_allowed
from tests.support.processes import Child, start
from tests.support.targets import ring_targets

UAVS = (101, 102, 103, 104)
TARGETS = 8
UAV_ROUTER_PORT = 7447
TAG = f"pc{os.getpid() % 100000}"  # interface names are <= 15 characters
#: How long a mission may fly, wall seconds from its send, before it is scored as it is.
MISSION_TIMEOUT_S = 240.0
#: How long after the heal the plans may take to agree again before "never" is scored.
CONVERGE_TIMEOUT_S = 90.0
OBJECTIVES = (Objective.GREEDY, Objective.MIN_SUM, Objective.MIN_MAX)


class Fault(StrEnum):
    SPLIT_2_2 = "split22"
    SPLIT_1_3 = "split13"
    FREEZE_GROUND = "freeze"
    RESTART_GROUND = "restart"


class Moment(StrEnum):
    COMMIT = "commit"
    MID_QUEUE = "mid"


#: The UAVs cut off from the ground's side by each split.
CUT_OFF = {Fault.SPLIT_2_2: (103, 104), Fault.SPLIT_1_3: (104,)}


@dataclass(frozen=True)
class Scenario:
    fault: Fault
    seconds: float
    moment: Moment
    #: fleet.launch.topology's star: every onboard a client of the ground's router.
    star: bool = False

    @property
    def name(self) -> str:
        prefix = "star-" if self.star else ""
        return f"{prefix}{self.fault}-{self.seconds:g}-{self.moment}"


def all_scenarios() -> list[Scenario]:
    splits = [
        Scenario(fault, seconds, moment)
        for fault in (Fault.SPLIT_2_2, Fault.SPLIT_1_3)
        for seconds in (10.0, 30.0, 60.0)
        for moment in (Moment.MID_QUEUE, Moment.COMMIT)
    ]
    ground = [
        Scenario(fault, 15.0, moment)
        for fault in (Fault.FREEZE_GROUND, Fault.RESTART_GROUND)
        for moment in (Moment.MID_QUEUE, Moment.COMMIT)
    ]
    star = [
        Scenario(fault, 15.0, moment, star=True)
        for fault in (Fault.FREEZE_GROUND, Fault.RESTART_GROUND)
        for moment in (Moment.MID_QUEUE, Moment.COMMIT)
    ]
    return splits + ground + star


QUICK = ("split22-10-mid", "freeze-15-commit", "split13-30-mid")


@dataclass
class Network:
    """The UAVs' namespaces and the veths of the Zenoh links: UAV-ground and the ring."""

    namespaces: dict[int, str] = field(default_factory=dict)
    #: (a, b) -> (namespace or "" for the host's, the interface on a's side); a=0: ground.
    links: dict[tuple[int, int], tuple[str, str]] = field(default_factory=dict)
    ground_address: dict[int, str] = field(default_factory=dict)  #: the ground's, UAV's side
    uav_address: dict[int, str] = field(default_factory=dict)  #: UAV's router, ground side
    ring_address: dict[tuple[int, int], str] = field(default_factory=dict)  #: b's, from a

    def set_links(self, up: bool, pairs: Sequence[tuple[int, int]]) -> None:
        for pair in pairs:
            namespace, device = self.links[pair]
            where = ("-n", namespace) if namespace else ()
            check_ip(ip(*where, "link", "set", device, "up" if up else "down"))

    def crossing(self, cut_off: Sequence[int]) -> list[tuple[int, int]]:
        """The links between the ground's side and `cut_off`'s."""
        side = set(cut_off)
        return [(a, b) for a, b in self.links if (a in side) != (b in side)]


@contextmanager
def network() -> Iterator[Network]:
    net = Network()
    try:
        for index, uav in enumerate(UAVS, 1):
            namespace = f"{TAG}-u{uav}"
            check_ip(ip("netns", "add", namespace))
            net.namespaces[uav] = namespace
            check_ip(ip("-n", namespace, "link", "set", "lo", "up"))
            near, far = f"{TAG}g{uav}", f"{TAG}x{uav}"
            check_ip(ip("link", "add", near, "type", "veth", "peer", "name", far,
                        "netns", namespace))  # fmt: skip
            net.ground_address[uav] = f"10.214.{index}.1"
            net.uav_address[uav] = f"10.214.{index}.2"
            check_ip(ip("addr", "add", f"{net.ground_address[uav]}/24", "dev", near))
            check_ip(ip("-n", namespace, "addr", "add", f"{net.uav_address[uav]}/24", "dev", far))
            check_ip(ip("link", "set", near, "up"))
            check_ip(ip("-n", namespace, "link", "set", far, "up"))
            net.links[(0, uav)] = ("", near)
        for index, (uav, nexts) in enumerate(ring_links(list(UAVS)).items(), 1):
            for other in nexts:
                a, b = f"{TAG}r{uav}a", f"{TAG}r{uav}b"
                check_ip(ip("link", "add", a, "netns", net.namespaces[uav], "type", "veth",
                            "peer", "name", b, "netns", net.namespaces[other]))  # fmt: skip
                check_ip(ip("-n", net.namespaces[uav], "addr", "add", f"10.215.{index}.1/24",
                            "dev", a))  # fmt: skip
                check_ip(ip("-n", net.namespaces[other], "addr", "add", f"10.215.{index}.2/24",
                            "dev", b))  # fmt: skip
                check_ip(ip("-n", net.namespaces[uav], "link", "set", a, "up"))
                check_ip(ip("-n", net.namespaces[other], "link", "set", b, "up"))
                net.links[(uav, other)] = (net.namespaces[uav], a)
                net.ring_address[(uav, other)] = f"10.215.{index}.2"
        yield net
    finally:
        for namespace in net.namespaces.values():  # deleting one deletes its veths' pairs
            ip("netns", "del", namespace)


@dataclass
class Fleet:
    net: Network
    workdir: Path
    speedup: float
    #: The star topology: no UAV routers, each onboard dials the ground's router.
    star: bool = False
    ground_port: int = field(default_factory=lambda: free_port("127.0.0.1"))
    children: list[Child] = field(default_factory=list)
    ground_router: Child | None = None
    onboards: dict[int, Child] = field(default_factory=dict)
    frozen: bool = False
    #: Where each mission's onboard output and the ground's view are kept (None: nowhere).
    logs: Path | None = None

    @property
    def ground_connect(self) -> list[str]:
        """The ground's router first, each UAV's router as a fallback (ring only)."""
        ground = f"tcp/127.0.0.1:{self.ground_port}"
        if self.star:
            return [ground]
        return [ground, *(f"tcp/{self.net.uav_address[u]}:{UAV_ROUTER_PORT}" for u in UAVS)]

    def ground_endpoint(self, uav: int) -> str:
        """The ground's router as UAV `uav`'s router dials it."""
        return f"tcp/{self.net.ground_address[uav]}:{self.ground_port}"

    def truth_path(self, uav: int) -> Path:
        return self.workdir / f"truth-{uav}.csv"

    def start_ground_router(self) -> None:
        port = self.ground_port
        listen = [
            f"tcp/127.0.0.1:{port}",
            *(f"tcp/{self.net.ground_address[u]}:{port}" for u in UAVS),
        ]
        argv = [sys.executable, "-m", "fleet.transport.router"]
        for endpoint in listen:
            argv += ["--listen", endpoint]
        router = start("router-ground", argv)
        self.children.append(router)
        router.wait_for_line(lambda line: line.startswith("router listening on"), 60.0)
        self.ground_router = router

    def start(self) -> None:
        scenario = self.workdir / "ring4.toml"
        scenario.write_text(ring_scenario(len(UAVS)))
        self.start_ground_router()
        nexts = ring_links(list(UAVS))
        for uav in UAVS:
            namespace = self.net.namespaces[uav]
            # The onboard's router: its UAV's own on the ring, the ground's on the star.
            router = self.ground_endpoint(uav) if self.star else f"tcp/127.0.0.1:{UAV_ROUTER_PORT}"
            if not self.star:
                argv = [sys.executable, "-m", "fleet.transport.router",
                        "--listen", f"tcp/0.0.0.0:{UAV_ROUTER_PORT}",
                        "--connect", self.ground_endpoint(uav)]  # fmt: skip
                for other in nexts[uav]:
                    argv += [
                        "--connect",
                        f"tcp/{self.net.ring_address[(uav, other)]}:{UAV_ROUTER_PORT}",
                    ]
                self.children.append(start(f"router-{uav}", in_namespace(namespace, *argv)))
            sim = start(f"sim {uav}", in_namespace(namespace, sys.executable, "-m",
                "fleet.sim.command", str(scenario), "--uav", str(uav), "--speedup",
                f"{self.speedup:g}", "--telemetry-hz", "5",
                "--truth-log", str(self.truth_path(uav))))  # fmt: skip
            self.children.append(sim)
            sim.wait_for_line(lambda line: line == "ready", 60.0)
            onboard = start(f"onboard {uav}", in_namespace(namespace, sys.executable, "-m",
                "onboard.main", "--id", str(uav), "--program", "socket://127.0.0.1:5760",
                "--payload", "socket://127.0.0.1:5860",
                "--connect", router))  # fmt: skip
            self.children.append(onboard)
            self.onboards[uav] = onboard

    def stop(self) -> None:
        if self.frozen and self.ground_router is not None:
            os.kill(self.ground_router.pid, signal.SIGCONT)
        for child in reversed(self.children):
            child.stop()

    def ground(self, *argv: str, timeout: float = 90.0) -> tuple[int, str, str]:
        done = ground_cli(*argv, connect=self.ground_connect, timeout=timeout)
        return done.returncode, done.stdout, done.stderr


@dataclass
class Marks:
    """Where each truth log and each onboard's output stood when the mission began."""

    truth: dict[int, int]
    output: dict[int, int]


def marks(fleet: Fleet) -> Marks:
    return Marks(
        {u: fleet.truth_path(u).stat().st_size for u in UAVS},
        {u: len(fleet.onboards[u].history) for u in UAVS},
    )


def truth_since(fleet: Fleet, mark: Marks, targets: Sequence[Target]) -> dict[int, list[float]]:
    """UAV -> its true closest approach to each target since `mark`."""
    samples = []
    for uav in UAVS:
        with fleet.truth_path(uav).open(encoding="utf-8") as file:
            file.seek(mark.truth[uav])
            samples += read_truth(file.read().splitlines(), str(fleet.truth_path(uav)))
    return closest_approaches(samples, [(t.lat, t.lon) for t in targets])


def keep_logs(fleet: Fleet, mark: Marks, directory: Path) -> None:
    """Each onboard's output since `mark`, and its truth log, into `directory`."""
    directory.mkdir(parents=True, exist_ok=True)
    for uav in UAVS:
        lines = fleet.onboards[uav].history[mark.output[uav] :]
        (directory / f"onboard-{uav}.log").write_text("\n".join(lines) + "\n")
        with fleet.truth_path(uav).open(encoding="utf-8") as file:
            file.seek(mark.truth[uav])
            (directory / f"truth-{uav}.csv").write_text(file.read())


def claims_since(fleet: Fleet, mark: Marks) -> list[tuple[int, int]]:
    """(UAV, target) for each "reached target N" its onboard logged since `mark`."""
    found = []
    for uav in UAVS:
        for line in fleet.onboards[uav].history[mark.output[uav] :]:
            _, sep, tail = line.partition("reached target ")
            if sep and tail.split(" ", 1)[0].isdigit():
                found.append((uav, int(tail.split(" ", 1)[0])))
    return found


def plans(session: zenoh.Session, mission: int) -> dict[int, AssignmentReport]:
    """UAV -> the plan it has committed for `mission`, from each that answers."""
    found: dict[int, AssignmentReport] = {}
    key = KeySpace().mission_assignments(mission)
    for reply in session.get(key, timeout=2.0):
        if reply.ok is None:
            continue
        sample = reply.ok
        try:
            report = decode_json(sample.payload.to_bytes(), AssignmentReport, str(sample.key_expr))
        except Exception:  # a reply we cannot read is no agreement
            continue
        found[report.uav] = report
    return found


def describe(held: dict[int, AssignmentReport]) -> str:
    """Each UAV's plan in a few characters: its epoch, digest and the team it used."""
    return ", ".join(
        f"{u} epoch {p.epoch} {p.digest[:8]} of {'+'.join(map(str, p.team))}"
        for u, p in sorted(held.items())
    )


@dataclass
class Score:
    scenario: str
    objective: str
    mission: int
    reached: int = 0
    twice: int = 0
    never: list[int] = field(default_factory=list)
    claims: int = 0
    false_claims: int = 0
    converge_s: float | None = None
    #: The epoch of the plan every onboard holds once they agree again (0: never re-planned).
    epoch: int = 0
    fleet_reached: int = 0
    note: str = ""


def wait_first_claim(fleet: Fleet, mark: Marks, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if claims_since(fleet, mark):
            return True
        time.sleep(0.2)
    return False


def inject(fleet: Fleet, scenario: Scenario) -> float:
    """Apply the fault, wait it out, heal; the monotonic time of the heal."""
    if scenario.fault in CUT_OFF:
        crossing = fleet.net.crossing(CUT_OFF[scenario.fault])
        fleet.net.set_links(False, crossing)
        try:
            time.sleep(scenario.seconds)
        finally:
            fleet.net.set_links(True, crossing)
        return time.monotonic()
    router = fleet.ground_router
    assert router is not None
    if scenario.fault is Fault.FREEZE_GROUND:
        os.kill(router.pid, signal.SIGSTOP)
        fleet.frozen = True
        try:
            time.sleep(scenario.seconds)
        finally:
            os.kill(router.pid, signal.SIGCONT)
            fleet.frozen = False
        return time.monotonic()
    router.kill()
    fleet.children.remove(router)
    time.sleep(scenario.seconds)
    fleet.start_ground_router()
    return time.monotonic()


def fly(
    fleet: Fleet, session: zenoh.Session, scenario: Scenario, objective: Objective, seed: int
) -> Score:
    targets = ring_targets(TARGETS, seed=seed)
    path = fleet.workdir / f"targets-{seed}.bin"
    write_targets(path, targets)
    mark = marks(fleet)
    started = time.monotonic()
    status, out, err = fleet.ground("send-targets", str(path), "--json", "--objective",
                                    str(objective), "--team", ",".join(map(str, UAVS)),
                                    "--force")  # fmt: skip
    if status != 0:
        raise RuntimeError(f"send-targets failed ({status}): {err[-2000:]}")
    mission = int(json.loads(out)["mission"])
    score = Score(scenario.name, str(objective), mission)
    if scenario.moment is Moment.MID_QUEUE and not wait_first_claim(fleet, mark, 120.0):
        score.note = "no target reached before the fault; injected anyway. "
    healed = inject(fleet, scenario)
    held: dict[int, AssignmentReport] = {}
    while time.monotonic() - healed < CONVERGE_TIMEOUT_S:
        held = plans(session, mission)
        if set(held) == set(UAVS) and len({p.digest for p in held.values()}) == 1:
            score.converge_s = time.monotonic() - healed
            score.epoch = held[UAVS[0]].epoch
            break
        time.sleep(0.5)
    else:
        score.note += f"plans held: {describe(held)}. "
    # Flown until every target is truly reached, or the mission's time is up.
    while time.monotonic() - started < MISSION_TIMEOUT_S:
        nearest = truth_since(fleet, mark, targets)
        if all(any(n[t] <= REACHED_RADIUS_M for n in nearest.values()) for t in range(TARGETS)):
            break
        time.sleep(2.0)
    time.sleep(2.0)  # the last claims' lines
    if fleet.logs is not None:
        keep_logs(fleet, mark, fleet.logs / f"mission-{mission}-{scenario.name}")
    nearest = truth_since(fleet, mark, targets)
    flown = {t: [u for u, n in nearest.items() if n[t] <= REACHED_RADIUS_M] for t in range(TARGETS)}
    score.reached = sum(1 for uavs in flown.values() if uavs)
    score.twice = sum(1 for uavs in flown.values() if len(uavs) > 1)
    score.never = [t for t, uavs in flown.items() if not uavs]
    claims = claims_since(fleet, mark)
    score.claims = len(claims)
    score.false_claims = sum(
        1 for uav, t in claims if nearest.get(uav, [1e9] * TARGETS)[t] > REACHED_RADIUS_M
    )
    status, out, _ = fleet.ground("mission", "--mission", str(mission), "--json")
    if fleet.logs is not None:
        (fleet.logs / f"mission-{mission}-{scenario.name}" / "mission.json").write_text(out)
    if status in (0, 1) and out.strip():
        report = json.loads(out)
        states = report.get("target_states", [])
        score.fleet_reached = sum(1 for s in states if s["state"] == "reached")
        unserved = {s["index"]: s.get("reason") for s in states if s["state"] != "reached"}
        if score.never:
            score.note += f"fleet says of those never flown: {unserved}"
    return score


HEADER = (
    f"{'mission':>7} {'scenario':<22} {'objective':<8} {'reached':>7} {'twice':>5} "
    f"{'never':>5} {'false/claims':>12} {'converge s':>10} {'epoch':>5} {'fleet says':>10}"
)


def row(s: Score) -> str:
    converge = f"{s.converge_s:.1f}" if s.converge_s is not None else "never"
    return (
        f"{s.mission:>7} {s.scenario:<22} {s.objective:<8} {s.reached:>5}/{TARGETS} "
        f"{s.twice:>5} {len(s.never):>5} {s.false_claims:>5}/{s.claims:<6} "
        f"{converge:>10} {s.epoch:>5} {s.fleet_reached:>8}/{TARGETS}  {s.note}"
    )


def totals(scores: Sequence[Score]) -> str:
    converged = sorted(s.converge_s for s in scores if s.converge_s is not None)
    spread = (
        f" (median {converged[len(converged) // 2]:.1f} s, max {converged[-1]:.1f} s)"
        if converged
        else ""
    )
    return (
        f"totals: {len(scores)} missions, {sum(s.reached for s in scores)}/"
        f"{TARGETS * len(scores)} targets truly reached, "
        f"{sum(s.twice for s in scores)} flown twice, "
        f"{sum(len(s.never) for s in scores)} never flown, "
        f"{sum(s.false_claims for s in scores)} false of {sum(s.claims for s in scores)} "
        f"'reached' claims; plans one again after the heal in "
        f"{len(converged)}/{len(scores)}{spread}"
    )


def _stop_on_sigterm() -> None:
    def handler(signum: int, _frame: object) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, handler)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--missions", type=int, default=24, help="missions in all (%(default)s)")
    parser.add_argument("--speedup", type=float, default=5.0, help="simulated s per wall s")
    parser.add_argument("--scenarios", help="comma-separated names (default: every one): "
                        + ", ".join(s.name for s in all_scenarios()))  # fmt: skip
    parser.add_argument("--quick", action="store_true", help=f"a smoke run: {', '.join(QUICK)}")
    parser.add_argument("--logs", type=Path, help="keep each mission's onboard logs here")
    args = parser.parse_args(argv)
    reason = namespaces_allowed(TAG)
    if reason is not None:
        print(f"cannot run: {reason}", file=sys.stderr)
        return 2
    known = {s.name: s for s in all_scenarios()}
    names = QUICK if args.quick else (args.scenarios.split(",") if args.scenarios else list(known))
    unknown = [n for n in names if n not in known]
    if unknown:
        print(f"unknown scenarios {unknown}: expected some of {list(known)}", file=sys.stderr)
        return 2
    layouts = {known[n].star for n in names}
    if len(layouts) > 1:
        print("star- and ring scenarios cannot share a run: run them apart", file=sys.stderr)
        return 2
    count = len(names) if args.quick else args.missions
    plan = list(itertools.islice(itertools.cycle(names), count))
    _stop_on_sigterm()
    scores: list[Score] = []
    with tempfile.TemporaryDirectory(prefix="partition-") as tmp, network() as net:
        fleet = Fleet(net, Path(tmp), args.speedup, star=layouts == {True}, logs=args.logs)
        try:
            fleet.start()
            with zenoh.open(make_config(connect=fleet.ground_connect)) as session:
                wait_all_live(fleet)
                print(HEADER, flush=True)
                for number, name in enumerate(plan):
                    objective = OBJECTIVES[number % len(OBJECTIVES)]
                    score = fly(fleet, session, known[name], objective, seed=100 + number)
                    scores.append(score)
                    print(row(score), flush=True)
        finally:
            fleet.stop()
    print(totals(scores))
    return 0


def wait_all_live(fleet: Fleet, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        status, out, _ = fleet.ground("uavs", "--json")
        if status == 0:
            rows = {row["id"]: row for row in json.loads(out)}
            if set(rows) >= set(UAVS) and all(rows[u]["lat"] is not None for u in UAVS):
                return
        time.sleep(1.0)
    raise RuntimeError("the UAVs never all came up")


if __name__ == "__main__":
    sys.exit(main())
