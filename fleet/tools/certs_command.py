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
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from fleet.files.certs import DEFAULT_VALID_DAYS, CertError, write_identities
from fleet.files.signers import ROSTER_FILE, RosterError, revoke, signing_key_path
from fleet.mission.access import GROUND, ROUTER, uav_identity, uav_router_identity
from fleet.transport.cli import ExitCode, bounded_int, fail, piccolo_ids
from fleet.transport.command import LocalCommand, options_from, set_handler

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
        help="withdraw identities (a lost aircraft): its signed messages and connections "
        "are refused once each process restarts with the new roster",
    )
    revoke.add_argument("directory", type=Path, metavar="DIR")
    revoke.add_argument("names", nargs="+", metavar="NAME", help="identities, e.g. uav-74")
    set_handler(revoke, REVOKE)


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
class RevokeOptions:
    directory: Path
    #: Identities, e.g. uav-74.
    names: list[str]


def run_revoke(args: RevokeOptions, out: TextIO) -> int:
    try:
        roster = revoke(args.directory, list(args.names))
    except RosterError as error:
        return fail("fleet certs", str(error), ExitCode.FAILED)
    print(
        f"fleet certs: {args.directory / ROSTER_FILE} revokes {', '.join(sorted(roster.revoked))}",
        file=out,
    )
    print("  copy it to every machine and restart the router and every process", file=out)
    return ExitCode.OK


MAKE = LocalCommand(options_from(MakeOptions), run_make)
REVOKE = LocalCommand(options_from(RevokeOptions), run_revoke)
