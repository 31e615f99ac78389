"""Zenoh's own log cut to what an operator can act on: its lines (as a real router
wrote them, tests/transport/test_link_refusal.py) parsed, each given the level it is
logged at, and withheld from the output they were written to while a program's own
output passes on untouched."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import pytest

from fleet.transport.fd_tap import FdTap
from fleet.transport.zenoh_log import ZenohLog, level_of, logger_name, parse
from tests.support.waiting import wait_until
from tests.transport.test_link_refusal import CAPTURED


def zenoh_line(level: str, target: str, message: str) -> str:
    """A line as Zenoh 1.x writes it to a pipe (coloured)."""
    colour = {"ERROR": "31", "WARN": "33", "INFO": "32"}.get(level, "34")
    return (
        f"\x1b[2m2026-11-28T10:32:40.296364Z\x1b[0m \x1b[{colour}m{level:>5}\x1b[0m "
        f"ThreadId(07) \x1b[2m{target}\x1b[0m\x1b[2m:\x1b[0m {message}"
    )


UNKNOWN_KEY_EXPR = zenoh_line(
    "ERROR", "zenoh::api::session", "Received Data for unknown key_expr: 12"
)
RETRY = (
    "2026-11-26T02:15:59.766132Z  WARN ThreadId(01) zenoh::net::runtime::orchestrator: Unable "
    "to connect to tls/127.0.0.1:47111! received fatal alert: CertificateRequired"
)
ODD = zenoh_line(
    "WARN",
    "zenoh::net::routing::dispatcher::face",
    "Face 3 closed with 2 pending queries at /root/.cargo/git/checkouts/z/src/face.rs:88.",
)


def test_zenohs_lines_are_parsed_and_nothing_else_is() -> None:
    line = parse(ODD)
    assert line is not None
    assert (line.level, line.target) == ("WARN", "zenoh::net::routing::dispatcher::face")
    assert line.message == "Face 3 closed with 2 pending queries"  # no Rust source path
    refusal = parse(next(iter(CAPTURED)))
    assert refusal is not None and refusal.target == "zenoh_link_tls::unicast"
    for own in (
        "fleet up: 2 UAV(s) alive (74, 112); router on tls/127.0.0.1:18391",
        "2026-11-26 02:13:45,189 __main__ INFO zenoh router 2619adce listening",
        "  ground-cli uavs",
        "",
        "\x1b[33m garbage \xff",
    ):
        assert parse(own) is None


@pytest.mark.parametrize(
    ("line", "level"),
    [
        (UNKNOWN_KEY_EXPR, logging.DEBUG),  # a race Zenoh resolves by dropping the sample
        (RETRY, logging.DEBUG),  # a mesh router retrying a peer
        *((refused, logging.DEBUG) for refused in CAPTURED),  # counted, totals logged
        (ODD, logging.WARNING),
        (zenoh_line("ERROR", "zenoh_transport::unicast", "link lost"), logging.ERROR),
        (zenoh_line("INFO", "zenoh::net::runtime", "Using ZID: 4073"), logging.DEBUG),
    ],
)
def test_each_line_is_logged_at_what_an_operator_can_act_on(line: str, level: int) -> None:
    parsed = parse(line)
    assert parsed is not None
    assert level_of(parsed, line) == level


def test_rust_modules_become_loggers_under_zenoh() -> None:
    assert logger_name("zenoh::api::session") == "zenoh.api.session"
    assert logger_name("zenoh_link_tls::unicast") == "zenoh_link_tls.unicast"
    assert logger_name("rustls::conn") == "zenoh.rustls.conn"


def test_a_zenoh_line_is_logged_not_passed_on_unless_rust_log_asks_for_it(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.DEBUG)
    gate = ZenohLog(raw=False)
    assert gate.keep("fleet up: stopping")
    assert not gate.keep(ODD)
    assert not gate.keep(UNKNOWN_KEY_EXPR)
    said = [(r.name, r.levelno, r.getMessage()) for r in caplog.records]
    assert said == [
        (
            "zenoh.net.routing.dispatcher.face",
            logging.WARNING,
            "Face 3 closed with 2 pending queries",
        ),
        ("zenoh.api.session", logging.DEBUG, "Received Data for unknown key_expr: 12"),
    ]
    raw = ZenohLog(raw=True)  # $RUST_LOG set: Zenoh's own log, as it writes it
    assert raw.keep(ODD) and raw.keep(UNKNOWN_KEY_EXPR)


def test_the_rust_log_variable_makes_the_gate_pass_zenohs_lines(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("RUST_LOG", "info")
    assert ZenohLog().raw
    monkeypatch.delenv("RUST_LOG")
    assert not ZenohLog().raw


def test_the_gated_tap_withholds_zenohs_lines_and_passes_the_rest_as_it_comes(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    out = tmp_path / "out"
    fd = os.open(out, os.O_WRONLY | os.O_CREAT)
    lines: list[str] = []
    tap = FdTap(lines.append, fd, keep=ZenohLog(raw=False).keep)
    try:
        tap.start()
        os.write(fd, b"fleet up: sta")
        # A program's own line passes on before it ends: nothing is held back.
        wait_until(lambda: out.read_bytes() == b"fleet up: sta", 10.0, "the line's start")
        os.write(fd, b"rting\n" + UNKNOWN_KEY_EXPR.encode() + b"\n")
        os.write(fd, ODD.encode()[:20])  # Zenoh's line arrives in parts
        os.write(fd, ODD.encode()[20:] + b"\n2 UAVs\n")
    finally:
        tap.stop()
        os.close(fd)
    # A line starting with a digit is held until it ends, then passed on: not Zenoh's.
    assert out.read_bytes() == b"fleet up: starting\n2 UAVs\n"
    assert lines == ["fleet up: starting", UNKNOWN_KEY_EXPR, ODD, "2 UAVs"]  # all seen
    warned = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert [(r.name, r.getMessage()) for r in warned] == [
        ("zenoh.net.routing.dispatcher.face", "Face 3 closed with 2 pending queries")
    ]
