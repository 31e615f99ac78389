"""No single point of failure: `fleet up --topology router-per-uav` (a router per UAV on
a ring, each linked to the ground's router, every onboard a client of its own router
with fallbacks), the ground's router killed (SIGKILL) right after it delivered a
mission: the UAVs still exchange results, agree and fly; the ground, reconnecting
through a UAV's router, sees the truth and can send the next mission.
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
from importlib.resources import files
from pathlib import Path
from typing import Any

import pytest

from fleet.launch.topology import fallbacks, ring_links
from tests.processes import Child, free_port, start

TIMEOUT_S = 120
TARGETS = str(files("fleet") / "scenarios" / "head_on_targets.bin")


def ground_cli(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "ground.cli", *argv],
        capture_output=True, text=True, timeout=TIMEOUT_S, check=False,
    )  # fmt: skip


def pids(log_dir: Path) -> dict[str, int]:
    lines = (log_dir / "pids").read_text().splitlines()
    return {name: int(pid) for pid, name in (line.split() for line in lines)}


@pytest.fixture
def mesh(tmp_path: Path) -> Iterator[tuple[Child, str, list[str]]]:
    ground = f"tcp/127.0.0.1:{free_port()}"
    up = start(
        "fleet up --topology router-per-uav",
        [sys.executable, "-m", "ground.fleet_cli", "up", "head_on", "--topology",
         "router-per-uav", "--listen", ground, "--speedup", "5", "--log-dir", str(tmp_path)],
    )  # fmt: skip
    try:
        line = up.wait_for_line(lambda line: "UAV routers:" in line, 90.0)
        uav_routers = re.findall(r"tcp/127\.0\.0\.1:\d+", line)
        up.wait_for_line(lambda line: "stops the fleet" in line, 10.0)
        yield up, ground, uav_routers
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30) == 0, "\n".join(up.history[-30:])


def mission_state(connect: list[str], mission: int) -> dict[int, dict[str, Any]]:
    argv = [arg for endpoint in connect for arg in ("--connect", endpoint)]
    listed = ground_cli(*argv, "uavs", "--json")
    assert listed.returncode == 0, listed.stderr
    return {row["id"]: row for row in json.loads(listed.stdout) if row["mission"] == mission}


def test_the_uavs_agree_and_fly_without_the_ground_router(
    mesh: tuple[Child, str, list[str]], tmp_path: Path
) -> None:
    up, ground, uav_routers = mesh
    sent = ground_cli("--connect", ground, "send-targets", TARGETS, "--json")
    assert sent.returncode == 0, sent.stderr  # delivered: both UAVs have mission 1
    mission = json.loads(sent.stdout)["mission"]
    os.kill(pids(tmp_path)["router-ground"], signal.SIGKILL)

    # The ground comes back through whichever router still answers.
    fallback = [ground, *uav_routers]
    deadline = time.monotonic() + 60
    while True:
        rows = mission_state(fallback, mission)
        if len(rows) == 2 and all(r["phase"] in ("flying", "reached") for r in rows.values()):
            break
        assert time.monotonic() < deadline, rows
        time.sleep(0.5)
    assert sorted(r["target"] for r in rows.values()) == [0, 1]  # agreed: one target each
    argv = [arg for endpoint in fallback for arg in ("--connect", endpoint)]
    shown = ground_cli(*argv, "keys", f"fleet/mission/{mission}/assignment/*", "--json")
    reports = [item["value"] for item in json.loads(shown.stdout)]
    assert len(reports) == 2 and reports[0]["digest"] == reports[1]["digest"]
    assert up.process.poll() is None  # the fleet runs on without its ground router

    # And the ground commands the fleet through the mesh.
    again = ground_cli(*argv, "send-targets", TARGETS, "--wait", "--json", "--timeout", "60")
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
