"""Where a fleet's parts are reached: the ports `fleet sim` prints, a router's endpoint
as a client on this machine dials it, and free ports to listen on."""

from __future__ import annotations

import re
import socket
from dataclasses import dataclass

_SIM_LINE = re.compile(r"^uav (?P<id>\d+) (?P<rest>.*)$")


@dataclass(frozen=True)
class SimEndpoints:
    """One aircraft's ports, as `fleet sim` printed them."""

    piccolo_id: int
    program: str
    payload: str
    ground: str


def parse_sim_line(line: str) -> SimEndpoints | None:
    """`uav 112 program=URL payload=URL ground=URL` -> SimEndpoints; None for other lines."""
    match = _SIM_LINE.match(line.strip())
    if match is None:
        return None
    fields = dict(part.split("=", 1) for part in match["rest"].split() if "=" in part)
    try:
        return SimEndpoints(
            int(match["id"]), fields["program"], fields["payload"], fields.get("ground", "")
        )
    except KeyError:
        return None


def client_endpoint(listen: str) -> str:
    """Where a client on this machine reaches a router listening on `listen`."""
    proto, _, address = listen.partition("/")
    host, _, port = address.rpartition(":")
    if host in ("0.0.0.0", ""):
        host = "127.0.0.1"
    elif host in ("[::]", "::"):
        host = "[::1]"
    return f"{proto}/{host}:{port}"


def host_port(endpoint: str) -> tuple[str, int]:
    """`tcp/127.0.0.1:7447` -> ("127.0.0.1", 7447)."""
    address = endpoint.partition("/")[2].split("#", 1)[0]
    host, _, port = address.rpartition(":")
    return host.strip("[]"), int(port)


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on `host` right now (the OS picks it; someone may take it after)."""
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as probe:
        probe.bind((host, 0))
        port: int = probe.getsockname()[1]
        return port
