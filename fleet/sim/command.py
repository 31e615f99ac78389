"""`fleet sim`: run simulated Piccolo autopilots for a scenario (docs/simulator.md).

Prints one line per aircraft once every port is listening, then ``ready``::

    uav 112 program=socket://127.0.0.1:5760 payload=socket://127.0.0.1:5860 ground=socket://127.0.0.1:5960
    ready

then serves until SIGTERM or SIGINT, and exits 0 after closing every socket.
Runnable on its own as ``python -m fleet.sim.command``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TextIO

from fleet.files.zones_file import read_zones
from fleet.sim.autopilot import (
    DEFAULT_TELEMETRY_HZ,
    MAX_TELEMETRY_HZ,
    AutopilotSettings,
    SimulatedAutopilot,
)
from fleet.sim.flight_model import Dynamics, FlightModelError
from fleet.sim.guidance import DEFAULT_ACCEPTANCE_RADIUS
from fleet.sim.scenario import ScenarioError, resolve_scenario, shipped_scenario_names
from fleet.sim.server import (
    DEFAULT_GROUND_PORT,
    DEFAULT_HOST,
    DEFAULT_PAYLOAD_PORT,
    DEFAULT_PROGRAM_PORT,
    DEFAULT_SPEEDUP,
    SimServer,
)
from fleet.sim.truth_log import TRUTH_PERIOD_MS, TruthLog
from fleet.transport.cli import (
    ExitCode,
    enum_option,
    fail,
    non_negative_float,
    positive_float,
    stop_on_signals,
    tcp_port,
)
from fleet.transport.command import LocalCommand, add_command, options_from, run_standalone

logger = logging.getLogger(__name__)


def configure_parser(parser: argparse.ArgumentParser) -> None:
    """Add the `fleet sim` arguments to `parser`."""
    parser.add_argument(
        "scenario",
        metavar="SCENARIO",
        help="a scenario TOML file, or the name of a shipped scenario "
        f"({', '.join(_shipped_names())})",
    )
    parser.add_argument(
        "--uav",
        type=int,
        metavar="ID",
        help="simulate only this Piccolo ID (one aircraft, e.g. a container per UAV); "
        "default: every aircraft of the scenario",
    )
    _add_listen_arguments(parser)
    parser.add_argument(
        "--speedup",
        type=non_negative_float,
        default=DEFAULT_SPEEDUP,
        metavar="K",
        help="simulated seconds per wall second; 0 runs as fast as possible (%(default)s)",
    )
    parser.add_argument(
        "--telemetry-hz",
        type=positive_float,
        default=DEFAULT_TELEMETRY_HZ,
        metavar="F",
        help=f"telemetry rate in simulated Hz, at most {MAX_TELEMETRY_HZ:g} (%(default)s)",
    )
    parser.add_argument(
        "--pty",
        action="store_true",
        help="serve the program and payload ports on pseudo-terminals (paths printed) "
        "instead of TCP",
    )
    parser.add_argument(
        "--acceptance-radius",
        type=positive_float,
        default=DEFAULT_ACCEPTANCE_RADIUS,
        metavar="M",
        help="distance (m) at which a waypoint counts as reached (%(default)s)",
    )
    parser.add_argument(
        "--no-fly",
        metavar="ZONES.geojson",
        help="no-fly zones (GeoJSON) whose every incursion is logged as an error "
        "(default: the scenario's no_fly file, if any)",
    )
    parser.add_argument(
        "--truth-log",
        metavar="FILE",
        help="write every aircraft's true position (the simulator's own state) every "
        f"{TRUTH_PERIOD_MS} simulated ms to FILE, as CSV lines sim_ms,uav,lat,lon,alt",
    )
    add_dynamics_argument(parser)


def add_dynamics_argument(parser: argparse.ArgumentParser) -> None:
    """`--dynamics`: the flight model the simulated aircraft fly."""
    enum_option(
        parser,
        "--dynamics",
        Dynamics.KINEMATIC,
        "the aircraft's flight model: kinematic, the project's point dynamics "
        "(default), or jsbsim, JSBSim's J3Cub behind the same autopilot "
        "(pip install 'uav-fleet[jsbsim]')",
    )


def _add_listen_arguments(parser: argparse.ArgumentParser) -> None:
    """The address and the first TCP port of each of the three serial channels."""
    parser.add_argument("--host", default=DEFAULT_HOST, help="address to listen on (%(default)s)")
    parser.add_argument(
        "--program-port",
        type=tcp_port,
        default=DEFAULT_PROGRAM_PORT,
        metavar="P",
        help="first program port; aircraft i gets P+i; 0 picks free ports (%(default)s)",
    )
    parser.add_argument(
        "--payload-port",
        type=tcp_port,
        default=DEFAULT_PAYLOAD_PORT,
        metavar="P",
        help="first payload port, onboard side (%(default)s)",
    )
    parser.add_argument(
        "--ground-port",
        type=tcp_port,
        default=DEFAULT_GROUND_PORT,
        metavar="P",
        help="first ground port, the ground side of the payload pipe (%(default)s)",
    )


def _shipped_names() -> list[str]:
    try:
        return shipped_scenario_names()
    except ScenarioError:
        return []


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register the `sim` subcommand."""
    return add_command(
        subparsers,
        "sim",
        SIM,
        help="simulated Piccolo autopilots (hardware-in-the-loop stand-in)",
        description="Run simulated Piccolo autopilots for a scenario, serving each "
        "aircraft's program, payload and ground ports.",
        configure=configure_parser,
    )


@dataclass(frozen=True, kw_only=True)
class SimOptions:
    #: A scenario TOML file, or a shipped scenario's name.
    scenario: str
    #: Simulate only this Piccolo ID (None: every aircraft of the scenario).
    uav: int | None = None
    host: str = DEFAULT_HOST
    program_port: int = DEFAULT_PROGRAM_PORT
    payload_port: int = DEFAULT_PAYLOAD_PORT
    ground_port: int = DEFAULT_GROUND_PORT
    speedup: float = DEFAULT_SPEEDUP
    telemetry_hz: float = DEFAULT_TELEMETRY_HZ
    pty: bool = False
    acceptance_radius: float = DEFAULT_ACCEPTANCE_RADIUS
    #: No-fly zones (GeoJSON) whose incursions are logged (None: the scenario's).
    no_fly: str | None = None
    #: The aircraft's flight model (fleet.sim.flight_model).
    dynamics: Dynamics = Dynamics.KINEMATIC
    #: Where to write every aircraft's true position (None: nowhere).
    truth_log: str | None = None


def _build(args: SimOptions) -> list[SimulatedAutopilot]:
    scenario = resolve_scenario(args.scenario)
    uavs = scenario.uavs if args.uav is None else (scenario.uav(args.uav),)
    settings = AutopilotSettings(
        telemetry_hz=args.telemetry_hz,
        acceptance_radius=args.acceptance_radius,
        limits=scenario.limits,
        wind=scenario.wind,
        zones=read_zones(args.no_fly) if args.no_fly else scenario.zones,
        dynamics=args.dynamics,
    )
    logger.info(
        "scenario %s (%s): %d aircraft (%s dynamics), wind north %.1f east %.1f m/s%s, "
        "%d no-fly zones",
        scenario.name,
        scenario.source,
        len(uavs),
        args.dynamics.value,
        scenario.wind.north,
        scenario.wind.east,
        "" if scenario.weather.steady else " drifting and gusting",
        len(settings.zones),
    )
    return [SimulatedAutopilot(uav, settings, scenario.weather) for uav in uavs]


def run(args: SimOptions, out: TextIO) -> int:
    """Run the simulator until SIGTERM or SIGINT; return the exit status."""
    try:
        autopilots = _build(args)
        truth = TruthLog.to_file(args.truth_log) if args.truth_log is not None else None
        server = SimServer(
            autopilots,
            host=args.host,
            program_port=args.program_port,
            payload_port=args.payload_port,
            ground_port=args.ground_port,
            speedup=args.speedup,
            use_pty=args.pty,
            truth=truth,
        )
    except (ScenarioError, FlightModelError, ValueError) as error:
        return fail("fleet sim", str(error))
    except OSError as error:
        return fail("fleet sim", f"cannot open {error.filename}: {error.strerror}")
    # Handlers first: a launcher may send SIGTERM as soon as it has read `ready`.
    with server, stop_on_signals(server.stop):
        try:
            endpoints = server.open()
        except OSError as error:
            return fail("fleet sim", str(error.strerror or error), ExitCode.FAILED)
        for endpoint in endpoints:
            print(endpoint.line(), file=out)
        print("ready", file=out, flush=True)
        logger.info("simulating at speedup %g", args.speedup)
        server.run()
    logger.info("stopped at simulated time %.1f s", server.time_ms / 1000.0)
    if autopilots[0].settings.zones:
        logger.info(
            "no-fly incursions: %s",
            ", ".join(f"UAV {a.piccolo_id}: {a.zone_log.incursions}" for a in autopilots),
        )
    return ExitCode.OK


def main(argv: Sequence[str] | None = None) -> int:
    return run_standalone(
        "fleet sim", "Run simulated Piccolo autopilots for a scenario.", configure_parser, SIM, argv
    )


SIM = LocalCommand(options_from(SimOptions), run)


if __name__ == "__main__":
    sys.exit(main())
