"""`ground-cli gui [--listen HOST:PORT] [--open]`: serve the Mission Manager's page.

Prints `gui: serving on URL` once the page can be opened, and serves until Ctrl-C or
SIGTERM. Listening on anything but loopback needs `--allow-remote`, and then a token
(`--token-file FILE`, made if missing, or `$FLEET_GUI_TOKEN`): the page commands
aircraft, and plain HTTP carries no identity of its own (docs/gui.md). The token is
never taken on the command line (`ps` shows every process's arguments to every user)
and never printed.
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
from pathlib import Path
from typing import TextIO

from fleet.errors import FleetError
from fleet.files.owned_files import read_private
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode, bounded_int, cannot_listen, positive_float
from fleet.transport.command import BusOptions, Command, OptionsError, add_command
from ground.host_check import is_loopback

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
    gui = add_command(
        commands,
        "gui",
        GUI,
        help="serve the Mission Manager's page (map, targets, send, abort)",
        doc=__doc__,
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
        "--token-file",
        type=Path,
        metavar="FILE",
        help=f"the access token, read from FILE (a new random one is written there, readable "
        f"by you only, if FILE does not exist); default ${TOKEN_ENV}",
    )
    # Refused with a clear word: a token in argv is in every user's `ps`.
    gui.add_argument("--token", dest="token_argv", help=argparse.SUPPRESS)
    gui.add_argument(
        "--rate",
        type=_rate,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help="snapshots pushed a second at most (1-10, default %(default)g)",
    )
    gui.add_argument("--open", action="store_true", help="open the page in a web browser")


class TokenError(FleetError, ValueError):
    """A token file that cannot be used."""


def read_token_file(path: Path) -> str:
    """The token in `path`; a new random one written there (owner-only, never through a
    link) if there is no such file. TokenError says what is wrong with the file."""
    try:
        token = read_private(path, TokenError, 4096).decode("utf-8", "replace").strip()
    except FileNotFoundError:
        token = secrets.token_urlsafe(24)
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            with os.fdopen(os.open(path, flags, 0o600), "w") as f:
                f.write(token + "\n")
        except OSError as error:
            raise TokenError(f"{path}: cannot write a new token: {error.strerror}") from None
        return token
    except OSError as error:
        raise TokenError(f"{path}: cannot read the token: {error.strerror}") from None
    if not token or any(c.isspace() for c in token):
        raise TokenError(f"{path}: expected one token (no spaces) on one line")
    return token


def _token(args: argparse.Namespace) -> str | None:
    """The token from `--token-file` or the environment; None if neither gives one."""
    if args.token_file is not None:
        return read_token_file(args.token_file)
    return os.environ.get(TOKEN_ENV) or None


@dataclass(frozen=True, kw_only=True)
class GuiOptions(BusOptions):
    host: str = "127.0.0.1"
    port: int = 8321
    #: Required on every request when set.
    token: str | None = None
    #: Where the token comes from, as the ready line says it (never the token).
    token_source: str = ""
    rate: float = DEFAULT_RATE_HZ
    #: Open the page in a web browser once it is served.
    open: bool = False


def gui_options(args: argparse.Namespace) -> GuiOptions:
    """The page's options, or OptionsError saying why the flags are refused: a token on
    the command line, an unusable token file, a non-loopback --listen without
    --allow-remote, or with it but no token."""
    if args.token_argv is not None:
        raise OptionsError(
            "gui: --token is not taken on the command line (every user's `ps` shows it): put "
            f"it in a file only you can read (--token-file FILE) or in ${TOKEN_ENV}"
        )
    host, port = args.http_listen
    try:
        token = _token(args)
    except TokenError as error:
        raise OptionsError(f"gui: {error}") from None
    if not is_loopback(host):
        if not args.allow_remote:
            raise OptionsError(
                f"gui: --listen {host}:{port} is not loopback: anyone who reaches it could send "
                "missions and aborts. Add --allow-remote (a token is then required)."
            )
        if token is None:
            raise OptionsError(
                f"gui: --listen {host}:{port} with --allow-remote needs a token: --token-file "
                f"FILE (a new one is made there if FILE does not exist) or ${TOKEN_ENV}"
            )
    return GuiOptions(
        host=host,
        port=port,
        token=token,
        token_source=_token_source(args),
        rate=args.rate,
        open=args.open,
        key_space=args.key_space,
        query_timeout=args.query_timeout,
    )


def _token_source(args: argparse.Namespace) -> str:
    if args.token_file is not None:
        return f"add ?token= with the token in {args.token_file}"
    return f"add ?token= with ${TOKEN_ENV}"


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
        # Never the token itself: stdout goes to logs (fleet up's gui.log) and terminals.
        where = "" if config.token is None else f" (token required: {options.token_source})"
        print(f"gui: serving on {url}{where}", file=out, flush=True)
        if options.open:
            # Without the token too: a browser started with it would show it in `ps`.
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
        where = f"{options.host}:{options.port}"
        print(f"ground-cli gui: error: {cannot_listen(where, error, '--listen')}", file=sys.stderr)
        return ExitCode.FAILED
    print("gui: stopped", file=out)
    return ExitCode.OK


GUI = Command(gui_options, run_gui)
