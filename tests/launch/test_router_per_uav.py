"""No single point of failure: `fleet up --topology router-per-uav` (a router per UAV on
a ring, each linked to the ground's router, every onboard a client of its own router
with fallbacks), the ground's router killed (SIGKILL) right after it delivered a
mission: the UAVs still exchange results, agree and fly; the ground, reconnecting
through a UAV's router, sees the truth and can send the next mission. In the open
profile and in the secure one (every router with mTLS and access control).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

import pytest

from fleet.files.certs import write_identities
from fleet.launch.topology import fallbacks, ring_links
from tests.support.ground_cli import ground_cli
from tests.support.processes import Child, start, wait_fleet_up

pytestmark = pytest.mark.e2e

TIMEOUT_S = 120
TARGETS = str(files("fleet") / "scenarios" / "head_on_targets.bin")


@dataclass
class Mesh:
    up: Child
    ground: str  #: the ground's router
    uav_routers: list[str]
    identity: list[str]  #: the ground's --zenoh-config, in the secure profile

    def ground_cli(self, *argv: str, via: list[str]) -> subprocess.CompletedProcess[str]:
        return ground_cli(*self.identity, *argv, connect=via, timeout=TIMEOUT_S)


def pids(log_dir: Path) -> dict[str, int]:
    lines = (log_dir / "pids").read_text().splitlines()
    return {name: int(pid) for pid, name in (line.split() for line in lines)}


@pytest.fixture(params=["open", "secure"])
def mesh(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Mesh]:
    proto = "tls" if request.param == "secure" else "tcp"
    listen = f"{proto}/127.0.0.1:0"  # the banner says which port
    secure: list[str] = []
    identity: list[str] = []
    if request.param == "secure":
        names = ["router", "ground", "uav-74", "uav-112", "router-74", "router-112"]
        write_identities(tmp_path / "certs", names, [listen])
        secure = ["--secure", str(tmp_path / "certs")]
        identity = ["--zenoh-config", str(tmp_path / "certs" / "ground.json5")]
    up = start(
        "fleet up --topology router-per-uav",
        [sys.executable, "-m", "programs.fleet_cli", "up", "head_on", "--topology",
         "router-per-uav", "--listen", listen, "--speedup", "5", "--log-dir", str(tmp_path),
         *secure],
    )  # fmt: skip
    try:
        banner = wait_fleet_up(up, 90.0)
        assert banner.connect.startswith(f"{proto}/127.0.0.1:"), banner
        yield Mesh(up, banner.connect, list(banner.uav_routers.values()), identity)
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30) == 0, "\n".join(up.history[-30:])


def mission_state(mesh: Mesh, via: list[str], mission: int) -> dict[int, dict[str, Any]]:
    listed = mesh.ground_cli("uavs", "--json", via=via)
    assert listed.returncode == 0, listed.stderr
    return {row["id"]: row for row in json.loads(listed.stdout) if row["mission"] == mission}


def test_the_uavs_agree_and_fly_without_the_ground_router(mesh: Mesh, tmp_path: Path) -> None:
    sent = mesh.ground_cli("send-targets", TARGETS, "--json", via=[mesh.ground])
    assert sent.returncode == 0, sent.stderr  # delivered: both UAVs have mission 1
    mission = json.loads(sent.stdout)["mission"]
    os.kill(pids(tmp_path)["router-ground"], signal.SIGKILL)

    # The ground comes back through whichever router still answers.
    fallback = [mesh.ground, *mesh.uav_routers]
    deadline = time.monotonic() + 60
    while True:
        rows = mission_state(mesh, fallback, mission)
        if len(rows) == 2 and all(r["phase"] in ("flying", "reached") for r in rows.values()):
            break
        assert time.monotonic() < deadline, rows
        time.sleep(0.5)
    assert sorted(r["target"] for r in rows.values()) == [0, 1]  # agreed: one target each
    shown = mesh.ground_cli("keys", f"fleet/mission/{mission}/assignment/*", "--json", via=fallback)
    reports = [item["value"] for item in json.loads(shown.stdout)]
    assert len(reports) == 2 and reports[0]["digest"] == reports[1]["digest"]
    assert mesh.up.process.poll() is None  # the fleet runs on without its ground router

    # And the ground commands the fleet through the mesh.
    again = mesh.ground_cli(
        "send-targets", TARGETS, "--wait", "--json", "--timeout", "60", via=fallback
    )
    assert again.returncode == 0, again.stderr
    outcome = json.loads(again.stdout)
    assert outcome["mission"] == mission + 1 and outcome["agreed"] is True


def test_the_mesh_is_sparse() -> None:
    ids = list(range(101, 151))
    links = ring_links(ids)
    assert sum(len(n) for n in links.values()) + len(ids) == 2 * len(ids)  # ring + ground
    assert all(len(n) == 1 for n in links.values())
    assert fallbacks(ids, 101) == [101, 102, 150]
    assert ring_links([74, 112]) == {74: [112], 112: []}
    assert ring_links([74]) == {74: []}
