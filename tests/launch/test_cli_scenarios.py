"""The fleet as a user runs it: `fleet demo`, `fleet up` and `ground-cli`, each a real
subprocess (console scripts' modules), checked from outside: exit codes, JSON output
and the Zenoh key space.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from importlib.resources import files
from pathlib import Path

import pytest

from tests.support.ground_cli import ground_cli
from tests.support.processes import ANY_PORT, start_fleet_up, wait_fleet_up

pytestmark = pytest.mark.e2e

TIMEOUT_S = 120


def run(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *argv], capture_output=True, text=True, timeout=TIMEOUT_S, check=False
    )


def test_fleet_demo_runs_the_thesis_multi_uav_scenario(tmp_path: Path) -> None:
    done = run(
        "-m", "programs.fleet_cli", "demo", "--json", "--listen", ANY_PORT,
        "--log-dir", str(tmp_path),
        "--timeout", "100",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    outcome = json.loads(done.stdout)
    assert outcome["agreed"] is True and outcome["success"] is True
    assert outcome["assignment"] == {"74": 0, "112": 1}
    # Target 2 is queued behind a first target: nobody's is unserved.
    queued = sorted(t for queue in outcome["queues"].values() for t in queue)
    assert outcome["unassigned"] == [] and queued == [0, 1, 2]
    assert set(outcome["reached"]) == {"74", "112"} and all(outcome["reached"].values())
    # Whole queues flown: every target reached, each by the UAV whose queue holds it.
    holder = {t: int(uav) for uav, queue in outcome["queues"].items() for t in queue}
    assert {int(t): a["uav"] for t, a in outcome["arrivals"].items()} == holder
    # It recorded the run and drew the mission from the recording.
    assert outcome["plot"] == str(tmp_path / "mission.png")
    assert (tmp_path / "mission.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "fleet.mcap").stat().st_size > 0
    # Every process it started is gone.
    pids = [int(line.split()[0]) for line in (tmp_path / "pids").read_text().splitlines()]
    assert pids and not any(Path(f"/proc/{pid}").exists() for pid in pids)


def test_fleet_up_then_ground_cli_single_uav(tmp_path: Path) -> None:
    up = start_fleet_up(
        "single_uav", "--listen", ANY_PORT, "--speedup", "5", "--log-dir", str(tmp_path)
    )
    try:
        endpoint = wait_fleet_up(up, 90.0).connect

        def ground(*argv: str) -> subprocess.CompletedProcess[str]:
            return ground_cli(*argv, connect=endpoint, timeout=TIMEOUT_S)

        listed = ground("uavs", "--json")
        assert listed.returncode == 0, listed.stderr
        (uav,) = json.loads(listed.stdout)
        # Ready means link up and telemetry flowing: the first listing has a position.
        assert uav["id"] == 112
        assert uav["lat"] is not None and abs(uav["lat"] - 35.72) < 0.05, uav
        assert uav["lon"] is not None and abs(uav["lon"] + 120.76) < 0.05, uav

        targets = str(files("fleet") / "scenarios" / "single_uav_targets.bin")
        sent = ground("send-targets", targets, "--wait", "--json", "--timeout", "60")
        assert sent.returncode == 0, sent.stderr
        outcome = json.loads(sent.stdout)
        assert outcome["team"] == [112]
        assert outcome["assignment"] == {"112": 1}  # the target ahead, 15 degrees right
        assert outcome["queues"]["112"][0] == 1 and sorted(outcome["queues"]["112"]) == [0, 1, 2]
        assert outcome["unassigned"] == [] and outcome["agreed"] is True
        assert all(isinstance(t, float) for t in outcome["results"]["112"])

        keys = ground("keys", "fleet/mission/**", "--json", "--window", "0.5")
        assert keys.returncode == 0, keys.stderr
        found = {item["key"]: item["value"] for item in json.loads(keys.stdout)}
        mission = outcome["mission"]
        assert found[f"fleet/mission/{mission}/assignment/112"]["target"] == 1
        assert len(found[f"fleet/mission/{mission}/targets"]["targets"]) == 3

        bad = tmp_path / "bad.bin"
        bad.write_bytes(b"\x00" * 25)
        refused = ground("send-targets", str(bad))
        assert refused.returncode != 0 and str(bad) in refused.stderr
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30) == 0
    pids = [int(line.split()[0]) for line in (tmp_path / "pids").read_text().splitlines()]
    assert pids and not any(Path(f"/proc/{pid}").exists() for pid in pids)
