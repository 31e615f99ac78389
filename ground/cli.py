"""`ground-cli`: the mission manager (thesis chapter 3) on the command line.

Connects as a Zenoh client to the fleet's router (--connect, else $FLEET_ZENOH_CONNECT,
else tcp/127.0.0.1:7447), or as a Zenoh config file says (--zenoh-config FILE or
$FLEET_ZENOH_CONFIG). Exit status: 0 success; 1 the operation failed (bad targets
file, no UAV, mission not committed or not agreed in time); 2 usage error, bad Zenoh
config or no router.
"""

from __future__ import annotations

import argparse
import logging
import sys

from fleet.mission.objective import Objective
from fleet.mission.target_checks import DEFAULT_MAX_REACH_M
from fleet.transport import bus_codec
from fleet.transport.cli import (
    ExitCode,
    add_query_timeout_argument,
    add_verbose_argument,
    add_zenoh_arguments,
    bounded_int,
    enum_option,
    non_negative_float,
    piccolo_id,
    piccolo_ids,
    positive_float,
    setup_logging,
)
from fleet.transport.command import run_parsed, set_handler
from ground import (
    fleet_commands,
    mission_change_command,
    mission_commands,
    routers_command,
    send_command,
    targets_command,
)
from ground.gui import cli as gui_cli
from ground.mission_ids import MAX_MISSION_ID

log = logging.getLogger("ground")

# ---- argument types -------------------------------------------------------------------------
_mission_id = bounded_int(0, MAX_MISSION_ID, "mission id")


# ---- the parser ---------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ground-cli",
        description="Mission manager for a fleet of Piccolo UAVs over Zenoh.",
        epilog=__doc__.split("\n", 2)[2] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_zenoh_arguments(parser)
    add_query_timeout_argument(parser)
    add_verbose_argument(parser)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    _add_uavs(commands)
    _add_send_targets(commands)
    _add_watch(commands)
    _add_opm(commands)
    _add_abort(commands)
    _add_mission(commands)
    _add_mission_changes(commands)
    _add_targets(commands)
    _add_keys(commands)
    _add_routers(commands)
    gui_cli.add_parser(commands)
    return parser


def _add_uavs(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`uavs`: the live UAVs."""
    uavs = commands.add_parser("uavs", help="list the live UAVs")
    uavs.add_argument("--json", action="store_true", help="a JSON list of objects")
    set_handler(uavs, fleet_commands.UAVS)


def _add_routers(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`routers`: each secure router's refused connections."""
    routers = commands.add_parser("routers", help="each secure router's refused connections")
    routers.add_argument("--json", action="store_true", help="a JSON list of objects")
    set_handler(routers, routers_command.ROUTERS)


def _add_send_targets(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`send-targets`: Send Targets (thesis 3.1.4)."""
    send = commands.add_parser("send-targets", help="send a targets file to the team")
    send.add_argument("file", metavar="FILE", help="targets file (thesis format, 24 bytes each)")
    send.add_argument(
        "--team",
        type=piccolo_ids,
        metavar="ID,ID,...",
        help="Piccolo IDs of the team (default: every live UAV)",
    )
    send.add_argument(
        "--wait",
        action="store_true",
        help="follow the mission until every UAV has committed its assignment",
    )
    send.add_argument(
        "--timeout",
        type=positive_float,
        default=60.0,
        metavar="S",
        help="how long --wait waits (default 60 s)",
    )
    send.add_argument(
        "--deadline",
        type=positive_float,
        metavar="S",
        help="how long each UAV waits for its teammates' results (default: 10 s, longer "
        "for a large team: 2 x (planning budget + 0.1 s per UAV))",
    )
    send.add_argument(
        "--mission",
        type=_mission_id,
        metavar="M",
        help="mission id (default: one more than the highest mission seen)",
    )
    send.add_argument(
        "--max-reach-km",
        type=positive_float,
        default=DEFAULT_MAX_REACH_M / 1000.0,
        metavar="KM",
        help="refuse a target farther than this from every team UAV with a fix "
        "(default %(default)g km)",
    )
    send.add_argument(
        "--force",
        action="store_true",
        help="send all the same a target set that fails the checks (two targets within the "
        "acceptance radius, beyond reach, the far side of the Earth) or a --team naming a "
        "UAV that is not live",
    )
    send.add_argument(
        "--no-fly",
        metavar="ZONES.geojson",
        help="no-fly zones (GeoJSON Polygon/MultiPolygon) every route keeps out of; a "
        "target inside one is refused and nothing is sent (--force does not override it)",
    )
    enum_option(
        send,
        "--objective",
        Objective.GREEDY,
        "what the team's plan optimises: greedy (the thesis rule, extended to "
        "queues), min-sum (the total of arrival times), min-max (the time until the last "
        "target is reached); default %(default)s",
    )
    send.add_argument(
        "--propose",
        action="store_true",
        help="propose a plan solved by PyVRP (pip install '.[solver]') once the team's "
        "results are in: every UAV verifies it and adopts it if it is valid and better "
        "than its own (min-sum and min-max only)",
    )
    send.add_argument(
        "--proposers",
        type=piccolo_ids,
        default=(),
        metavar="ID,...",
        help="UAVs that propose a plan, each solved on board (`fleet up --proposers`): the "
        "UAVs wait for each one's proposal, verify it and adopt the best (with --propose, "
        "the ground's too; min-sum and min-max only)",
    )
    send.add_argument("--json", action="store_true", help="print the outcome as one JSON object")
    set_handler(send, send_command.SEND_TARGETS)


def _add_watch(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`watch`: the table and the status box."""
    watch_cmd = commands.add_parser("watch", help="live table of the fleet and its status box")
    watch_cmd.add_argument(
        "--count", type=bounded_int(1, what="count"), metavar="N", help="stop after N tables"
    )
    watch_cmd.add_argument(
        "--duration", type=positive_float, metavar="S", help="stop after S seconds"
    )
    watch_cmd.add_argument(
        "--interval", type=positive_float, default=1.0, metavar="S", help="table period (1 s)"
    )
    set_handler(watch_cmd, fleet_commands.WATCH)


def _add_opm(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`opm`: the onboard planning module on or off."""
    opm = commands.add_parser("opm", help="turn a UAV's onboard planning module on or off")
    opm.add_argument("uav", type=piccolo_id, metavar="ID")
    opm.add_argument("state", choices=("on", "off"))
    opm.add_argument(
        "--status-rate",
        type=non_negative_float,
        default=1.0,
        metavar="HZ",
        help="status messages a second; 0: only on change (default 1)",
    )
    set_handler(opm, fleet_commands.OPM)


def _add_mission_id(parser: argparse.ArgumentParser) -> None:
    """`--mission M`: which mission a command is about."""
    parser.add_argument(
        "--mission", type=_mission_id, metavar="M", help="mission id (default: the latest seen)"
    )


def _add_abort(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`abort`: end a mission."""
    abort = commands.add_parser("abort", help="abort the current mission (team or one UAV)")
    _add_mission_id(abort)
    abort.add_argument(
        "--uav",
        type=piccolo_id,
        metavar="ID",
        help="abort this UAV alone; its teammates fly on (default: the whole team)",
    )
    set_handler(abort, mission_commands.ABORT)


def _add_mission(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`mission`: a mission's status as the fleet reports it now."""
    status = commands.add_parser(
        "mission", help="a mission's targets: reached (by whom), assigned or unserved"
    )
    _add_mission_id(status)
    status.add_argument(
        "--until-reached",
        type=positive_float,
        metavar="S",
        help="first wait up to S seconds for every target to be reached; exit 0 only if so",
    )
    status.add_argument("--json", action="store_true", help="print it as one JSON object")
    set_handler(status, mission_commands.MISSION)


def _add_change_flags(parser: argparse.ArgumentParser) -> None:
    _add_mission_id(parser)
    parser.add_argument(
        "--timeout",
        type=positive_float,
        default=mission_change_command.ACK_WAIT_S,
        metavar="S",
        help="wait up to S seconds for every live team UAV to acknowledge it (default %(default)g)",
    )
    parser.add_argument("--json", action="store_true", help="print the outcome as one JSON object")


def _add_mission_changes(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`add-targets`, `remove-targets`: the mission changed in flight."""
    add = commands.add_parser(
        "add-targets",
        help="add targets to a mission in flight (the team re-plans what is left)",
    )
    add.add_argument("file", metavar="FILE", help="a targets file (see `targets show`)")
    _add_change_flags(add)
    set_handler(add, mission_change_command.ADD_TARGETS)
    remove = commands.add_parser(
        "remove-targets",
        help="remove targets from a mission in flight: never flown from then on",
    )
    remove.add_argument(
        "indexes", nargs="+", type=bounded_int(0, 0xFFFF, "target index"), metavar="INDEX"
    )
    _add_change_flags(remove)
    set_handler(remove, mission_change_command.REMOVE_TARGETS)


def _add_targets(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`targets make|show`: Save and Load Targets."""
    targets = commands.add_parser("targets", help="make or show a targets file")
    targets_commands = targets.add_subparsers(dest="targets_command", required=True)
    make = targets_commands.add_parser(
        "make",
        help="write a targets file (Save Targets)",
        description="Write a targets file. Put `--` before a target starting with '-'.",
    )
    make.add_argument("--out", required=True, metavar="FILE")
    make.add_argument("targets", nargs="+", metavar="LAT,LON,ALT")
    set_handler(make, targets_command.MAKE)
    show = targets_commands.add_parser("show", help="read a targets file (Load Targets)")
    show.add_argument("file", metavar="FILE")
    show.add_argument("--json", action="store_true")
    set_handler(show, targets_command.SHOW)


def _add_keys(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`keys`: the key space."""
    keys_cmd = commands.add_parser("keys", help="the key space and each key's latest value")
    keys_cmd.add_argument(
        "expr",
        nargs="?",
        default=None,
        metavar="EXPR",
        help="(everything under the key prefix: fleet/**)",
    )
    keys_cmd.add_argument("--admin", action="store_true", help="the router's admin space too")
    keys_cmd.add_argument(
        "--window",
        type=non_negative_float,
        default=1.0,
        metavar="S",
        help="how long to listen for published-only keys (default 1 s)",
    )
    keys_cmd.add_argument("--full", action="store_true", help="do not shorten long values")
    keys_cmd.add_argument("--json", action="store_true", help="a JSON list of objects")
    set_handler(keys_cmd, fleet_commands.KEYS)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose, base=logging.WARNING)
    try:
        return run_parsed(args, "ground-cli")
    except KeyboardInterrupt:
        return ExitCode.INTERRUPTED
    finally:
        _report_drops()


def _report_drops() -> None:
    """Say how many bus messages were refused (each was logged when it arrived)."""
    if bus_codec.DROPPED.total():
        reasons = ", ".join(f"{n} {why}" for why, n in sorted(bus_codec.DROPPED.counts().items()))
        log.warning("refused %d message(s) from the bus: %s", bus_codec.DROPPED.total(), reasons)


if __name__ == "__main__":
    sys.exit(main())
