"""A MAVLink station's side of the end-to-end tests: a free UDP port, and waiting on
a socket for the message a test expects."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from tests.support.waiting import stretched

#: How long a test waits for an expected message at most.
WAIT_S = 60.0


def free_udp_port() -> int:
    """A UDP port free right now (someone may take it after). Only for a station that
    listens, MAVProxy (`--master=udpin:`), which the gateway must be told before it
    starts, and which never says which port it bound; a gateway that listens is given
    port 0 and says its own (`served_port`)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def receiver(sock: socket.socket, parser: mavlink2.MAVLink) -> Callable[..., Any]:
    """`heard(predicate, timeout_s)`: the first message off `sock` that matches."""

    def heard(predicate: Callable[[Any], bool], timeout_s: float = WAIT_S) -> Any:
        timeout_s = stretched(timeout_s)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                data = sock.recv(65535)
            except (TimeoutError, ConnectionRefusedError):
                continue
            for message in parser.parse_buffer(data) or []:
                if predicate(message):
                    return message
        raise AssertionError(f"nothing matching within {timeout_s:.0f} s")

    return heard
