"""`fleet mavlink`'s command line: what is refused before anything is opened."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from ground.mavlink.cli import _identity_line
from programs.fleet_cli import main


def test_two_uavs_on_one_system_id_are_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mavlink", "--sysid", "300=30", "--sysid", "400=30"]) == 2
    assert "system id 30 given to both UAV 300 and UAV 400" in capsys.readouterr().err


def test_a_sysid_out_of_range_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["mavlink", "--sysid", "300=255"])
    assert stopped.value.code == 2
    assert "255 is for ground stations" in capsys.readouterr().err


@pytest.mark.parametrize("out", ["serial:/dev/ttyS0", "udpout:nowhere", "tcpin:127.0.0.1:x"])
def test_a_bad_endpoint_is_a_usage_error(out: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mavlink", "--out", out]) == 2
    assert "fleet mavlink: error:" in capsys.readouterr().err


def test_a_port_in_use_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        assert main(["mavlink", "--out", f"udpin:127.0.0.1:{port}"]) == 2
    said = capsys.readouterr().err
    assert "in use" in said
    assert said.splitlines() == [
        f"fleet mavlink: error: udpin:127.0.0.1:{port}: Address already in use (another "
        "program listens there): stop it, or give another port with --out"
    ]


def test_the_identity_it_holds_is_said() -> None:
    assert "ground's identity" in _identity_line("/certs/ground.json5")
    assert "not the ground's identity" in _identity_line("/certs/uav-74.json5")
    assert "open fleet" in _identity_line(None)


@pytest.mark.parametrize("out", ["udpin:0.0.0.0:14550", "udpout:192.168.1.20:14550"])
def test_a_non_loopback_out_needs_signing_or_insecure(
    out: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["mavlink", "--out", out]) == 2
    err = capsys.readouterr().err
    assert "not loopback" in err and "--signing-key" in err and "--insecure" in err


def test_a_signing_key_file_others_can_read_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    keys = tmp_path / "keys"
    keys.write_text("operator secret words\n")
    keys.chmod(0o644)
    assert main(["mavlink", "--out", "udpin:0.0.0.0:0", "--signing-key", str(keys)]) == 2
    assert "chmod 600" in capsys.readouterr().err
