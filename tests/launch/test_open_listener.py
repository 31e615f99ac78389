"""`fleet up --listen`: an open (not tls/) router beyond loopback needs `--insecure`."""

from __future__ import annotations

import pytest

from fleet.launch.up_command import open_listener_problem
from programs.fleet_cli import main as fleet_main


@pytest.mark.parametrize(
    "listen",
    ["tcp/127.0.0.1:7447", "tcp/[::1]:7447", "tcp/localhost:7447", "tls/0.0.0.0:7447"],
)
def test_loopback_or_tls_needs_nothing(listen: str) -> None:
    assert open_listener_problem(listen, insecure=False) is None


@pytest.mark.parametrize(
    "listen", ["tcp/0.0.0.0:7447", "tcp/[::]:7447", "tcp/192.168.1.5:7447", "tcp/router:7447"]
)
def test_an_open_listener_beyond_loopback_needs_insecure(listen: str) -> None:
    problem = open_listener_problem(listen, insecure=False)
    assert problem is not None and "--insecure" in problem and "--secure" in problem
    assert open_listener_problem(listen, insecure=True) is None


def test_fleet_up_refuses_it_before_starting_anything(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert fleet_main(["up", "head_on", "--listen", "tcp/0.0.0.0:7447"]) == 2
    err = capsys.readouterr().err
    assert "open router beyond this host" in err and "--insecure" in err
