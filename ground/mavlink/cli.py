"""`fleet mavlink`: the gateway's command line (docs/mavlink.md).

    fleet mavlink --out udpout:127.0.0.1:14550     # QGroundControl's default port
    fleet mavlink --out udpin:127.0.0.1:14551 --sysid 300=30 --mission-team live

It connects to the fleet as `ground-cli` does (the Zenoh flags), prints one line when it
serves, and runs until Ctrl-C or SIGTERM; then it says how much MAVLink input it
dropped and why. With `--signing-key FILE` every station must sign its frames (MAVLink 2
signing); on any address but loopback that is required, unless `--insecure`.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, TextIO

from fleet.mission.access import GROUND
from fleet.transport.bus import Bus
from fleet.transport.bus_factory import unwrap
from fleet.transport.cli import (
    ExitCode,
    add_query_timeout_argument,
    add_zenoh_arguments,
    fail,
    stop_on_signals,
)
from fleet.transport.command import (
    BusOptions,
    Command,
    OptionsError,
    add_command,
    fields_from,
    run_standalone,
)
from ground.host_check import is_loopback
from ground.mavlink.endpoint import Endpoint, EndpointError, InputDrops, parse_url
from ground.mavlink.fleet_link import FleetLink, TeamChoice
from ground.mavlink.gateway import Gateway
from ground.mavlink.requests import Requests
from ground.mavlink.signing import SigningKeyError, Verifier, load_keys
from ground.mavlink.sysids import SysIdError, SysIdMap, sysid_pair

log = logging.getLogger(__name__)

DEFAULT_OUT = "udpout:127.0.0.1:14550"
PROG = "fleet mavlink"


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    add_command(
        subparsers,
        "mavlink",
        MAVLINK,
        help="show every live UAV to MAVLink ground stations (QGroundControl, MAVProxy, MAVSDK)",
        doc=__doc__,
        configure=configure,
    )


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out",
        default=DEFAULT_OUT,
        metavar="URL",
        help="udpout:HOST:PORT (a station listening there), udpin:HOST:PORT or "
        "tcpin:HOST:PORT (stations connect here); default %(default)s",
    )
    parser.add_argument(
        "--sysid",
        type=sysid_pair,
        action="append",
        default=[],
        metavar="PICCOLO=SYS",
        help="show UAV PICCOLO as MAVLink system SYS (1-254); repeatable. Piccolo IDs "
        "1-254 are their own system id unless mapped",
    )
    parser.add_argument(
        "--signing-key",
        type=Path,
        metavar="FILE",
        help="MAVLink 2 signing: every frame a station sends must be signed with one of the "
        "stations' secrets in FILE (`NAME PASSPHRASE` a line, readable by you only); needed "
        "on any address but loopback",
    )
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="allow a non-loopback --out without --signing-key (anyone who reaches it "
        "commands the fleet)",
    )
    parser.add_argument(
        "--mission-team",
        choices=("uav", "live"),
        default="uav",
        help="who flies a mission uploaded to a UAV: that UAV alone (default), or every "
        "live UAV, the fleet assigning the items across them",
    )
    add_query_timeout_argument(parser)
    add_zenoh_arguments(parser)


def _identity_line(config_file: str | None) -> str:
    if config_file is None:
        return "Zenoh: no config file (an open fleet)"
    if Path(config_file).stem == GROUND:
        return f"Zenoh: holding the ground's identity ({config_file})"
    return (
        f"Zenoh: config {config_file}, not the ground's identity: a secure fleet refuses "
        "its missions and aborts"
    )


@dataclass(frozen=True, kw_only=True)
class MavlinkOptions(BusOptions):
    #: Where stations are: udpout:HOST:PORT, udpin:HOST:PORT or tcpin:HOST:PORT.
    out: str = DEFAULT_OUT
    sysids: SysIdMap
    #: Who flies a mission uploaded to a UAV: that UAV alone, or every live UAV.
    mission_team: Literal["uav", "live"] = "uav"
    #: The Zenoh config file it connects with (None: an open fleet), for its first line.
    zenoh_config: str | None = None
    #: The stations' secrets (`--signing-key`): every frame must be signed; None: unsigned.
    verifier: Verifier | None = None


def _verifier(out: str, signing_key: Path | None, insecure: bool) -> Verifier | None:
    """The stations' secrets (`--signing-key`); None without. SigningKeyError if the file
    cannot be used, EndpointError if a non-loopback --out has no secret and no --insecure."""
    if signing_key is not None:
        return Verifier(load_keys(signing_key))
    host = parse_url(out)[1][0]
    if not is_loopback(host) and not insecure:
        raise EndpointError(
            f"--out {out} is not loopback: anyone who reaches it could upload missions "
            "and RTL aircraft. Give the stations' secrets (--signing-key FILE) or add "
            "--insecure."
        )
    return None


def mavlink_options(args: argparse.Namespace) -> MavlinkOptions:
    """The options; two UAVs on one system id, an unusable signing-key file, or a
    non-loopback --out without one (and no --insecure) is a usage error."""
    try:
        sysids = SysIdMap(args.sysid)
        verifier = _verifier(args.out, args.signing_key, args.insecure)
    except (SysIdError, SigningKeyError, EndpointError) as error:
        raise OptionsError(f"error: {error}") from None
    return fields_from(MavlinkOptions, args, sysids=sysids, verifier=verifier)


def run(bus: Bus, options: MavlinkOptions, out: TextIO) -> int:
    drops = InputDrops()
    try:
        endpoint = Endpoint(options.out, drops, verifier=options.verifier)
    except EndpointError as error:
        return fail(PROG, f"error: {error}")
    team = TeamChoice.LIVE if options.mission_team == "live" else TeamChoice.UAV
    stop = threading.Event()
    try:
        with stop_on_signals(stop.set):
            # Connected once the endpoint is open: a bad or taken one is said first.
            return _serve(options, unwrap(bus), endpoint, team, stop, out)
    finally:
        endpoint.close()
        if drops.total():
            print(f"{PROG}: dropped {drops.total()} MAVLink input(s): {drops.counts()}", file=out)


def _serve(
    args: MavlinkOptions,
    bus: Bus,
    endpoint: Endpoint,
    team: TeamChoice,
    stop: threading.Event,
    out: TextIO,
) -> int:
    fleet = FleetLink(bus, args.key_space, args.query_timeout)
    gateway = Gateway(bus, args.key_space, fleet, endpoint, args.sysids)
    requests = Requests(gateway, team)
    with gateway.view:
        refresher = threading.Thread(
            target=gateway.refresh_forever,
            args=(stop, args.query_timeout),
            name="mavlink-refresh",
            daemon=True,
        )
        refresher.start()
        print(_identity_line(args.zenoh_config), file=out, flush=True)
        signed = (
            f"signed ({len(endpoint.verifier.keys)} station secret(s))"
            if endpoint.verifier is not None
            else "unsigned"
        )
        print(
            f"{PROG}: serving on {endpoint.url} (local port {endpoint.local_port}, {signed}), "
            f"missions to {'every live UAV' if team is TeamChoice.LIVE else 'the UAV alone'}",
            file=out,
            flush=True,
        )
        try:
            gateway.run(stop, requests.handle, requests.tick)
        finally:
            stop.set()
            gateway.workers.shutdown(wait=True, cancel_futures=True)
            refresher.join(timeout=max(5.0, 3 * args.query_timeout))
            fleet.close()
    return ExitCode.OK


MAVLINK = Command(mavlink_options, run)


if __name__ == "__main__":
    sys.exit(run_standalone(PROG, __doc__ or "", configure, MAVLINK))
