"""Hosts that are really apart: each UAV (its simulated autopilot and its onboard) in its
own network namespace, the ground (router and ground-cli) in another, joined by one veth
pair per UAV with addresses inside the namespaces only. With the fleet flying its first
mission, one UAV's veth is cut (its link goes silent, as a radio out of range does);
the next mission names it still (its token lives until its lease ends): the survivors
commit without it and fly to their targets, and the ground reports the partition.

Needs root and `ip netns` (iproute2); skipped with the reason where not allowed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from fleet.files.targets_io import write_targets
from fleet.launch.ring import ring_scenario
from tests.support.ground_cli import ground_cli
from tests.support.netns import check_ip, in_namespace, ip, namespaces_allowed
from tests.support.processes import Child, start
from tests.support.targets import ring_targets

pytestmark = pytest.mark.e2e

UAVS = (101, 102, 103)
VICTIM = 103
ROUTER_PORT = 7447
DEADLINE_S = 8.0
TAG = f"f{os.getpid() % 100000}"  # unique per test run; interface names are <= 15 chars


@dataclass
class Network:
    ground: str
    uavs: dict[int, str]  #: UAV id -> its namespace
    made: list[str] = field(default_factory=list)

    def ground_side(self, uav: int) -> str:
        return f"{TAG}g{uav}"

    def router_address(self, uav: int) -> str:
        return f"10.211.{uav}.1"

    def run(self, namespace: str, *argv: str) -> list[str]:
        return in_namespace(namespace, *argv)


@pytest.fixture
def network() -> Iterator[Network]:
    reason = namespaces_allowed(TAG)
    if reason is not None:
        pytest.skip(reason)
    net = Network(f"{TAG}-ground", {uav: f"{TAG}-uav{uav}" for uav in UAVS})
    try:
        for namespace in (net.ground, *net.uavs.values()):
            check_ip(ip("netns", "add", namespace))
            net.made.append(namespace)
            check_ip(ip("-n", namespace, "link", "set", "lo", "up"))
        for uav, namespace in net.uavs.items():
            near, far = net.ground_side(uav), f"{TAG}u{uav}"
            check_ip(ip("link", "add", near, "netns", net.ground, "type", "veth",
                      "peer", "name", far, "netns", namespace))  # fmt: skip
            check_ip(
                ip("-n", net.ground, "addr", "add", f"{net.router_address(uav)}/24", "dev", near)
            )
            check_ip(ip("-n", namespace, "addr", "add", f"10.211.{uav}.2/24", "dev", far))
            check_ip(ip("-n", net.ground, "link", "set", near, "up"))
            check_ip(ip("-n", namespace, "link", "set", far, "up"))
        yield net
    finally:
        for namespace in net.made:  # deleting a namespace deletes its veth ends too
            ip("netns", "del", namespace)


@pytest.fixture
def children() -> Iterator[list[Child]]:
    started: list[Child] = []
    try:
        yield started
    finally:
        for child in reversed(started):
            child.stop()


def start_uav(net: Network, uav: int, scenario: Path, children: list[Child]) -> None:
    namespace = net.uavs[uav]
    sim_argv = [sys.executable, "-m", "fleet.sim.command", str(scenario), "--uav", str(uav),
                "--speedup", "5", "--telemetry-hz", "5"]  # fmt: skip
    sim = start(f"sim {uav}", net.run(namespace, *sim_argv))
    children.append(sim)
    sim.wait_for_line(lambda line: line == "ready", 60.0)
    router = f"tcp/{net.router_address(uav)}:{ROUTER_PORT}"
    children.append(start(f"onboard {uav}", net.run(namespace, sys.executable, "-m",
        "onboard.main", "--id", str(uav), "--program", "socket://127.0.0.1:5760",
        "--payload", "socket://127.0.0.1:5860", "--connect", router)))  # fmt: skip


def ground(net: Network, *argv: str, timeout: float) -> subprocess.CompletedProcess[str]:
    """`ground-cli ARGV` in the ground's namespace, against its router."""
    return ground_cli(
        *argv, connect=f"tcp/127.0.0.1:{ROUTER_PORT}", timeout=timeout, prefix=net.run(net.ground)
    )


def run_mission(net: Network, targets: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    return ground(net, "send-targets", str(targets), "--wait", "--json",
                  "--deadline", f"{DEADLINE_S:g}", "--timeout", "40", *argv,
                  timeout=90)  # fmt: skip


def live_uavs(net: Network) -> dict[int, dict[str, object]]:
    done = ground(net, "uavs", "--json", timeout=60)
    assert done.returncode == 0, done.stderr
    return {row["id"]: row for row in json.loads(done.stdout)}


def test_cut_uav_the_survivors_complete_and_the_ground_reports_it(
    network: Network, children: list[Child], tmp_path: Path
) -> None:
    net = network
    scenario = tmp_path / "ring3.toml"
    scenario.write_text(ring_scenario(len(UAVS)))
    targets = tmp_path / "targets.bin"
    write_targets(targets, ring_targets(3, seed=7))
    router = [sys.executable, "-m", "fleet.transport.router",
              "--listen", f"tcp/0.0.0.0:{ROUTER_PORT}"]  # fmt: skip
    children.append(start("router", net.run(net.ground, *router)))
    for uav in UAVS:
        start_uav(net, uav, scenario, children)
    deadline = time.monotonic() + 90
    while set(live_uavs(net)) != set(UAVS) or any(
        row["lat"] is None for row in live_uavs(net).values()
    ):
        assert time.monotonic() < deadline, "the UAVs never all came up"
        time.sleep(0.5)

    first = run_mission(net, targets, "--team", ",".join(map(str, UAVS)))
    assert first.returncode == 0, first.stderr  # all three agree
    # Mid-mission (the fleet flying mission 1): cut the victim's only link, silently, as
    # a radio out of range. The next mission names it, as the ground would by default
    # (its token lives on until its lease ends); the survivors wait for it until the
    # deadline, then commit without it.
    check_ip(ip("-n", net.ground, "link", "set", net.ground_side(VICTIM), "down"))
    second = run_mission(net, targets, "--team", ",".join(map(str, UAVS)))
    assert second.returncode in (0, 1), second.stderr
    outcome = json.loads(second.stdout)
    survivors = sorted(set(UAVS) - {VICTIM})
    assert outcome["missing_results"] == [VICTIM]
    # Reported: lost (its liveliness went away while the ground waited) or missing.
    assert VICTIM in outcome["lost"] or outcome["missing_assignments"] == [VICTIM]
    assert outcome["disagreed"] == []
    # Committed without the victim: one target each, none for it.
    pairs = {int(uav): target for uav, target in outcome["assignment"].items()}
    assert pairs[VICTIM] is None
    assert None not in {pairs[u] for u in survivors}
    assert len({pairs[u] for u in survivors}) == len(survivors)

    # The survivors fly to their targets; the ground sees the victim gone (its lease).
    deadline = time.monotonic() + 60
    while True:
        rows = live_uavs(net)
        flying = all(rows.get(u, {}).get("phase") in ("flying", "reached") for u in survivors)
        if flying and VICTIM not in rows:
            break
        assert time.monotonic() < deadline, rows
        time.sleep(1.0)
