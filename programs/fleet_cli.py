"""`fleet`: the shared command line: decode a capture, simulate autopilots, run a fleet,
record, replay, plot and report on it, serve it to Foxglove and MAVLink stations."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from types import ModuleType

from fleet.transport.cli import ExitCode, add_verbose_argument, setup_logging
from fleet.transport.command import run_parsed


# Each subcommand's module, imported (statically, where it is named) only when its
# command runs or `build_parser` builds every parser: `fleet --help` and `fleet up`
# do not pay for matplotlib, pymavlink or cryptography (bench/bench_startup.py).
def _decode() -> ModuleType:
    from fleet.tools import decode_command

    return decode_command


def _sim() -> ModuleType:
    from fleet.sim import command

    return command


def _up() -> ModuleType:
    from fleet.launch import up_command

    return up_command


def _certs() -> ModuleType:
    from fleet.tools import certs_command

    return certs_command


def _demo() -> ModuleType:
    from programs import demo

    return demo


def _recording() -> ModuleType:
    from fleet.recording import commands

    return commands


def _foxglove() -> ModuleType:
    from ground.foxglove_live import command

    return command


def _mavlink() -> ModuleType:
    from ground.mavlink import cli

    return cli


#: Each subcommand: its one-line help, and its module (whose `add_parser(subparsers)`
#: registers it, with that same help; tests/test_fleet_cli.py checks they agree).
SUBCOMMANDS: dict[str, tuple[str, Callable[[], ModuleType]]] = {
    "decode": ("decode a captured Piccolo link byte stream to JSON lines", _decode),
    "sim": ("simulated Piccolo autopilots (hardware-in-the-loop stand-in)", _sim),
    "up": ("run a simulated fleet: router, simulator and one onboard per UAV", _up),
    "certs": ("identities for the secure (mTLS) profile", _certs),
    "demo": ("the thesis's multi-UAV scenario end to end (head_on)", _demo),
    "record": ("record the fleet's key space to MCAP", _recording),
    "replay": ("replay a recording onto Zenoh", _recording),
    "plot": ("draw a recorded mission as a PNG", _recording),
    "report": ("each recorded mission, summed up", _recording),
    "foxglove": ("serve the live fleet to Foxglove (WebSocket)", _foxglove),
    "mavlink": (
        "show every live UAV to MAVLink ground stations (QGroundControl, MAVProxy, MAVSDK)",
        _mavlink,
    ),
}


def _named(argv: Sequence[str]) -> str | None:
    """The subcommand `argv` names: its first word that is one (options come first)."""
    return next((word for word in argv if word in SUBCOMMANDS), None)


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """`fleet`'s parser: every subcommand's in full, or, given the `argv` it will parse,
    only the one `argv` names (the others by name and help, enough for `--help`)."""
    parser = argparse.ArgumentParser(prog="fleet", description=__doc__)
    add_verbose_argument(parser)
    subparsers = parser.add_subparsers(dest="command", required=True)
    if argv is None:
        wanted = set(SUBCOMMANDS)
    else:
        named = _named(argv)
        # With the others its module registers (record, replay, plot and report are one's).
        loader = SUBCOMMANDS[named][1] if named is not None else None
        wanted = {name for name, (_, module) in SUBCOMMANDS.items() if module is loader}
    built: set[str] = set()
    for name, (help_text, module) in SUBCOMMANDS.items():
        if name in built:
            continue
        if name in wanted:
            before = set(subparsers.choices)
            module().add_parser(subparsers)
            built |= set(subparsers.choices) - before
        else:
            subparsers.add_parser(name, help=help_text, add_help=False)
            built.add(name)
    return parser


def main(argv: list[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else argv
    args = build_parser(words).parse_args(words)
    setup_logging(args.verbose)
    try:
        return run_parsed(args, f"fleet {args.command}")
    except KeyboardInterrupt:
        return ExitCode.INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
