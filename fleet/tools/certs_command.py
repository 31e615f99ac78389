"""`fleet certs make DIR --uavs 74,112 --ground`: the fleet's identities for mutual TLS.

Writes `DIR/ca.pem`, and per identity NAME (`router`, `ground`, `uav-74`, and
`router-74` for UAV 74's own router in a router-per-UAV mesh, ...) `DIR/NAME.pem`,
`DIR/NAME.key`, `DIR/NAME.json5` (a Zenoh client configuration for `--zenoh-config`) and
`DIR/NAME.sign` (its key for signed commands), and `DIR/signers.json` (the roster of
signers, signed by the CA). Only router identities may serve. A DIR that already has a
CA is refused unless `--force`. `fleet certs revoke DIR uav-74` withdraws an identity.
See `fleet.files.certs`, `fleet.files.signers` and docs/security.md.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from fleet.files.certs import DEFAULT_VALID_DAYS, CertError, write_identities
from fleet.files.signers import (
    ROSTER_FILE,
    RosterError,
    revoke,
    roster_document,
    signing_key_path,
)
from fleet.mission.access import GROUND, ROUTER, uav_identity, uav_router_identity
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.transport.cli import (
    ExitCode,
    add_key_prefix_argument,
    bounded_int,
    fail,
    piccolo_ids,
)
from fleet.transport.command import LocalCommand, options_from, set_handler
from fleet.transport.zenoh_config import ZenohConfigError, build_config, endpoints

DEFAULT_SECURE_ROUTER = "tls/127.0.0.1:7447"


def identity_names(uav_ids: tuple[int, ...], ground: bool) -> list[str]:
    """The router always, the ground when asked, then one identity per UAV and one for
    each UAV's own router (used by `fleet up --topology router-per-uav --secure`)."""
    return [
        ROUTER,
        *([GROUND] if ground else []),
        *(uav_identity(u) for u in uav_ids),
        *(uav_router_identity(u) for u in uav_ids),
    ]


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    certs = subparsers.add_parser("certs", help="identities for the secure (mTLS) profile")
    actions = certs.add_subparsers(dest="certs_command", required=True, metavar="ACTION")
    make = actions.add_parser(
        "make",
        help="a CA, and a certificate, key and Zenoh client config per identity",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    make.add_argument("directory", type=Path, metavar="DIR")
    make.add_argument(
        "--uavs", type=piccolo_ids, default=(), metavar="ID,ID", help="the UAVs' Piccolo IDs"
    )
    make.add_argument("--ground", action="store_true", help="an identity for the ground")
    make.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help=f"the router endpoint(s) the client configs name; their hosts go in every "
        f"certificate (default {DEFAULT_SECURE_ROUTER})",
    )
    make.add_argument(
        "--days",
        type=bounded_int(1, 3650, "validity"),
        default=DEFAULT_VALID_DAYS,
        help="validity in days (default %(default)s)",
    )
    make.add_argument(
        "--seen-as",
        type=Path,
        metavar="PATH",
        help="where DIR is on the machines that use the configs, e.g. /certs in a "
        "container (default: DIR's absolute path)",
    )
    make.add_argument(
        "--force",
        action="store_true",
        help="replace the CA already in DIR (every identity it issued stops being trusted)",
    )
    set_handler(make, MAKE)
    revoke = actions.add_parser(
        "revoke",
        help="withdraw identities (a lost aircraft): the new roster is put to the running "
        "fleet (as DIR/ground.json5), whose processes refuse their messages at once and "
        "whose routers close their sessions",
    )
    revoke.add_argument("directory", type=Path, metavar="DIR")
    revoke.add_argument("names", nargs="+", metavar="NAME", help="identities, e.g. uav-74")
    _add_publish_arguments(revoke)
    set_handler(revoke, REVOKE)
    publish = actions.add_parser(
        "publish",
        help="put DIR's roster to the running fleet again (a process that was cut off "
        "when an identity was revoked)",
    )
    publish.add_argument("directory", type=Path, metavar="DIR")
    _add_publish_arguments(publish)
    set_handler(publish, PUBLISH)


def _add_publish_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help="the fleet's router (default: the endpoints DIR/ground.json5 names)",
    )
    parser.add_argument(
        "--no-publish", action="store_true", help="only write the roster; put nothing"
    )
    add_key_prefix_argument(parser)


@dataclass(frozen=True, kw_only=True)
class MakeOptions:
    directory: Path
    uavs: tuple[int, ...] = ()
    #: An identity for the ground too.
    ground: bool = False
    #: The router endpoints the client configs name (None: DEFAULT_SECURE_ROUTER).
    connect: list[str] | None = None
    days: int = DEFAULT_VALID_DAYS
    #: Where `directory` is on the machines that use the configs.
    seen_as: Path | None = None
    #: Replace the CA already there.
    force: bool = False


def run_make(args: MakeOptions, out: TextIO) -> int:
    connect = args.connect or [DEFAULT_SECURE_ROUTER]
    bad = [e for e in connect if not e.startswith("tls/")]
    if bad:
        return fail("fleet certs", f"{bad[0]!r} is not a tls/ endpoint")
    names = identity_names(args.uavs, args.ground)
    try:
        written = write_identities(
            args.directory, names, connect, args.days, args.seen_as, force=args.force
        )
    except (CertError, RosterError) as error:
        return fail("fleet certs", str(error), ExitCode.FAILED)
    directory = written[0].directory
    print(f"fleet certs: CA {directory / 'ca.pem'}, signers {directory / ROSTER_FILE}", file=out)
    for files in written:
        made = (files.certificate, files.key, files.client_config)
        signing = signing_key_path(directory, files.name)
        print(f"  {files.name}: {' '.join(path.name for path in (*made, signing))}", file=out)
    return ExitCode.OK


@dataclass(frozen=True, kw_only=True)
class PublishOptions:
    directory: Path
    #: The router to put the roster through (None: those DIR/ground.json5 names).
    connect: list[str] | None = None
    #: Only write the roster.
    no_publish: bool = False
    key_space: KeySpace = DEFAULT_SPACE


@dataclass(frozen=True, kw_only=True)
class RevokeOptions(PublishOptions):
    #: Identities, e.g. uav-74.
    names: list[str]


#: How many times the roster is put, this far apart (s): a put is not acknowledged, and
#: every copy after the first changes nothing where it arrived.
PUTS = 3
PUT_EVERY_S = 0.2
#: How long to try to reach the fleet's router.
OPEN_TIMEOUT_S = 5.0


def run_revoke(args: RevokeOptions, out: TextIO) -> int:
    try:
        roster = revoke(args.directory, list(args.names))
    except RosterError as error:
        return fail("fleet certs", str(error), ExitCode.FAILED)
    print(
        f"fleet certs: {args.directory / ROSTER_FILE} revokes {', '.join(sorted(roster.revoked))}",
        file=out,
    )
    return run_publish(args, out)


def run_publish(args: PublishOptions, out: TextIO) -> int:
    """Put the roster on `roster` as the ground: every process connected now (each
    checks the CA's signature) refuses the revoked identities from then on."""
    restart = "  copy it to every machine: a process started later loads it from there"
    ground = args.directory / f"{GROUND}.json5"
    if args.no_publish or not ground.is_file():
        if not args.no_publish:
            print(
                f"  no {ground.name} in {args.directory}: nothing put to a running fleet", file=out
            )
        print(f"{restart}, and restart the running ones", file=out)
        return ExitCode.OK
    from fleet.transport.zenoh_bus import BusConnectError, connect

    try:
        document = roster_document(args.directory)
        config = build_config(config_file=str(ground), connect=args.connect)
        where = ", ".join(endpoints(config))
        with contextlib.closing(connect(config, open_timeout_s=OPEN_TIMEOUT_S)) as bus:
            if not bus.signed:
                return fail("fleet certs", f"{ground}: not a secure identity: nothing put")
            for attempt in range(PUTS):
                bus.put(args.key_space.roster(), document)
                if attempt + 1 < PUTS:
                    time.sleep(PUT_EVERY_S)
    except (RosterError, ZenohConfigError) as error:
        return fail("fleet certs", str(error), ExitCode.FAILED)
    except BusConnectError as error:
        print(f"  no fleet reached ({error})", file=out)
        print(f"{restart}, and restart the running ones (or `fleet certs publish`)", file=out)
        return ExitCode.OK
    print(f"  put on {args.key_space.roster()} through {where}, as {GROUND}", file=out)
    print(restart, file=out)
    return ExitCode.OK


MAKE = LocalCommand(options_from(MakeOptions), run_make)
REVOKE = LocalCommand(options_from(RevokeOptions), run_revoke)
PUBLISH = LocalCommand(options_from(PublishOptions), run_publish)
