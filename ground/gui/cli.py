"""`ground-cli gui [--listen HOST:PORT] [--open]`: serve the Mission Manager's page.

Prints `gui: serving on URL` once the page can be opened, and serves until Ctrl-C or
SIGTERM. Listening on anything but loopback needs `--allow-remote`, and then a token
(`--token`, `$FLEET_GUI_TOKEN`, or one generated and printed): the page commands
aircraft, and plain HTTP carries no identity of its own (docs/gui.md).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import secrets
import signal
import sys
import webbrowser
from typing import TYPE_CHECKING

from fleet.transport.cli import ExitCode, bounded_int, fail, positive_float
from fleet.transport.zenoh_bus import client_bus

if TYPE_CHECKING:
    from ground.gui.server import GuiConfig

DEFAULT_LISTEN = "127.0.0.1:8321"
TOKEN_ENV = "FLEET_GUI_TOKEN"
DEFAULT_RATE_HZ = 5.0


def _rate(text: str) -> float:
    value = positive_float(text)
    if not 1.0 <= value <= 10.0:
        raise argparse.ArgumentTypeError(f"{text!r}: the page is pushed 1-10 times a second")
    return value


def host_port(text: str) -> tuple[str, int]:
    """`HOST:PORT` (IPv6 as `[::1]:PORT`; a Zenoh-style `tcp/HOST:PORT` too) -> (host, port)."""
    scheme, slash, rest = text.partition("/")
    if slash:
        if scheme != "tcp":
            raise argparse.ArgumentTypeError(
                f"{text!r}: the page is served over TCP: expected HOST:PORT, e.g. {DEFAULT_LISTEN}"
            )
        text = rest
    host, sep, port = text.rpartition(":")
    if not sep or not host:
        raise argparse.ArgumentTypeError(f"{text!r}: expected HOST:PORT, e.g. {DEFAULT_LISTEN}")
    port_number = bounded_int(0, 65535, "port")(port)
    return host.removeprefix("[").removesuffix("]"), port_number


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    gui = commands.add_parser(
        "gui",
        help="serve the Mission Manager's page (map, targets, send, abort)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    # Not `listen`: ground-cli's own --listen is a Zenoh endpoint.
    gui.add_argument(
        "--listen",
        dest="http_listen",
        type=host_port,
        default=host_port(DEFAULT_LISTEN),
        metavar="HOST:PORT",
        help=f"where the page is served (default {DEFAULT_LISTEN}; port 0: any free port)",
    )
    gui.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a non-loopback --listen; a token is then required on every request",
    )
    gui.add_argument(
        "--token",
        default=os.environ.get(TOKEN_ENV) or None,
        help=f"the access token (default ${TOKEN_ENV}; generated when needed and not given)",
    )
    gui.add_argument(
        "--rate",
        type=_rate,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help="snapshots pushed a second at most (1-10, default %(default)g)",
    )
    gui.add_argument("--open", action="store_true", help="open the page in a web browser")
    gui.set_defaults(handler=cmd_gui)


def _config(args: argparse.Namespace) -> GuiConfig | str:
    """The server's config, or why the flags are refused."""
    # aiohttp is imported only by the command that serves.
    from ground.gui.server import GuiConfig, is_loopback

    host, port = args.http_listen
    token = args.token
    if not is_loopback(host):
        if not args.allow_remote:
            return (
                f"--listen {host}:{port} is not loopback: anyone who reaches it could send "
                "missions and aborts. Add --allow-remote (a token is then required)."
            )
        token = token or secrets.token_urlsafe(24)
    return GuiConfig(host, port, token, args.rate, args.query_timeout, args.key_space)


def cmd_gui(args: argparse.Namespace) -> int:
    from ground.gui.server import serve

    config = _config(args)
    if isinstance(config, str):
        return fail("ground-cli gui", config)

    def on_ready(url: str) -> None:
        print(f"gui: serving on {url}", flush=True)
        if args.open:
            webbrowser.open(url)

    async def main() -> None:
        task = asyncio.current_task()
        assert task is not None
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, task.cancel)
        await serve(bus, config, on_ready)

    with client_bus(args.zenoh) as bus:
        try:
            asyncio.run(main())
        except asyncio.CancelledError:
            pass
        except OSError as error:
            print(f"ground-cli gui: error: cannot listen: {error}", file=sys.stderr)
            return ExitCode.FAILED
    print("gui: stopped")
    return ExitCode.OK
