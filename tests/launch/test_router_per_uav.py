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
import re
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
import zenoh

from fleet.files.certs import write_identities
from fleet.launch.topology import fallbacks, ring_links
from fleet.mission.key_space import KeySpace
from fleet.transport.zenoh_config import build_config
from tests.support.ground_cli import ground_cli
from tests.support.processes import Child, start, wait_fleet_up
from tests.support.telemetry_times import TelemetryTimes
from tests.support.waiting import wait_until

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


@pytest.mark.parametrize("mesh", ["secure"], indirect=True)
def test_a_revoked_uav_is_cut_off_by_every_router_of_the_mesh(mesh: Mesh, tmp_path: Path) -> None:
    """`fleet certs revoke` through the ground's router: UAV 74's own router closes its
    onboard's session and its reconnections, the other routers hear the revocation too;
    UAV 112 flies on and keeps reporting."""
    certs = tmp_path / "certs"
    config = build_config(config_file=str(certs / "ground.json5"), connect=[mesh.ground])
    with zenoh.open(config) as ground:
        telemetry = TelemetryTimes(ground, KeySpace())
        wait_until(lambda: telemetry.since(74, 0.0) and telemetry.since(112, 0.0), 60.0,
                   "both UAVs' telemetry")  # fmt: skip
        revoked = subprocess.run(
            [sys.executable, "-m", "programs.fleet_cli", "certs", "revoke", str(certs),
             "uav-74", "--connect", mesh.ground],
            capture_output=True, text=True, timeout=TIMEOUT_S, check=False,
        )  # fmt: skip
        assert revoked.returncode == 0, revoked.stderr[-3000:]
        since = time.monotonic()
        wait_until(lambda: telemetry.stopped(74, 112, since, 20), 60.0,
                   "74's telemetry to stop while 112's flows")  # fmt: skip
        stopped_at = telemetry.last(74)

        def closed_by_74s_router() -> int:
            shown = mesh.ground_cli("routers", via=[mesh.ground])
            counted = re.search(r"router router-74 \(\w+\): refused links: .*revoked=(\d+)",
                                shown.stdout)  # fmt: skip
            return int(counted[1]) if counted else 0

        # 74's onboard dials its own router again (first of its fallbacks), which holds
        # that link, then closes it: the session and a reconnection, at least.
        wait_until(lambda: closed_by_74s_router() >= 2, 60.0, "router-74 refusing 74 again")
        for router in ("router-ground", "router-112"):  # they heard it too, should 74 fall back
            log = (tmp_path / f"{router}.log").read_text()
            assert "revoked from now on (a roster heard on fleet/roster): uav-74" in log, router
        mark = time.monotonic()
        wait_until(lambda: telemetry.since(112, mark) >= 20, 30.0, "112's telemetry")
        assert telemetry.last(74) == stopped_at, "74's telemetry came back"
        telemetry.undeclare()


def test_the_mesh_is_sparse() -> None:
    ids = list(range(101, 151))
    links = ring_links(ids)
    assert sum(len(n) for n in links.values()) + len(ids) == 2 * len(ids)  # ring + ground
    assert all(len(n) == 1 for n in links.values())
    assert fallbacks(ids, 101) == [101, 102, 150]
    assert ring_links([74, 112]) == {74: [112], 112: []}
    assert ring_links([74]) == {74: []}
