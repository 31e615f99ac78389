"""A new `fleet up` refuses a port, or Piccolo IDs, that another fleet's processes
hold, naming them (fleet.launch.holders)."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest

from fleet.launch.endpoints import free_port, host_port
from fleet.launch.holders import uav_holders
from tests.support.processes import start, wait_fleet_up

pytestmark = pytest.mark.e2e

START_S = 120.0


def fleet_up(port: int, log_dir: Path, *flags: str) -> list[str]:
    """`fleet up --uavs 2` on loopback port `port` (0: a port the OS picks)."""
    return [
        sys.executable, "-m", "programs.fleet_cli", "up", "--uavs", "2", "--no-record",
        "--listen", f"tcp/127.0.0.1:{port}", "--log-dir", str(log_dir), *flags,
    ]  # fmt: skip


def test_a_second_fleet_up_on_a_held_port_says_who_holds_it(tmp_path: Path) -> None:
    first = start("first fleet up", fleet_up(0, tmp_path / "first"))
    try:
        port = host_port(wait_fleet_up(first, START_S).connect)[1]
        second = start("second fleet up", fleet_up(port, tmp_path / "second"))
        assert second.process.wait(START_S) == 1
        said = "\n".join(second.history)
        assert f"port {port} of tcp/127.0.0.1:{port} is held by PID {first.pid} (" in said
        assert "programs.fleet_cli up" in said
        assert not (tmp_path / "second" / "pids").exists()  # nothing was started
    finally:
        first.process.send_signal(signal.SIGTERM)
        assert first.process.wait(60) == 0


def test_fleet_up_refuses_uavs_an_onboard_of_another_fleet_would_join_with(
    tmp_path: Path,
) -> None:
    # Guessed free, not port 0: the stand-in below names the fleet's port before the
    # fleet starts, as a left-over onboard of a dead fleet would.
    port = free_port()
    # A stand-in for an onboard left running by a dead fleet: its command line is one's.
    left = start(
        "left onboard",
        [sys.executable, "-c", "import time; print('up', flush=True); time.sleep(120)",
         "onboard.main", "--id", "102", "--connect", f"tcp/127.0.0.1:{port}"],
    )  # fmt: skip
    try:
        left.wait_for_line(lambda line: line == "up", START_S)
        assert [holder.pid for holder in uav_holders(port, [102])] == [left.pid]
        assert uav_holders(port, [101]) == []
        assert uav_holders(port + 1, [102]) == []
        up = start("fleet up", fleet_up(port, tmp_path))
        assert up.process.wait(START_S) == 1
        said = "\n".join(up.history)
        assert f"would join this one on port {port}: PID {left.pid} (" in said
        assert "--id 102" in said
    finally:
        left.kill()
