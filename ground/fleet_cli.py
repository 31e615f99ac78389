"""`fleet`: the shared command line: decode a capture, simulate autopilots, run a fleet."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

#: Each subcommand lives in its own module with `add_parser(subparsers)`.
SUBCOMMANDS = (
    "fleet.planning.decode_command",
    "fleet.sim.command",
    "fleet.launch.up_command",
    "ground.demo",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    subparsers = parser.add_subparsers(dest="command", required=True)
    for module in SUBCOMMANDS:
        importlib.import_module(module).add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(name)s %(levelname)s %(message)s",
        stream=sys.stderr,
    )
    status: int = args.func(args)
    return status


if __name__ == "__main__":
    sys.exit(main())
