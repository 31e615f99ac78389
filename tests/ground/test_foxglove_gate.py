"""The Foxglove server's gate: which handshakes pass (`ground.foxglove_live.gate`)."""

from __future__ import annotations

import pytest

from ground.foxglove_live.gate import Rules
from ground.host_check import host_of_header


def handshake(*headers: str) -> bytes:
    return ("GET / HTTP/1.1\r\n" + "".join(f"{h}\r\n" for h in headers) + "\r\n").encode()


LOCAL = Rules.make("127.0.0.1", [], [])


@pytest.mark.parametrize(
    ("headers", "refused"),
    [
        (("Host: 127.0.0.1:8765",), None),  # a script or Foxglove's desktop client
        (("Host: localhost:8765", "Origin: https://app.foxglove.dev"), None),
        (("Host: [::1]:8765", "Origin: file://"), None),
        (("Host: 127.0.0.1:8765", "Origin: https://evil.example"), "origin"),
        (("Host: 127.0.0.1:8765", "Origin: null"), "origin"),  # a sandboxed frame
        (("Host: 127.0.0.1:8765", "Origin: https://app.foxglove.dev.evil.example"), "origin"),
        (("Host: evil.example:8765", "Origin: http://evil.example:8765"), "host"),  # rebinding
        ((), "no Host"),
        (("Host: 127.0.0.1", "Host: evil.example"), "no Host, or more than one"),
        (("Host: 127.0.0.1", "Origin: file://", "Origin: https://evil.example"), "more than"),
    ],
)
def test_the_gate_refuses_foreign_origins_and_hosts(
    headers: tuple[str, ...], refused: str | None
) -> None:
    reason = LOCAL.refusal(handshake(*headers))
    if refused is None:
        assert reason is None
    else:
        assert reason is not None and reason.startswith(refused)


def test_origins_and_hosts_may_be_added() -> None:
    rules = Rules.make("192.168.1.5", ["ground.local"], ["https://studio.example/"])
    assert (
        rules.refusal(handshake("Host: ground.local:8765", "Origin: https://studio.example"))
        is None
    )
    assert rules.refusal(handshake("Host: 192.168.1.5:8765")) is None
    assert rules.refusal(handshake("Host: 127.0.0.1:8765")) is not None  # not what it is bound to
    assert rules.refusal(b"POST / HTTP/1.1\r\nHost: 192.168.1.5\r\n\r\n") is not None


def test_every_interface_checks_the_origin_only() -> None:
    rules = Rules.make("0.0.0.0", [], [])
    assert rules.refusal(handshake("Host: anything.example")) is None
    assert rules.refusal(handshake("Host: anything.example", "Origin: https://x.example"))


@pytest.mark.parametrize(
    ("header", "host"),
    [("127.0.0.1:8765", "127.0.0.1"), ("[::1]:8765", "::1"), ("localhost", "localhost"),
     ("::1", "::1")],
)  # fmt: skip
def test_a_host_header_without_its_port(header: str, host: str) -> None:
    assert host_of_header(header) == host
