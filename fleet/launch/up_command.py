"""`fleet up`: a whole simulated fleet on this machine (docs/ground.md).

`fleet up (SCENARIO | --uavs N)` starts the router, the simulator and one onboard per
UAV (`fleet.launch.launcher`), waits until every UAV is ready, prints how to connect,
and runs until Ctrl-C or SIGTERM, then stops everything. `fleet demo` (programs.demo)
builds on it.
"""

from __future__ import annotations

import argparse
import ipaddress
import logging
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from fleet.files.certs import endpoint_host
from fleet.launch.children import Child
from fleet.launch.launcher import DEFAULT_START_TIMEOUT_S, Fleet, FleetSpec, LaunchError
from fleet.launch.ring import ring_scenario
from fleet.launch.supervisor import ChildLost, RestartPolicy, supervise
from fleet.launch.topology import Topology
from fleet.mission.access import GROUND
from fleet.mission.key_registry import DEFAULT_PREFIX
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.recording.streams import Stall, short_streams
from fleet.sim.command import add_dynamics_argument
from fleet.sim.flight_model import Dynamics, FlightModelError, require
from fleet.sim.scenario import ScenarioError, resolve_scenario
from fleet.transport.cli import (
    PREFIX_ENV,
    ExitCode,
    add_key_prefix_argument,
    bounded_int,
    enum_option,
    fail,
    piccolo_ids,
    positive_float,
    stop_on_signals,
)
from fleet.transport.command import LocalCommand, OptionsError, add_command, fields_from
from fleet.transport.zenoh_config import CONFIG_ENV, CONNECT_ENV, DEFAULT_ROUTER

log = logging.getLogger(__name__)

#: The recording's file name in the run's log folder.
RECORDING_NAME = "fleet.mcap"

#: Where `--gui` serves the page unless told (`ground-cli gui`'s default).
DEFAULT_GUI_LISTEN = "127.0.0.1:8321"


def start_gui(fleet: Fleet, listen: str | None) -> str | None:
    """Start the page's server if asked and wait until it serves; the line that says
    where it is (the port it bound: `--gui 127.0.0.1:0` takes a free one)."""
    if listen is None:
        return None
    child, url = fleet.start_gui(listen)
    return f"Mission Manager page: {url} (log {child.log_path})"


def common_arguments(parser: argparse.ArgumentParser, speedup: float) -> None:
    add_key_prefix_argument(parser)
    parser.add_argument(
        "--speedup",
        type=positive_float,
        default=speedup,
        metavar="K",
        help="simulated seconds per wall second (default %(default)g)",
    )
    parser.add_argument(
        "--log-dir",
        type=Path,
        metavar="DIR",
        help="where each process's log goes (default: a new temporary directory)",
    )
    parser.add_argument(
        "--gui",
        nargs="?",
        const=DEFAULT_GUI_LISTEN,
        metavar="HOST:PORT",
        help=f"also serve the Mission Manager's page (`ground-cli gui`), on {DEFAULT_GUI_LISTEN} "
        "unless given (port 0: a free port, which the banner says)",
    )
    parser.add_argument(
        "--start-timeout",
        type=positive_float,
        default=DEFAULT_START_TIMEOUT_S,
        metavar="S",
        help="how long to wait for every UAV to come up (default %(default)g s)",
    )
    parser.add_argument(
        "--no-record",
        dest="record",
        action="store_false",
        help=f"do not record the run (default: record it to {RECORDING_NAME} in the log folder)",
    )
    parser.add_argument(
        "--no-fork-server",
        dest="fork_onboards",
        action="store_false",
        help="start each onboard as its own `python -m onboard.main` (default: fork them "
        "from one process that imported it, so they share its memory)",
    )


@dataclass(frozen=True, kw_only=True)
class LaunchOptions:
    """What `fleet up` and `fleet demo` both take (`common_arguments`)."""

    key_space: KeySpace = DEFAULT_SPACE
    speedup: float = 1.0
    log_dir: Path | None = None
    #: Also serve the page there (`ground-cli gui`); None: not.
    gui: str | None = None
    start_timeout: float = DEFAULT_START_TIMEOUT_S
    #: Record the run to RECORDING_NAME in its log folder.
    record: bool = True
    fork_onboards: bool = True


def recording_path(fleet: Fleet, options: LaunchOptions) -> Path | None:
    """Where the run is recorded (in its log folder), or None with --no-record."""
    return fleet.log_dir / RECORDING_NAME if options.record else None


def add_up_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    parser = add_command(
        subparsers,
        "up",
        UP,
        help="run a simulated fleet: router, simulator and one onboard per UAV",
        description="Run a simulated fleet on this machine until Ctrl-C or SIGTERM.",
    )
    # Not required by argparse: `fleet up --gui head_on` reads the scenario as the page's
    # address, and run_up says so rather than argparse's 'SCENARIO or --uavs is required'.
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "scenario", nargs="?", metavar="SCENARIO", help="a shipped scenario name or a TOML file"
    )
    which.add_argument(
        "--uavs",
        type=bounded_int(1, 500, "number of UAVs"),
        metavar="N",
        help="N generated UAVs (ids 101..) on a ring",
    )
    parser.add_argument(
        "--listen",
        default=DEFAULT_ROUTER,
        metavar="ENDPOINT",
        help="the router's endpoint (default %(default)s; port 0: a free port, which the "
        "banner says)",
    )
    parser.add_argument(
        "--secure",
        type=Path,
        metavar="DIR",
        help="the secure profile: mutual TLS and access control with the identities in DIR "
        "(`fleet certs make`); needs a tls/ --listen endpoint",
    )
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="allow an open (not tls/) --listen endpoint beyond loopback: anyone who reaches "
        "it can command the fleet",
    )
    enum_option(
        parser,
        "--topology",
        Topology.STAR,
        "star: one router (default); router-per-uav: a router per UAV on a ring, "
        "each also linked to the ground's router (docs/security.md)",
    )
    parser.add_argument(
        "--restart",
        action="store_true",
        help="start a UAV's onboard module again when it dies (back-off 1 s, doubling to "
        "30 s); without it a dead module is reported and the rest of the fleet flies on",
    )
    parser.add_argument(
        "--proposers",
        type=piccolo_ids,
        default=(),
        metavar="ID,...",
        help="UAVs whose onboard solves and proposes plans (PyVRP: pip install '.[solver]') "
        "for the missions that name them (`ground-cli send-targets --proposers`)",
    )
    add_dynamics_argument(parser)
    common_arguments(parser, speedup=1.0)
    return parser


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `up`."""
    add_up_parser(subparsers)


def scenario_info(name: str) -> tuple[str, Path | None]:
    """A scenario's description and targets file; raises ScenarioError if it is bad."""
    scenario = resolve_scenario(name)
    return scenario.description, scenario.targets_path


# ---- fleet up ---------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class UpOptions(LaunchOptions):
    #: A shipped scenario name or a TOML file (None: `uavs` generated ones).
    scenario: str | None = None
    uavs: int | None = None
    listen: str = DEFAULT_ROUTER
    secure: Path | None = None
    insecure: bool = False
    topology: Topology = Topology.STAR
    restart: bool = False
    #: The simulated aircraft's flight model (`fleet sim --dynamics`).
    dynamics: Dynamics = Dynamics.KINEMATIC
    #: UAVs whose onboard proposes plans (`fleet-onboard --propose`).
    proposers: tuple[int, ...] = ()


def up_options(args: argparse.Namespace) -> UpOptions:
    """The options of `fleet up`; an open router beyond loopback without --insecure, or
    neither a scenario nor --uavs, is a usage error. `--gui NAME` (no HOST:PORT) took
    the scenario as the page's address: it is moved back."""
    problem = open_listener_problem(args.listen, args.insecure)
    if problem is not None:
        raise OptionsError(problem)
    scenario, gui = args.scenario, args.gui
    if scenario is None and args.uavs is None:
        if gui is None or ":" in gui:
            raise OptionsError("give a SCENARIO (a shipped name or a TOML file) or --uavs N")
        scenario, gui = gui, DEFAULT_GUI_LISTEN
    return fields_from(UpOptions, args, scenario=scenario, gui=gui)


def run_up(options: UpOptions, out: TextIO) -> int:
    stop = threading.Event()
    with stop_on_signals(stop.set):
        return _run_up(options, stop)


def open_listener_problem(listen: str, insecure: bool) -> str | None:
    """Why `listen` may not be used without `--insecure`, or None: an open (non-TLS)
    router reachable beyond this host lets anyone who reaches it command the fleet."""
    if insecure or listen.startswith("tls/"):
        return None
    host = endpoint_host(listen)
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if loopback:
        return None
    return (
        f"--listen {listen} is an open router beyond this host: anyone who reaches it can "
        "command the fleet. Use the secure profile (--secure DIR with a tls/ endpoint), "
        "or say --insecure"
    )


def _run_up(args: UpOptions, stop: threading.Event) -> int:
    try:
        require(args.dynamics)
    except FlightModelError as error:
        return fail("fleet up", str(error))
    spec = FleetSpec(
        scenario="",
        listen=args.listen,
        speedup=args.speedup,
        log_dir=args.log_dir,
        start_timeout_s=args.start_timeout,
        secure_dir=args.secure,
        topology=args.topology,
        key_space=args.key_space,
        fork_onboards=args.fork_onboards,
        dynamics=args.dynamics,
        proposers=frozenset(args.proposers),
    )
    fleet = Fleet(spec, stop_requested=stop, progress=_print_progress)
    if args.uavs is not None:
        path = fleet.log_dir / f"ring-{args.uavs}.toml"
        path.write_text(ring_scenario(args.uavs))
        spec.scenario = str(path)
    else:
        assert args.scenario is not None  # up_options: a scenario or --uavs
        spec.scenario = args.scenario
    spec.record = recording_path(fleet, args)
    try:
        description, targets_path = scenario_info(spec.scenario)
    except ScenarioError as error:
        return fail("fleet up", str(error))
    print(f"fleet up: starting {description or spec.scenario} (logs in {fleet.log_dir})")
    if spec.record is not None:
        print(f"fleet up: recording to {spec.record} (fleet replay/plot/report read it)")
    try:
        with fleet:
            gui_line = start_gui(fleet, args.gui)
            _print_banner(fleet, targets_path, gui_line)

            def on_death(child: Child) -> None:
                print(
                    f"fleet up: {child.name} exited with status {child.process.returncode}; "
                    f"stopping the fleet. Last lines of {child.log_path}:\n{child.tail()}",
                    file=sys.stderr,
                )

            policy = RestartPolicy() if args.restart else None
            stopped_cleanly = supervise(fleet, stop, on_death, _print_lost, policy, _print_stall)
            print("fleet up: stopping", flush=True)
    except LaunchError as error:
        if stop.is_set():
            return fail("fleet up", "stopped while starting", ExitCode.INTERRUPTED)
        return fail("fleet up", str(error), ExitCode.FAILED)
    print("fleet up: stopped")
    if fleet.recording_failure is not None:
        # The fleet flew on, but the recording it promised is cut short: not a success.
        print(f"fleet up: the recording stopped early: {fleet.recording_failure}", file=sys.stderr)
        return ExitCode.FAILED
    if spec.record is not None:
        print(f"fleet up: recorded to {spec.record}")
        for line in short_streams(fleet.recorded_telemetry):
            log.warning("%s", line)
            print(f"fleet up: {line}")
    return ExitCode.OK if stopped_cleanly else ExitCode.FAILED


def _print_lost(lost: ChildLost) -> None:
    then = "the rest of the fleet flies on"
    if lost.restart_at is not None:
        then += f"; restarting it in {max(0.0, lost.restart_at - time.monotonic()):.0f} s"
    print(
        f"fleet up: {lost.child.name} exited with status {lost.status}; {then}. "
        f"Last lines of {lost.child.log_path}:\n{lost.child.tail()}",
        file=sys.stderr,
        flush=True,
    )


def _print_stall(stall: Stall) -> None:
    log.warning("%s", stall)
    print(f"fleet up: {stall}", flush=True)


def _print_progress(text: str) -> None:
    print(f"fleet up: {text}", flush=True)


def _print_banner(fleet: Fleet, targets_path: Path | None, gui_line: str | None) -> None:
    ids = ", ".join(map(str, fleet.uav_ids))
    targets = str(targets_path) if targets_path is not None else "TARGETS.bin"
    space = fleet.spec.key_space
    prefix = [f"  export {PREFIX_ENV}={space.prefix}"] if space.prefix != DEFAULT_PREFIX else []
    if fleet.secure is not None:
        identity = fleet.secure.identity(GROUND).client_config
        connect = [f"  export {CONFIG_ENV}={identity}", f"  export {CONNECT_ENV}={fleet.connect}"]
    else:
        connect = [f"  export {CONNECT_ENV}={fleet.connect}"]
    if fleet.uav_routers:
        routers = ", ".join(f"{uav} {where}" for uav, where in fleet.uav_routers.items())
        connect.append(f"  (UAV routers: {routers}; any works as a fallback --connect)")
    lines = [
        f"fleet up: {len(fleet.uav_ids)} UAV(s) alive ({ids}); router on "
        f"{fleet.listening or fleet.spec.listen}",
        "Connect from another terminal:",
        *connect,
        *prefix,
        "  ground-cli uavs",
        "  ground-cli watch",
        f"  ground-cli send-targets {targets} --wait",
        "  ground-cli keys",
        *([gui_line] if gui_line else []),
        "Ctrl-C (or SIGTERM) stops the fleet.",
    ]
    print("\n".join(lines), flush=True)


UP = LocalCommand(up_options, run_up)
