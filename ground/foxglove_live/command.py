"""`fleet foxglove`: serve the live fleet to Foxglove over its WebSocket protocol.

A client of the fleet, as `ground-cli` is: it connects to the fleet's router with the
usual Zenoh flags and serves, on 127.0.0.1:8765 by default, the topics `fleet record`
writes (docs/foxglove.md). Prints `fleet foxglove: serving ws://HOST:PORT` once a client
can connect, and serves until Ctrl-C/SIGTERM or `--duration`. A handshake naming another
Host, or from a web page of another Origin, is refused (`gate`).

Exit status: 0 stopped; 1 cannot listen; 2 usage error or no Zenoh router.
"""

from __future__ import annotations

import argparse
import os
import threading
from dataclasses import dataclass
from typing import TextIO

import foxglove

from fleet.recording.bus_tap import ended_line
from fleet.transport.bus import Bus
from fleet.transport.bus_factory import unwrap
from fleet.transport.cli import (
    ExitCode,
    add_zenoh_arguments,
    cannot_listen,
    fail,
    non_negative_float,
    positive_float,
    stop_on_signals,
)
from fleet.transport.command import BusOptions, Command, OptionsError, add_command
from ground.foxglove_live.bridge import DEFAULT_STATE_EVERY_S, FoxgloveBridge
from ground.foxglove_live.client_log import quiet_client_resets
from ground.foxglove_live.gate import DEFAULT_ORIGINS, Gate, Rules, upstream_identity
from ground.gui.cli import host_port
from ground.host_check import is_loopback

PROG = "fleet foxglove"
#: Foxglove's own default: its "Open connection" dialog offers ws://localhost:8765.
DEFAULT_SERVE = "127.0.0.1:8765"
#: The line printed once clients can connect (tests and scripts wait for it).
READY_LINE = f"{PROG}: serving"


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = add_command(
        subparsers,
        "foxglove",
        FOXGLOVE,
        help="serve the live fleet to Foxglove (WebSocket)",
        doc=__doc__,
    )
    parser.add_argument(
        "--serve",
        type=_address,
        default=_address(DEFAULT_SERVE),
        metavar="HOST:PORT",
        help=f"where Foxglove connects (default {DEFAULT_SERVE}; port 0: any free port)",
    )
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a non-loopback --serve (the protocol has no access control)",
    )
    parser.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="ORIGIN",
        help="a web page origin that may connect, e.g. https://studio.example (repeatable; "
        f"allowed always: {', '.join(DEFAULT_ORIGINS)}, and clients that send none)",
    )
    parser.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="a host name clients may reach the server by besides its address and "
        "localhost (repeatable)",
    )
    parser.add_argument(
        "--state-every",
        type=non_negative_float,
        default=DEFAULT_STATE_EVERY_S,
        metavar="S",
        help="query every UAV's state this often; 0: never (default %(default)g s)",
    )
    parser.add_argument("--duration", type=positive_float, metavar="S", help="stop after S s")
    add_zenoh_arguments(parser)


def _address(text: str) -> tuple[str, int]:
    """`HOST:PORT` (IPv6 as `[::1]:PORT`), as `ground-cli gui --listen` takes it."""
    try:
        return host_port(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected HOST:PORT with a port 0-65535, e.g. {DEFAULT_SERVE}"
        ) from None


@dataclass(frozen=True, kw_only=True)
class FoxgloveOptions(BusOptions):
    #: Where Foxglove connects (HOST, PORT; port 0: any free port).
    serve: tuple[str, int]
    #: Host names clients may reach the server by besides its address and localhost.
    allow_host: tuple[str, ...] = ()
    #: Web page origins that may connect besides DEFAULT_ORIGINS.
    allow_origin: tuple[str, ...] = ()
    #: Query every UAV's state this often (0: never).
    state_every: float = DEFAULT_STATE_EVERY_S
    #: Stop after this long (None: at Ctrl-C/SIGTERM).
    duration: float | None = None


def foxglove_options(args: argparse.Namespace) -> FoxgloveOptions:
    """The options; serving beyond loopback without --allow-remote is a usage error."""
    host, port = args.serve
    if not is_loopback(host) and not args.allow_remote:
        raise OptionsError(
            f"--serve {host}:{port} is not loopback: anyone who reaches it would see the "
            "fleet (the Foxglove protocol has no access control). Add --allow-remote."
        )
    return FoxgloveOptions(
        serve=args.serve,
        allow_host=tuple(args.allow_host),
        allow_origin=tuple(args.allow_origin),
        state_every=args.state_every,
        duration=args.duration,
        key_space=args.key_space,
    )


def run(bus: Bus, options: FoxgloveOptions, out: TextIO) -> int:
    host, port = options.serve
    quiet_client_resets()  # a client leaving is not an error
    context = foxglove.Context()
    certificate, key = upstream_identity()
    try:
        # Behind the gate: on loopback, any port, reached through TLS by the gate alone.
        server = foxglove.start_server(
            name="uav-fleet",
            host="127.0.0.1",
            port=0,
            context=context,
            tls_cert=certificate,
            tls_key=key,
        )
    except RuntimeError as error:  # the SDK's FoxgloveError
        return fail(PROG, f"cannot start the Foxglove server: {error}", ExitCode.FAILED)
    rules = Rules.make(host, list(options.allow_host), list(options.allow_origin))
    gate = Gate(host, port, rules, server.port, certificate)
    try:
        gate.start()
    except OSError as error:
        server.stop()
        return fail(PROG, cannot_listen(f"{host}:{port}", error, "--serve"), ExitCode.FAILED)
    try:
        # Connected once the port is ours: a taken port is said without a router.
        return _serve(options, unwrap(bus), context, gate, out)
    finally:
        server.stop()  # first: its clients are told it closes, through the gate
        gate.stop()
        if gate.refused:
            refused = f"refused {sum(gate.refused.values())} client(s): {dict(gate.refused)}"
            print(f"{PROG}: {refused}", file=out)


def _serve(
    args: FoxgloveOptions, bus: Bus, context: foxglove.Context, gate: Gate, out: TextIO
) -> int:
    stop = threading.Event()
    bridge = FoxgloveBridge(bus, context, args.key_space, state_every_s=args.state_every)
    try:
        with stop_on_signals(stop.set):
            bridge.start()
            host = args.serve[0]
            where = f"[{host}]" if ":" in host else host
            print(
                f"{READY_LINE} ws://{where}:{gate.port} for {args.key_space.prefix}/** "
                f"(pid {os.getpid()})",
                file=out,
                flush=True,
            )
            stop.wait(args.duration)
    finally:
        bridge.stop()
    done = f"{PROG}: {sum(bridge.published.values())} messages on {len(bridge.topics())} topics"
    print(ended_line(done, bridge.dropped), file=out, flush=True)
    return ExitCode.OK


FOXGLOVE = Command(foxglove_options, run)
