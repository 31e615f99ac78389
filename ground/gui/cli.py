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
from dataclasses import dataclass
from typing import TextIO

from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode, bounded_int, positive_float
from fleet.transport.command import BusOptions, Command, OptionsError, set_handler

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
    set_handler(gui, GUI)


@dataclass(frozen=True, kw_only=True)
class GuiOptions(BusOptions):
    host: str = "127.0.0.1"
    port: int = 8321
    #: Required on every request when set.
    token: str | None = None
    rate: float = DEFAULT_RATE_HZ
    #: Open the page in a web browser once it is served.
    open: bool = False


def gui_options(args: argparse.Namespace) -> GuiOptions:
    """The page's options; a non-loopback --listen is refused without --allow-remote, and
    gets a token (generated when none is given) with it."""
    from ground.gui.server import is_loopback  # aiohttp only for the command that serves

    host, port = args.http_listen
    token = args.token
    if not is_loopback(host):
        if not args.allow_remote:
            raise OptionsError(
                f"gui: --listen {host}:{port} is not loopback: anyone who reaches it could send "
                "missions and aborts. Add --allow-remote (a token is then required)."
            )
        token = token or secrets.token_urlsafe(24)
    return GuiOptions(
        host=host,
        port=port,
        token=token,
        rate=args.rate,
        open=args.open,
        key_space=args.key_space,
        query_timeout=args.query_timeout,
    )


def run_gui(bus: Bus, options: GuiOptions, out: TextIO) -> int:
    from ground.gui.server import GuiConfig, serve

    config = GuiConfig(
        options.host,
        options.port,
        options.token,
        options.rate,
        options.query_timeout,
        options.key_space,
    )

    def on_ready(url: str) -> None:
        print(f"gui: serving on {url}", file=out, flush=True)
        if options.open:
            webbrowser.open(url)

    async def main() -> None:
        task = asyncio.current_task()
        assert task is not None
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, task.cancel)
        await serve(bus, config, on_ready)

    try:
        asyncio.run(main())
    except asyncio.CancelledError:
        pass
    except OSError as error:
        print(f"ground-cli gui: error: cannot listen: {error}", file=sys.stderr)
        return ExitCode.FAILED
    print("gui: stopped", file=out)
    return ExitCode.OK


GUI = Command(gui_options, run_gui)
