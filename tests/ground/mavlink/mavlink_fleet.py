"""The fleet side of the `fleet mavlink` end-to-end tests: `fleet up` with simulated UAVs
on a TCP port, `ground-cli` against it, and the gateway as its own process."""

from __future__ import annotations

import json
import re
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tests.ground.mavlink.stations import WAIT_S, free_udp_port
from tests.support.ground_cli import ground_cli
from tests.support.processes import ANY_PORT, Child, start, start_fleet_up, wait_fleet_up
from tests.support.waiting import wait_until

#: What the gateway prints once it serves, before its URL.
SERVING = "fleet mavlink: serving on "
#: How long `fleet up` may take to say its fleet is up.
START_S = 90.0
#: MAVProxy's prompts ("MAV> ", "Mode(393216)> "): its console prints them with no
#: newline, so the next line it prints may come after one, or several.
_PROMPTS = re.compile(r"^(?:\S+> )+")


def said(line: str) -> str:
    """A line of MAVProxy's console without the prompts before it."""
    return _PROMPTS.sub("", line)


class FleetUp:
    def __init__(self, endpoint: str, up: Child, tmp: Path) -> None:
        #: Where `fleet up` said its router listens.
        self.endpoint = endpoint
        self.up = up
        self.tmp = tmp

    def ground_cli(self, *argv: str) -> Any:
        done = ground_cli(*argv, connect=self.endpoint, timeout=WAIT_S)
        assert done.returncode in (0, 1), done.stderr
        return json.loads(done.stdout) if done.stdout.strip() else None

    def uav(self, piccolo: int) -> dict[str, Any]:
        views = self.ground_cli("uavs", "--json") or []
        return next((v for v in views if v["id"] == piccolo), {})

    def gateway(self, out: str, *extra: str) -> Child:
        child = start(
            "fleet mavlink",
            [sys.executable, "-m", "programs.fleet_cli", "mavlink", "--connect", self.endpoint,
             "--out", out, *extra],
        )  # fmt: skip
        child.wait_for_line(lambda line: line.startswith(SERVING), WAIT_S)
        return child

    def mavproxy(self, port: int, state: str = "mavproxy") -> Child:
        """MAVProxy, headless (driven through its standard input), listening on UDP `port`
        for the gateway; its state in tmp/`state`. Unbuffered: some of what it says is
        printed, not written to its console (which flushes), and a test that fails shows
        it all (`wp load`'s "Loaded 3 waypoints" was missing from a failure's output)."""
        return start(
            "mavproxy",
            [sys.executable, "-m", "MAVProxy.mavproxy", f"--master=udpin:127.0.0.1:{port}",
             f"--state-basedir={self.tmp / state}"],
            env={"HOME": str(self.tmp), "PYTHONUNBUFFERED": "1"},
            stdin=True,
        )  # fmt: skip

    @contextmanager
    def mavproxy_gateway(
        self, *extra: str, state: str = "mavproxy"
    ) -> Iterator[tuple[Child, Child]]:
        """A gateway (with `extra` arguments) sending to MAVProxy (`mavproxy`) on a free
        UDP port: (MAVProxy, the gateway), both stopped on exit (the gateway's whole
        output is then its `history`)."""
        port = free_udp_port()
        gateway = self.gateway(f"udpout:127.0.0.1:{port}", *extra)
        proxy = self.mavproxy(port, state)
        try:
            yield proxy, gateway
        finally:
            proxy.stop()
            stop(gateway)


def served_port(gateway: Child) -> int:
    """The port a gateway said it serves on (`fleet mavlink: serving on KIND:HOST:PORT`):
    the one it bound, for a `udpin:`/`tcpin:` URL on port 0."""
    line = next(line for line in gateway.history if line.startswith(SERVING))
    return int(line.removeprefix(SERVING).split()[0].rsplit(":", 1)[1])


@contextmanager
def running_fleet(uavs: int, tmp: Path) -> Iterator[FleetUp]:
    """`fleet up --uavs N` at five times real time, logging under `tmp`, until exit."""
    up = start_fleet_up(
        "--uavs",
        str(uavs),
        "--speedup",
        "5",
        "--listen",
        ANY_PORT,
        "--log-dir",
        str(tmp / "logs"),
        "--no-record",
    )
    try:
        yield FleetUp(wait_fleet_up(up, START_S).connect, up, tmp)
    finally:
        up.process.send_signal(signal.SIGTERM)
        up.process.wait(30)


@contextmanager
def mavsdk_systems(port: int, uavs: int) -> Iterator[dict[int, Any]]:
    """MAVSDK (its bundled library) as a ground station to the gateway's udpin `port`,
    once it sees `uavs` systems: its systems by system id, until exit."""
    from mavsdk.component_type import ComponentType
    from mavsdk.mavsdk import Configuration, Mavsdk

    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    with Mavsdk(config) as sdk:
        sdk.add_any_connection(f"udpout://127.0.0.1:{port}")
        wait_until(lambda: len(sdk.get_systems()) >= uavs, WAIT_S, f"{uavs} systems")
        yield {s.get_system_id(): s for s in sdk.get_systems()}


def stop(child: Child) -> list[str]:
    """SIGTERM, wait, and its whole output."""
    assert child.process.poll() is None, f"{child.name} died:\n" + "\n".join(child.history)
    child.stop(grace=15.0)
    time.sleep(0.2)  # the reader thread takes the last lines off the pipe
    return child.history
