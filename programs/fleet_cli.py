"""`fleet`: the shared command line: decode a capture, simulate autopilots, run a fleet,
record, replay, plot and report on it, serve it to Foxglove and MAVLink stations."""

from __future__ import annotations

import argparse
import sys

from fleet.launch import up_command
from fleet.recording import commands as recording_commands
from fleet.sim import command as sim_command
from fleet.tools import certs_command, decode_command
from fleet.transport.cli import ExitCode, add_verbose_argument, setup_logging
from fleet.transport.command import run_parsed
from ground.foxglove_live import command as foxglove_command
from ground.mavlink import cli as mavlink_command
from programs import demo

#: Each subcommand's module registers its parser with `add_parser(subparsers)`.
SUBCOMMANDS = (
    decode_command,
    sim_command,
    up_command,
    certs_command,
    demo,
    recording_commands,
    foxglove_command,
    mavlink_command,
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet", description=__doc__)
    add_verbose_argument(parser)
    subparsers = parser.add_subparsers(dest="command", required=True)
    for module in SUBCOMMANDS:
        module.add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose)
    try:
        return run_parsed(args, f"fleet {args.command}")
    except KeyboardInterrupt:
        return ExitCode.INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
