"""The CLI plumbing every program shares: argument types, Zenoh flags, signals, logging."""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

import pytest
import zenoh

from fleet.mission.key_registry import DEFAULT_PREFIX
from fleet.mission.key_space import KeySpace
from fleet.transport.cli import (
    PREFIX_ENV,
    ExitCode,
    ZenohConfigError,
    add_zenoh_arguments,
    bounded_int,
    non_negative_float,
    piccolo_id,
    positive_float,
    setup_logging,
    stop_on_signals,
    tcp_port,
    zenoh_config,
)
from fleet.transport.command import LocalCommand, run_standalone
from fleet.transport.zenoh_config import CONFIG_ENV, CONNECT_ENV, endpoints
from tests.support.ground_cli import ground_cli_here
from tests.support.processes import router_session
from tests.support.waiting import wait_until

REPO = Path(__file__).resolve().parents[2]
CLI_TIMEOUT_S = 60.0


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    return parser.parse_args(argv)


def write_config(path: Path, connect: str) -> Path:
    path.write_text(
        "// a deployment's Zenoh config (JSON5)\n"
        "{\n"
        '  mode: "client",\n'
        f'  connect: {{ endpoints: ["{connect}"] }},\n'
        "  scouting: { multicast: { enabled: false } },\n"
        "}\n"
    )
    return path


@pytest.fixture
def router() -> Iterator[tuple[zenoh.Session, str]]:
    with router_session() as running:
        yield running.session, running.endpoints[0]


def env_without_zenoh() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in (CONNECT_ENV, CONFIG_ENV)}


def run_program(*argv: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", *argv],
        cwd=REPO,
        env=env if env is not None else env_without_zenoh(),
        capture_output=True,
        text=True,
        timeout=CLI_TIMEOUT_S,
        check=False,
    )


# ---- argument types -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("parse_type", "text", "message"),
    [
        (positive_float, "0", "must be a positive number"),
        (positive_float, "-1", "must be a positive number"),
        (positive_float, "nan", "not a finite number"),
        (positive_float, "fast", "not a number"),
        (non_negative_float, "-0.5", "must be a number >= 0"),
        (non_negative_float, "inf", "not a finite number"),
        (tcp_port, "65536", "the TCP port must be 0-65535, got 65536"),
        (tcp_port, "80.5", "not a whole number"),
        (piccolo_id, "0", "the Piccolo ID must be 1-65520, got 0"),
        (piccolo_id, "65521", "the Piccolo ID must be 1-65520, got 65521"),
        (bounded_int(1, what="count"), "0", "the count must be at least 1, got 0"),
    ],
)
def test_argument_types_refuse_with_the_reason(parse_type: object, text: str, message: str) -> None:
    assert callable(parse_type)
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        parse_type(text)


def test_argument_types_accept_their_range() -> None:
    assert positive_float("2.5") == 2.5
    assert non_negative_float("0") == 0.0
    assert tcp_port("0") == 0
    assert piccolo_id("65520") == 0xFFF0
    assert bounded_int(1, what="count")("10000") == 10000


# ---- Zenoh flags ------------------------------------------------------------------------------
def test_no_flags_give_a_client_of_the_default_router(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(CONFIG_ENV, raising=False)
    monkeypatch.setenv(CONNECT_ENV, "tcp/127.0.0.1:7999")
    config = zenoh_config(parse())
    assert json.loads(config.get_json("mode")) == "client"
    assert endpoints(config) == ["tcp/127.0.0.1:7999"]
    assert config.get_json("scouting/multicast/enabled") == "false"


def test_the_environment_and_connect_override_a_config_file_s_router(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`fleet up --secure` says `export FLEET_ZENOH_CONNECT=tls/...:PORT` beside the
    identity's config file, which names the default port: the exported router wins, and
    --connect wins over both."""
    path = write_config(tmp_path / "zenoh.json5", "tcp/127.0.0.1:7447")
    monkeypatch.setenv(CONNECT_ENV, "tcp/127.0.0.1:18350")
    assert endpoints(zenoh_config(parse("--zenoh-config", str(path)))) == ["tcp/127.0.0.1:18350"]
    flags = ("--zenoh-config", str(path), "--connect", "tcp/127.0.0.1:9")
    assert endpoints(zenoh_config(parse(*flags))) == ["tcp/127.0.0.1:9"]
    monkeypatch.delenv(CONNECT_ENV)
    assert endpoints(zenoh_config(parse("--zenoh-config", str(path)))) == ["tcp/127.0.0.1:7447"]


def test_a_config_file_is_honoured_by_a_real_session(
    router: tuple[zenoh.Session, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    router_session_, endpoint = router
    monkeypatch.delenv(CONNECT_ENV, raising=False)
    path = write_config(tmp_path / "zenoh.json5", endpoint)
    config = zenoh_config(parse("--zenoh-config", str(path)))
    assert endpoints(config) == [endpoint]
    with zenoh.open(config) as session:
        wait_until(
            lambda: router_session_.zid() in session.info.routers_zid(),
            10.0,
            "the client to join the router named in the config file",
        )


def test_the_environment_names_the_config_file(
    router: tuple[zenoh.Session, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, endpoint = router
    path = write_config(tmp_path / "zenoh.json5", endpoint)
    monkeypatch.setenv(CONFIG_ENV, str(path))
    assert endpoints(zenoh_config(parse())) == [endpoint]


def test_flags_override_the_config_file(tmp_path: Path) -> None:
    path = write_config(tmp_path / "zenoh.json5", "tcp/127.0.0.1:1")
    config = zenoh_config(
        parse(
            "--zenoh-config",
            str(path),
            "--connect",
            "tcp/127.0.0.1:2",
            "--mode",
            "peer",
            "--listen",
            "tcp/127.0.0.1:3",
        )
    )
    assert endpoints(config) == ["tcp/127.0.0.1:2"]
    assert endpoints(config, "listen") == ["tcp/127.0.0.1:3"]
    assert json.loads(config.get_json("mode")) == "peer"


def test_a_missing_config_file_is_named(tmp_path: Path) -> None:
    missing = tmp_path / "absent.json5"
    with pytest.raises(ZenohConfigError, match=rf"cannot read Zenoh config {missing}: No such"):
        zenoh_config(parse("--zenoh-config", str(missing)))


def test_a_malformed_config_file_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json5"
    bad.write_text('{ mode: "sideways" }')
    with pytest.raises(ZenohConfigError, match=rf"Zenoh config {bad} is not valid: .*sideways"):
        zenoh_config(parse("--zenoh-config", str(bad)))


def test_a_malformed_endpoint_is_refused() -> None:
    with pytest.raises(ZenohConfigError, match="malformed Zenoh endpoint 'localhost'"):
        zenoh_config(parse("--connect", "localhost"))


def test_ground_cli_uses_the_config_file(
    router: tuple[zenoh.Session, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, endpoint = router
    for name in (CONNECT_ENV, CONFIG_ENV):
        monkeypatch.delenv(name, raising=False)
    path = write_config(tmp_path / "zenoh.json5", endpoint)
    done = ground_cli_here("--zenoh-config", str(path), "uavs", "--json")
    assert done.returncode == ExitCode.OK, done.stderr
    assert json.loads(done.stdout) == []


@pytest.mark.parametrize("program", ["ground.cli", "onboard.main"])
def test_a_bad_config_file_exits_2_with_the_reason(
    program: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    bad = tmp_path / "bad.json5"
    bad.write_text("{ mode: ")
    monkeypatch.delenv(CONNECT_ENV, raising=False)
    monkeypatch.setenv(CONFIG_ENV, str(bad))
    if program == "ground.cli":
        done = ground_cli_here("uavs")
        status, err = done.returncode, done.stderr
    else:
        from onboard.main import main as onboard_main

        status = onboard_main(["--id", "7", "--program", "x", "--payload", "y"])
        err = capsys.readouterr().err
    assert status == 2
    assert f"Zenoh config {bad} is not valid" in err
    assert "Traceback" not in err


# ---- signals and logging -------------------------------------------------------------------------
def test_sigterm_and_sigint_call_the_stop_and_the_old_handlers_come_back() -> None:
    stop = threading.Event()
    before = signal.getsignal(signal.SIGTERM)
    for sig in (signal.SIGTERM, signal.SIGINT):
        stop.clear()
        with stop_on_signals(stop.set):
            signal.raise_signal(sig)
            assert stop.wait(5.0)
    assert signal.getsignal(signal.SIGTERM) is before


def test_stop_on_signals_off_the_main_thread_installs_nothing() -> None:
    before = signal.getsignal(signal.SIGTERM)
    seen: list[object] = []

    def body() -> None:
        with stop_on_signals(lambda: None):
            seen.append(signal.getsignal(signal.SIGTERM))

    thread = threading.Thread(target=body)
    thread.start()
    thread.join()
    assert seen == [before]


def test_each_v_lowers_the_level(monkeypatch: pytest.MonkeyPatch) -> None:
    root = logging.getLogger()
    monkeypatch.setattr(root, "handlers", [])
    monkeypatch.setattr(root, "level", root.level)
    setup_logging(0, base=logging.WARNING)
    assert root.level == logging.WARNING
    root.handlers = []
    setup_logging(1, base=logging.WARNING)
    assert root.level == logging.INFO
    root.handlers = []
    setup_logging(5)
    assert root.level == logging.DEBUG


def test_run_standalone_parses_the_command_and_v_then_returns_its_status(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    root = logging.getLogger()
    monkeypatch.setattr(root, "handlers", [])
    monkeypatch.setattr(root, "level", root.level)
    seen: list[str] = []

    def configure(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("thing")

    def run(thing: str, out: TextIO) -> int:
        seen.append(thing)
        return ExitCode.FAILED

    command = LocalCommand(lambda args: str(args.thing), run)
    status = run_standalone("fleet x", "a command", configure, command, ["-v", "a"])
    assert status == ExitCode.FAILED
    assert seen == ["a"]
    assert root.level == logging.DEBUG


def test_key_prefix_flag_sets_the_key_space_for_this_command_and_its_children(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(PREFIX_ENV, DEFAULT_PREFIX)  # restored after the test
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    args = parser.parse_args(["--key-prefix", "replay"])
    assert "key_prefix" not in vars(args)  # the KeySpace is stored, not the text
    assert args.key_space == KeySpace("replay")
    assert args.key_space.all_state == "replay/uav/*/state"
    assert os.environ[PREFIX_ENV] == "replay"


def test_the_key_prefix_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(PREFIX_ENV, raising=False)
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    assert parser.parse_args([]).key_space == KeySpace(DEFAULT_PREFIX)
    monkeypatch.setenv(PREFIX_ENV, "replay")
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    assert parser.parse_args([]).key_space.telemetry(7) == "replay/uav/7/telemetry"


def test_a_bad_key_prefix_is_a_usage_error(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv(PREFIX_ENV, DEFAULT_PREFIX)
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    with pytest.raises(SystemExit, match="2"):
        parser.parse_args(["--key-prefix", "a/b"])
    assert "one key chunk" in capsys.readouterr().err
    assert os.environ[PREFIX_ENV] == DEFAULT_PREFIX
    monkeypatch.setenv(PREFIX_ENV, "a/b")
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    with pytest.raises(SystemExit, match="2"):
        parser.parse_args([])
    assert "one key chunk" in capsys.readouterr().err
