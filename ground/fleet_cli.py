"""`fleet`: the shared command line: decode a capture, simulate autopilots, run a fleet,
record, replay, plot and report on it, serve it to Foxglove."""

from __future__ import annotations

import argparse
import importlib
import sys

from fleet.transport.cli import add_verbose_argument, setup_logging

#: Each subcommand lives in its own module with `add_parser(subparsers)`.
SUBCOMMANDS = (
    "fleet.tools.decode_command",
    "fleet.sim.command",
    "fleet.launch.up_command",
    "fleet.tools.certs_command",
    "ground.demo",
    "fleet.recording.commands",
    "ground.foxglove_live.command",
    "ground.mavlink.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet", description=__doc__)
    add_verbose_argument(parser)
    subparsers = parser.add_subparsers(dest="command", required=True)
    for module in SUBCOMMANDS:
        importlib.import_module(module).add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose)
    status: int = args.func(args)
    return status


if __name__ == "__main__":
    sys.exit(main())
