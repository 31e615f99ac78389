"""One bus factory (`open_bus`) and the command shell over it (`run_parsed`)."""

from __future__ import annotations

import argparse
import io
from typing import TextIO

import pytest

from fleet.transport.bus import Bus, BusSample
from fleet.transport.bus_factory import OnFirstUse, forget_memory_network, open_bus, opened_bus
from fleet.transport.cli import ExitCode, add_zenoh_arguments
from fleet.transport.command import Command, LocalCommand, OptionsError, run_parsed, set_handler
from fleet.transport.faulty_bus import FaultRule, FaultyBus
from fleet.transport.memory import MemoryBus
from tests.support.processes import refused_endpoint


def test_memory_buses_of_one_name_see_each_other_and_of_another_do_not() -> None:
    got: list[str] = []
    try:
        with (
            opened_bus("memory:a") as one,
            opened_bus("memory:a") as two,
            opened_bus("memory:b") as other,
        ):
            assert isinstance(one, MemoryBus)
            two.subscribe("x/**", lambda sample: got.append(sample.key))
            one.put("x/1", b"{}")
            other.put("x/2", b"{}")
        assert got == ["x/1"]
    finally:
        forget_memory_network("a")
        forget_memory_network("b")


def test_faults_wrap_the_bus_and_a_memory_bus_needs_a_name() -> None:
    rule = FaultRule("x/**", drop_first=1)
    seen: list[BusSample] = []
    with opened_bus("memory:faults", faults=[rule]) as bus:
        assert isinstance(bus, FaultyBus)
        bus.subscribe("x/**", seen.append)
        bus.put("x/1", b"1")
        bus.put("x/1", b"2")
        assert [s.payload for s in seen] == [b"2"] and bus.dropped["x/1"] == 1
    forget_memory_network("faults")
    with pytest.raises(ValueError, match="needs a name"):
        open_bus("memory:")


def test_a_bus_on_first_use_opens_only_when_used_and_once() -> None:
    opened: list[Bus] = []

    def opener() -> Bus:
        opened.append(open_bus("memory:lazy"))
        return opened[-1]

    bus = OnFirstUse(opener)
    bus.close()  # never used: never opened
    assert opened == []
    bus = OnFirstUse(opener)
    bus.put("x", b"{}")
    assert bus.live_tokens("x/**", 0.1) == []
    assert len(opened) == 1
    bus.close()
    assert isinstance(opened[0], MemoryBus) and opened[0].closed
    forget_memory_network("lazy")


def _parse(command: Command[str] | LocalCommand[str], *argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    parser.add_argument("word", nargs="?")
    set_handler(parser, command)
    return parser.parse_args(list(argv))


def _word(args: argparse.Namespace) -> str:
    if args.word == "bad":
        raise OptionsError("error: a bad word")
    return str(args.word)


def test_the_root_builds_the_options_then_runs_the_command_on_the_bus_it_opened(
    capsys: pytest.CaptureFixture[str],
) -> None:
    seen: list[tuple[str, bool]] = []

    def run(bus: Bus, word: str, out: TextIO) -> int:
        bus.put("x", b"{}")
        seen.append((word, isinstance(bus, OnFirstUse)))
        print(word, file=out)
        return ExitCode.OK

    out = io.StringIO()
    command = Command(_word, run)
    assert run_parsed(_parse(command, "--connect", "memory:root", "hi"), "prog", out) == 0
    assert seen == [("hi", True)] and out.getvalue() == "hi\n"
    # Options refused: said once, with the program's name, and nothing run.
    assert run_parsed(_parse(command, "--connect", "memory:root", "bad"), "prog", out) == 2
    assert capsys.readouterr().err == "prog: error: a bad word\n" and len(seen) == 1
    forget_memory_network("root")


def test_no_router_is_said_when_the_command_first_uses_the_bus(
    capsys: pytest.CaptureFixture[str],
) -> None:
    steps: list[str] = []

    def run(bus: Bus, word: str, out: TextIO) -> int:
        steps.append("before the bus")  # a command checks its files first
        bus.put("x", b"{}")
        steps.append("after")
        return ExitCode.OK

    with refused_endpoint() as endpoint:
        status = run_parsed(_parse(Command(_word, run), "--connect", endpoint, "w"), "prog")
    assert status == ExitCode.USAGE and steps == ["before the bus"]
    assert f"prog: error: no Zenoh router answers at {endpoint}" in capsys.readouterr().err
    # A local command never dials.
    local = LocalCommand(_word, lambda word, out: ExitCode.OK)
    assert run_parsed(_parse(local, "--connect", endpoint, "w"), "prog") == ExitCode.OK
