"""What the command lines accept and say: the targets files the page
loads (CSV, GeoJSON) are read by `ground-cli` too; `ground-cli gui --listen` takes a
`tcp/` endpoint; `fleet up --gui SCENARIO` is the scenario, not the page's address;
`fleet replay` has one prefix flag."""

from __future__ import annotations

import argparse
import errno
import json
import socket
from pathlib import Path

import pytest

from fleet.launch.up_command import DEFAULT_GUI_LISTEN, add_up_parser, up_options
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import Target
from fleet.transport.cli import PREFIX_ENV, cannot_listen
from fleet.transport.command import OptionsError
from ground import targets_formats
from ground.cli import main
from ground.gui.cli import host_port
from programs.fleet_cli import build_parser
from tests.support.ground_cli import ground_cli_here

TARGETS = [Target(35.73, -120.75, 600.0), Target(35.70, -120.79, 610.0)]


@pytest.mark.parametrize("fmt", [targets_formats.TargetsFormat.CSV, "geojson"])
def test_targets_show_reads_the_files_the_page_loads(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str
) -> None:
    path = tmp_path / f"targets.{fmt}"
    path.write_bytes(targets_formats.encode(TARGETS, targets_formats.TargetsFormat(fmt)))
    assert main(["targets", "show", str(path), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert [(t["lat"], t["lon"], t["alt"]) for t in shown] == [
        (t.lat, t.lon, t.alt) for t in TARGETS
    ]


def test_a_bad_csv_is_refused_naming_file_and_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.csv"
    path.write_text("lat,lon,alt\n35.7,-120.7,600\n35.7,east,600\n")
    assert main(["targets", "show", str(path)]) == 1
    error = capsys.readouterr().err
    assert error.startswith(f"error: {path}") and "line 3" in error, error


def test_the_page_listens_on_a_tcp_endpoint_too() -> None:
    assert host_port("tcp/127.0.0.1:8321") == ("127.0.0.1", 8321)
    assert host_port("[::1]:8321") == ("::1", 8321)
    with pytest.raises(argparse.ArgumentTypeError, match="served over TCP"):
        host_port("udp/127.0.0.1:8321")


def _up_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_up_parser(parser.add_subparsers())
    return parser.parse_args(["up", *argv])


def test_fleet_up_gui_then_a_scenario_runs_the_scenario_with_the_page() -> None:
    options = up_options(_up_args("--gui", "head_on"))
    assert (options.scenario, options.gui) == ("head_on", DEFAULT_GUI_LISTEN)
    options = up_options(_up_args("head_on", "--gui", "127.0.0.1:9000"))
    assert (options.scenario, options.gui) == ("head_on", "127.0.0.1:9000")
    with pytest.raises(OptionsError) as refused:
        up_options(_up_args("--gui"))
    assert refused.value.message == "give a SCENARIO (a shipped name or a TOML file) or --uavs N"


def test_fleet_replay_has_one_prefix_flag_defaulting_to_replay(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(PREFIX_ENV, "fleet")  # the live fleet's: never a replay's default
    parser = build_parser()
    assert parser.parse_args(["replay", "x.mcap"]).key_space == KeySpace("replay")
    assert parser.parse_args(["replay", "x.mcap", "--key-prefix", "lab"]).key_space == KeySpace(
        "lab"
    )
    with pytest.raises(SystemExit):
        parser.parse_args(["replay", "x.mcap", "--prefix", "lab"])


def test_a_hostile_geojson_file_is_refused_by_name_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "deep.geojson"
    path.write_bytes(b"[" * 100_000 + b"]" * 100_000)
    assert main(["targets", "show", str(path)]) == 1
    assert capsys.readouterr().err == f"error: {path}: nested too deeply to be GeoJSON\n"


def test_the_page_on_a_port_in_use_is_one_line_saying_what_to_do() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = ground_cli_here("gui", "--listen", f"127.0.0.1:{port}", connect="memory:in-use")
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr.splitlines() == [
        f"ground-cli gui: error: cannot listen on 127.0.0.1:{port}: Address already in use "
        "(another program listens there): stop it, or give another port with --listen"
    ]


def test_cannot_listen_advises_only_for_a_port_in_use() -> None:
    in_use = OSError(errno.EADDRINUSE, "error while binding: address already in use")
    assert cannot_listen("h:1", in_use) == (
        "cannot listen on h:1: Address already in use (another program listens there): "
        "stop it, or listen on another port"
    )
    denied = OSError(errno.EACCES, "Permission denied")
    assert cannot_listen("h:80", denied, "--serve") == "cannot listen on h:80: Permission denied"
