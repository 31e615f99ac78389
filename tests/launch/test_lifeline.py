"""Children end with their launcher (fleet.lifeline): `fleet up` killed with SIGKILL
leaves none of its processes running, forked onboards included."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleet import lifeline
from tests.support.processes import (
    ANY_PAGE,
    ANY_PORT,
    descendants,
    running,
    start,
    start_fleet_up,
    wait_fleet_up,
)
from tests.support.waiting import wait_until

#: Generous for a loaded machine: the kernel kills them at once, but a start takes long.
START_S = 120.0
#: How long the tree may take to go after the kill: what the kernel does at once, with
#: room for a loaded machine to schedule the exits.
GONE_S = 30.0


def test_a_child_env_names_this_process_as_the_parent() -> None:
    env = lifeline.child_env({"A": "1"})
    assert env == {"A": "1", lifeline.PARENT_ENV: str(os.getpid())}


def test_a_bad_parent_pid_is_ignored_and_forgotten(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setenv(lifeline.PARENT_ENV, "not-a-pid")
    lifeline.bind_from_env()
    assert lifeline.PARENT_ENV not in os.environ
    assert "not a process id" in caplog.text


@pytest.mark.e2e
def test_a_child_whose_parent_is_gone_before_it_binds_ends_at_once() -> None:
    # Its parent is named as a PID that is not its parent: as if the parent had died
    # between the fork and the binding, the child ends before running anything.
    env = {**os.environ, lifeline.PARENT_ENV: str(os.getpid() + 1_000_000)}
    code = "import fleet; print('ran')"
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == -signal.SIGKILL
    assert "ran" not in done.stdout


@pytest.mark.e2e
def test_a_bound_child_ends_when_its_parent_is_killed() -> None:
    # A parent starts a child bound to it, then is killed.
    child_code = "import fleet, time; print('bound', flush=True); time.sleep(120)"
    parent_code = (
        "import os, subprocess, sys, time\n"
        "from fleet import lifeline\n"
        f"child = subprocess.Popen([sys.executable, '-c', {child_code!r}],"
        " env=lifeline.child_env(dict(os.environ)), start_new_session=True)\n"
        "print(child.pid, flush=True)\n"
        "time.sleep(120)\n"
    )
    parent = start("parent", [sys.executable, "-c", parent_code])
    try:
        child = int(parent.wait_for_line(str.isdigit, START_S))
        parent.wait_for_line(lambda line: line == "bound", START_S)
        assert running(child)
    finally:
        parent.process.kill()
        parent.process.wait(30)
    wait_until(lambda: not running(child), GONE_S, f"the child {child} to end with its parent")


@pytest.mark.e2e
@pytest.mark.parametrize(
    "flags", [[], ["--no-fork-server"], ["--gui"]], ids=["fork-server", "no-fork-server", "gui"]
)
def test_fleet_up_killed_with_sigkill_leaves_no_process(tmp_path: Path, flags: list[str]) -> None:
    gui = ["--gui", ANY_PAGE] if flags == ["--gui"] else flags
    up = start_fleet_up("--uavs", "2", "--listen", ANY_PORT, "--log-dir", str(tmp_path), *gui)
    tree: dict[int, str] = {}
    try:
        wait_fleet_up(up, START_S)
        tree = descendants(up.pid)
        listed = {int(line.split()[0]) for line in (tmp_path / "pids").read_text().splitlines()}
        assert listed <= set(tree), (listed, tree)  # the pids file's and any others
        # The simulator, the fork server or not, two onboards, the page's server or not.
        assert len(tree) >= 3
        up.process.send_signal(signal.SIGKILL)
        up.process.wait(30)
        killed = time.monotonic()
        wait_until(
            lambda: not any(running(pid) for pid in tree),
            GONE_S,
            "every process of the killed fleet to end",
        )
        print(f"the tree of {len(tree)} ended {time.monotonic() - killed:.2f} s after the kill")
    finally:
        for pid in tree:  # only if the test failed: never leave them
            if running(pid):
                os.kill(pid, signal.SIGKILL)
        up.kill()
