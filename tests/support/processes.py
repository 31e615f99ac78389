"""Real processes and real Zenoh sessions for the end-to-end tests, always cleaned up.

Every child is started in its own session (process group) and stopped by PID: SIGTERM,
then SIGKILL after a grace period (the launcher's `stop_children`). Zenoh sessions opened
here are closed by the fixtures that open them. All traffic stays on 127.0.0.1.

Unlike the launcher's children, whose output goes to log files, a test's child's output
lines are read as they come, so a test can wait for one. Like the launcher's children,
each ends with the process that started it (`fleet.lifeline`: a test worker that
crashes leaves none behind) and dumps its traceback if it crashes.

Ports are never guessed: whatever listens is asked for port 0 (`ANY_PORT`) and the port
the OS gave is taken from what the program printed (`fleet up`'s banner, `fleet sim`'s
`uav ...` lines, `router listening on ...`) or, in this process, from the router itself
(`Router.endpoints`). A port found free and then handed to a program may be taken by
another test's process meanwhile.
"""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from fleet import lifeline
from fleet.launch.children import stop_children
from fleet.launch.endpoints import SimEndpoints, parse_sim_line
from fleet.transport.cli import CRASH_DUMP_ENV
from fleet.transport.router import Router, parse_listening
from fleet.transport.zenoh_config import CONNECT_ENV, make_config
from tests.support.waiting import stretched

#: A Zenoh endpoint on loopback on the port the OS picks when it is bound.
ANY_PORT = "tcp/127.0.0.1:0"
#: `ground-cli gui --listen`'s and `fleet up --gui`'s: a loopback page on any free port.
ANY_PAGE = "127.0.0.1:0"


@dataclass
class Child:
    """A started child process whose output lines are collected by a reader thread."""

    name: str
    process: subprocess.Popen[str]
    lines: queue.Queue[str] = field(default_factory=queue.Queue)
    history: list[str] = field(default_factory=list)

    def wait_for_line(self, predicate: Callable[[str], bool], timeout: float) -> str:
        """The first line that matches, within `timeout` s (`stretched` when loaded)."""
        timeout = stretched(timeout)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                if self.process.poll() is not None:
                    break
                continue
            if predicate(line):
                return line
        raise AssertionError(
            f"{self.name}: no expected line within {timeout:.0f} s; last output:\n"
            + "\n".join(self.history[-30:])
        )

    @property
    def pid(self) -> int:
        return self.process.pid

    def stop(self, grace: float = 5.0) -> int:
        stop_children([self], grace)
        return self.process.returncode

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(5)


def start(
    name: str, argv: list[str], env: dict[str, str] | None = None, *, stdin: bool = False
) -> Child:
    """Start `argv`; with `stdin`, its standard input is a pipe the test writes to
    (`child.process.stdin`), else it reads nothing."""
    process = subprocess.Popen(
        argv,
        stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        env=lifeline.child_env({**os.environ, CRASH_DUMP_ENV: "1", **(env or {})}),
    )
    child = Child(name, process)

    def pump() -> None:
        assert process.stdout is not None
        for line in process.stdout:
            line = line.rstrip("\n")
            child.history.append(line)
            child.lines.put(line)

    threading.Thread(target=pump, daemon=True).start()
    return child


#: What `fleet up` prints last once every UAV is up (the end of its banner).
FLEET_UP_READY = "stops the fleet"
_EXPORT_CONNECT = f"  export {CONNECT_ENV}="
_UAV_ROUTERS = "  (UAV routers: "
_PAGE = "Mission Manager page: "


@dataclass(frozen=True)
class FleetUpBanner:
    """Where `fleet up` said to connect, once up: the ports it bound."""

    #: The ground's router, as `export FLEET_ZENOH_CONNECT=...` says.
    connect: str
    #: A router-per-UAV mesh's routers: UAV id -> endpoint.
    uav_routers: dict[int, str]
    #: The Mission Manager page's URL (`--gui`), or None.
    page: str | None


def read_banner(lines: list[str]) -> FleetUpBanner:
    """The endpoints in `fleet up`'s banner (its output up to its ready line)."""
    connect, routers, page = None, {}, None
    for line in lines:
        if line.startswith(_EXPORT_CONNECT):
            connect = line.removeprefix(_EXPORT_CONNECT).strip()
        elif line.startswith(_UAV_ROUTERS):
            listed = line.removeprefix(_UAV_ROUTERS).split(";", 1)[0]
            for entry in listed.split(", "):
                uav, where = entry.split()
                routers[int(uav)] = where
        elif line.startswith(_PAGE):
            page = line.removeprefix(_PAGE).split()[0]
    assert connect is not None, "fleet up printed no endpoint:\n" + "\n".join(lines[-30:])
    return FleetUpBanner(connect, routers, page)


def start_fleet_up(*argv: str, env: dict[str, str] | None = None) -> Child:
    """`fleet up ARGV` started as a user starts it (`python -m programs.fleet_cli up`)."""
    return start("fleet up", [sys.executable, "-m", "programs.fleet_cli", "up", *argv], env)


def wait_fleet_up(up: Child, timeout: float) -> FleetUpBanner:
    """Once `fleet up` says every UAV is up: where its banner says to connect."""
    up.wait_for_line(lambda line: FLEET_UP_READY in line, timeout)
    return read_banner(up.history)


def end_process(process: subprocess.Popen[Any], sig: signal.Signals, grace_s: float) -> int:
    """`sig` to `process` (unless it has ended), SIGKILL if it has not ended within
    `grace_s` s; its exit status."""
    if process.poll() is None:
        process.send_signal(sig)
    try:
        return process.wait(grace_s)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def stop_fleet_up(up: Child, grace: float = 30.0) -> int:
    """SIGTERM, as Ctrl-C stops `fleet up`; its exit status (SIGKILL, and TimeoutExpired,
    if it has not ended within `grace` s)."""
    if up.process.poll() is None:
        up.process.send_signal(signal.SIGTERM)
    try:
        return up.process.wait(grace)
    except subprocess.TimeoutExpired:
        up.kill()
        raise


@dataclass
class RunningFleet:
    """A `fleet up` process (`fleet_up`), up, and where it said to connect."""

    child: Child
    banner: FleetUpBanner

    @property
    def connect(self) -> str:
        return self.banner.connect

    def stop(self, grace: float = 30.0) -> int:
        return stop_fleet_up(self.child, grace)


@contextlib.contextmanager
def fleet_up(
    *argv: str, env: dict[str, str] | None = None, timeout: float = 120.0
) -> Iterator[RunningFleet]:
    """`fleet up ARGV` (on a router port it picks, `ANY_PORT`, unless ARGV says
    --listen), once every UAV is up; stopped on exit if it still runs."""
    listen = [] if "--listen" in argv else ["--listen", ANY_PORT]
    up = start_fleet_up(*argv, *listen, env=env)
    try:
        yield RunningFleet(up, wait_fleet_up(up, timeout))
    finally:
        stop_fleet_up(up)


class Fleet:
    """Children of one test: stopped together, in reverse order, whatever happens."""

    def __init__(self) -> None:
        self.children: list[Child] = []

    def sim(
        self, scenario: str, speedup: float = 10.0, telemetry_hz: float = 5.0, *extra: str
    ) -> dict[int, SimEndpoints]:
        child = start(
            "fleet sim",
            [
                sys.executable, "-m", "fleet.sim.command", scenario,
                "--program-port", "0", "--payload-port", "0", "--ground-port", "0",
                "--speedup", str(speedup), "--telemetry-hz", str(telemetry_hz), *extra,
            ],
        )  # fmt: skip
        self.children.append(child)
        endpoints: dict[int, SimEndpoints] = {}
        while True:
            line = child.wait_for_line(lambda s: s.startswith(("uav ", "ready")), 30.0)
            if line == "ready":
                return endpoints
            where = parse_sim_line(line)
            assert where is not None, f"fleet sim printed {line!r}"
            endpoints[where.piccolo_id] = where

    def onboard(self, uav: int, where: SimEndpoints, router: str, *extra: str) -> Child:
        child = start(
            f"onboard {uav}",
            [
                sys.executable, "-m", "onboard.main", "--id", str(uav),
                "--program", where.program, "--payload", where.payload,
                "--connect", router, *extra,
            ],
        )  # fmt: skip
        self.children.append(child)
        return child

    def onboard_child(self, uav: int) -> Child:
        """The onboard process of UAV `uav` started last (by `onboard` or `restart`)."""
        return [c for c in self.children if c.name == f"onboard {uav}"][-1]

    def restart(self, child: Child) -> Child:
        """Start `child`'s command again (after it was killed), as a new child."""
        argv = child.process.args
        assert isinstance(argv, list)
        again = start(child.name, [str(arg) for arg in argv])
        self.children.append(again)
        return again

    def stop_all(self) -> None:
        for child in reversed(self.children):
            child.stop()


@contextlib.contextmanager
def router_session(listen: str = ANY_PORT) -> Iterator[Router]:
    """An embedded router on `listen` (by default a loopback port the OS picks), open for
    the duration of a test: its session is `.session`, where it listens `.endpoints[0]`."""
    with Router([listen]) as router:
        yield router


@contextlib.contextmanager
def client_session(endpoint: str) -> Iterator[zenoh.Session]:
    """A client session of the router at `endpoint`."""
    session = zenoh.open(make_config("client", connect=[endpoint]))
    try:
        yield session
    finally:
        session.close()


@contextlib.contextmanager
def refused_endpoint() -> Iterator[str]:
    """A loopback endpoint where every connection is refused: its port is bound by this
    process but not listened on, so no other process can take it meanwhile (a port
    merely found free could be by the time the test dials it)."""
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        yield f"tcp/127.0.0.1:{held.getsockname()[1]}"


def start_router(*argv: str, name: str = "router", timeout: float = 30.0) -> tuple[Child, str]:
    """`python -m fleet.transport.router ARGV` (`--listen ANY_PORT`, say), once it
    listens: the child and the endpoint it printed first (`router listening on ...`)."""
    child = start(name, [sys.executable, "-m", "fleet.transport.router", *argv])
    try:
        line = child.wait_for_line(lambda text: parse_listening(text) is not None, timeout)
    except BaseException:
        child.stop()
        raise
    endpoint = parse_listening(line)
    assert endpoint is not None
    return child, endpoint


# ---- the process tree ------------------------------------------------------------------
def running(pid: int) -> bool:
    """Whether `pid` runs (a zombie, ended but not yet collected, does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def command_line(pid: int) -> str:
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return "?"
    return " ".join(part.decode(errors="replace") for part in raw.split(b"\0") if part)


def descendants(root: int) -> dict[int, str]:
    """The processes under `root` (children, theirs, ...) that run, PID -> command line."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError):
                stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
                children.setdefault(int(stat[1]), []).append(int(entry))
    found: dict[int, str] = {}
    todo = list(children.get(root, []))
    while todo:
        pid = todo.pop()
        if running(pid):
            found[pid] = command_line(pid)
        todo.extend(children.get(pid, []))
    return found
