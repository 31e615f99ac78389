"""`fleet up` supervises: a UAV's onboard module that dies is reported (which, its exit
status, the last lines of its log) and the rest of the fleet flies on, its target
re-planned by a teammate; with `--restart` the module is started again."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest

from fleet.files.targets_io import write_targets
from fleet.transport.cli import ExitCode
from tests.support.ground_view import GroundView
from tests.support.processes import (
    ANY_PORT,
    Child,
    client_session,
    start,
    start_fleet_up,
    wait_fleet_up,
)
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

CLI_TIMEOUT_S = 60.0


def fleet_up(tmp_path: Path, *extra: str) -> tuple[Child, str]:
    """`fleet up --uavs 3`, up: its process and the endpoint its banner names."""
    up = start_fleet_up(
        "--uavs",
        "3",
        "--listen",
        ANY_PORT,
        "--speedup",
        "3",
        "--no-record",
        "--log-dir",
        str(tmp_path),
        *extra,
    )
    try:
        endpoint = wait_fleet_up(up, 90.0).connect
        # Each progress line said once (it used to be printed and logged both).
        said = sum("simulator up with 3 aircraft" in line for line in up.history)
        assert said == 1, up.history
    except BaseException:
        stop(up)  # a start that failed its checks leaves no fleet behind
        raise
    return up, endpoint


def onboard_pids(tmp_path: Path) -> dict[int, int]:
    """Piccolo ID -> pid of its onboard module, from `fleet up`'s pids file."""
    pids = {}
    for line in (tmp_path / "pids").read_text().splitlines():
        pid, name = line.split()
        if name.startswith("onboard-"):
            pids[int(name.removeprefix("onboard-"))] = int(pid)
    return pids


def stop(up: Child) -> None:
    up.process.send_signal(signal.SIGTERM)
    assert up.process.wait(30) == 0


def test_a_dead_onboard_is_reported_and_the_team_re_plans_its_target(tmp_path: Path) -> None:
    up, endpoint = fleet_up(tmp_path)
    try:
        with client_session(endpoint) as session:
            seen = GroundView(session)
            try:
                team = sorted(onboard_pids(tmp_path))
                path = tmp_path / "two.bin"
                write_targets(path, ring_targets(2, seed=7))
                send = start(
                    "send-targets",
                    [sys.executable, "-m", "ground.cli", "--connect", endpoint,
                     "send-targets", str(path), "--wait", "--timeout", "60"],
                )  # fmt: skip
                assert send.process.wait(CLI_TIMEOUT_S) == 0, send.history
                wait_until(lambda: set(team) <= set(seen.assignments), 60.0, "every commitment")
                pairs = seen.assignments[team[0]].pairs
                (idle,) = set(team) - set(pairs)
                victim = max(pairs)

                os.kill(
                    onboard_pids(tmp_path)[victim], signal.SIGKILL
                )  # the fault: one UAV's module dies
                told = up.wait_for_line(lambda line: f"onboard-{victim} exited" in line, 30.0)
                assert "status -9" in told and "the rest of the fleet flies on" in told
                wait_until(
                    lambda: seen.assignments[idle].epoch == 1, 30.0, f"UAV {idle} re-planning"
                )
                replanned = seen.assignments[idle]
                assert replanned.released == (victim,)
                # The orphan goes to the survivor that reaches it first from where it is
                # now: the idle UAV, or the other holder after its own target.
                holders = [u for u, queue in replanned.queues.items() if pairs[victim] in queue]
                assert len(holders) == 1 and holders[0] in set(team) - {victim}, replanned
                assert up.process.poll() is None  # the fleet flies on
                others = set(team) - {victim}
                heard = {uav: len(seen.telemetry.get(uav, [])) for uav in others}
                wait_until(
                    lambda: all(len(seen.telemetry.get(u, [])) > n for u, n in heard.items()),
                    10.0,
                    "telemetry from the others",
                )
            finally:
                seen.close()
    finally:
        stop(up)


def test_restart_brings_a_dead_onboard_back(tmp_path: Path) -> None:
    up, endpoint = fleet_up(tmp_path, "--restart")
    try:
        victim = min(onboard_pids(tmp_path))
        before = onboard_pids(tmp_path)[victim]
        os.kill(before, signal.SIGKILL)
        told = up.wait_for_line(lambda line: f"onboard-{victim} exited" in line, 30.0)
        assert "restarting it in 1 s" in told
        wait_until(lambda: onboard_pids(tmp_path).get(victim, before) != before, 30.0, "a new pid")
        with client_session(endpoint) as session:
            seen = GroundView(session)
            try:
                wait_until(lambda: victim in seen.telemetry, 60.0, "the restarted UAV's telemetry")
            finally:
                seen.close()
        assert up.process.poll() is None
    finally:
        stop(up)


def test_a_recording_that_fails_is_said_and_fails_the_run(tmp_path: Path) -> None:
    # The disk is full from the first write: the recording is the device that refuses.
    (tmp_path / "fleet.mcap").symlink_to("/dev/full")
    up = start_fleet_up("--uavs", "1", "--listen", ANY_PORT, "--log-dir", str(tmp_path))
    try:
        wait_fleet_up(up, 90.0)
    finally:
        up.process.send_signal(signal.SIGTERM)
        status = up.process.wait(30)
    said = "\n".join(up.history)
    assert "the recording stopped early" in said and "No space left on device" in said, said
    assert "recorded to" not in said  # the fleet flew, but the recording is not there
    assert status == ExitCode.FAILED, said
