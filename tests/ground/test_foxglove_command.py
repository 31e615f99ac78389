"""`fleet foxglove`'s command line: what it refuses, and why, before serving anything."""

from __future__ import annotations

import socket

import pytest

from fleet.transport.cli import ExitCode
from programs.fleet_cli import main
from tests.support.processes import refused_endpoint


def test_serving_beyond_loopback_needs_allow_remote(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["foxglove", "--serve", "0.0.0.0:8765"]) == ExitCode.USAGE
    err = capsys.readouterr().err
    assert "fleet foxglove: --serve 0.0.0.0:8765 is not loopback" in err
    assert "--allow-remote" in err


@pytest.mark.parametrize("address", ["8765", "localhost:http", "127.0.0.1:65536", ":8765"])
def test_a_bad_address_is_a_usage_error(address: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["foxglove", "--serve", address])
    assert exited.value.code == ExitCode.USAGE
    assert f"{address!r}: expected HOST:PORT with a port 0-65535, e.g. 127.0.0.1:8765" in (
        capsys.readouterr().err
    )


def test_a_taken_port_is_said_before_connecting(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        status = main(["foxglove", "--serve", f"127.0.0.1:{port}", "--connect", "tcp/127.0.0.1:1"])
    assert status == ExitCode.FAILED
    err = capsys.readouterr().err
    assert f"fleet foxglove: cannot listen on 127.0.0.1:{port}" in err
    assert "Address already in use" in err
    assert err.splitlines()[-1].endswith("stop it, or give another port with --serve")


def test_no_router_is_said(capsys: pytest.CaptureFixture[str]) -> None:
    with refused_endpoint() as endpoint:
        status = main(["foxglove", "--serve", "127.0.0.1:0", "--connect", endpoint])
    assert status == ExitCode.USAGE
    assert f"no Zenoh router answers at {endpoint}" in capsys.readouterr().err
