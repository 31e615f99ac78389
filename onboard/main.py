"""`onboard`: the onboard planning module of one UAV."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

import zenoh

from fleet.errors import CertError, RosterError
from fleet.solver.pyvrp_plan import solver_available
from fleet.transport.bus_factory import open_bus
from fleet.transport.cli import (
    ExitCode,
    ZenohConfigError,
    add_verbose_argument,
    add_zenoh_arguments,
    fail,
    non_negative_float,
    piccolo_id,
    positive_float,
    setup_logging,
    stop_on_signals,
    zenoh_config,
)
from fleet.transport.zenoh_bus import BusConnectError
from fleet.transport.zenoh_config import uses_mtls
from onboard.core import CONFIRM_LIMIT_S, LINK_RELEASE_S
from onboard.planner.approach_highs import load_highs_core
from onboard.process import OnboardProcess, OnboardSettings

log = logging.getLogger("onboard")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="onboard", description=__doc__)
    parser.add_argument("--id", type=piccolo_id, required=True, help="Piccolo ID of this aircraft")
    parser.add_argument("--program", required=True, help="program port: a pyserial URL or path")
    parser.add_argument("--payload", required=True, help="payload port: a pyserial URL or path")
    parser.add_argument("--baud", type=int, default=57_600)
    parser.add_argument(
        "--payload-ground",
        action="store_true",
        help="also send status and results to the ground over the payload port",
    )
    parser.add_argument(
        "--status-rate",
        type=non_negative_float,
        default=1.0,
        help="status messages a second; 0: only on change",
    )
    parser.add_argument(
        "--budget", type=positive_float, default=2.0, help="planning time budget, s (> 0)"
    )
    parser.add_argument(
        "--telemetry-hz",
        type=positive_float,
        metavar="HZ",
        help="publish telemetry on the bus at most this often (default: every packet)",
    )
    parser.add_argument(
        "--confirm-limit",
        type=positive_float,
        default=CONFIRM_LIMIT_S,
        metavar="S",
        help="give a target up when its writes are not echoed this long after the "
        "commitment, s (default %(default)g)",
    )
    parser.add_argument(
        "--link-release",
        type=positive_float,
        default=LINK_RELEASE_S,
        metavar="S",
        help="give a held target up (it is re-planned) when the autopilot link stays "
        "lost this long, s (default %(default)g)",
    )
    parser.add_argument(
        "--propose",
        action="store_true",
        help="solve and propose a plan (PyVRP: pip install '.[solver]') for each mission "
        "that names this UAV among its proposers",
    )
    add_zenoh_arguments(parser)
    add_verbose_argument(parser)
    return parser


def settings_from(args: argparse.Namespace, config: zenoh.Config) -> OnboardSettings:
    """The process's settings from `build_parser`'s arguments and their Zenoh config."""
    return OnboardSettings(
        uav_id=args.id,
        program_url=args.program,
        payload_url=args.payload,
        zenoh_config=config,
        baud=args.baud,
        payload_ground=args.payload_ground,
        status_rate_hz=args.status_rate,
        planning_budget_s=args.budget,
        confirm_limit_s=args.confirm_limit,
        link_release_s=args.link_release,
        telemetry_hz=args.telemetry_hz,
        key_space=args.key_space,
        # In the secure profile only Zenoh, where each message's sender is known, commands.
        payload_commands=not uses_mtls(config),
        propose=args.propose,
    )


def fork_preload() -> None:
    """What a fork server (fleet.launch.fork_server) loads before it forks onboards:
    the approach model and HiGHS's compiled core, which each onboard otherwise loads
    when it builds its model, so their pages are shared too."""
    importlib.import_module("onboard.planner.approach_model")
    load_highs_core()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose, name=f"onboard[{args.id}]")
    try:
        config = zenoh_config(args)
    except ZenohConfigError as error:
        return fail("onboard", str(error))
    settings = settings_from(args, config)
    if settings.propose and not solver_available():
        return fail("onboard", "--propose needs PyVRP: pip install '.[solver]'")
    try:
        bus = open_bus(config)
    except BusConnectError as error:
        # Its signing key or the roster unreadable: a failure, not a usage error.
        signing = isinstance(error.__cause__, CertError | RosterError)
        return fail("onboard", str(error), ExitCode.FAILED if signing else ExitCode.USAGE)
    try:
        process = OnboardProcess(settings, bus=bus)
    except BaseException:
        bus.close()
        raise
    with stop_on_signals(process.stop_requested.set):
        process.run()
    return ExitCode.OK


if __name__ == "__main__":
    sys.exit(main())
