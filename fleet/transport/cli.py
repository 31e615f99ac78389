"""Command-line plumbing shared by `fleet`, `onboard` and `ground-cli`.

One place for what every program of the project does the same way: argparse value
types, the Zenoh flags (``--connect``, ``--listen``, ``--mode``, ``--zenoh-config`` /
$FLEET_ZENOH_CONFIG), ``--key-prefix``, ``-v`` and logging set-up, SIGTERM/SIGINT
handling, and exit codes.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import faulthandler
import logging
import math
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from enum import IntEnum, StrEnum
from types import FrameType
from typing import Any

import zenoh

from fleet.mission.key_registry import DEFAULT_PREFIX
from fleet.mission.key_space import KeySpace
from fleet.piccolo.stream_packet import MAX_PICCOLO_ID, MIN_PICCOLO_ID
from fleet.transport.bus_factory import MEMORY_SCHEME
from fleet.transport.zenoh_config import (
    CONFIG_ENV,
    CONNECT_ENV,
    DEFAULT_ROUTER,
    MODES,
    ZenohConfigError,
    build_config,
)

log = logging.getLogger(__name__)


class ExitCode(IntEnum):
    """Exit status of every program of the project."""

    OK = 0
    #: The operation ran and failed (bad input file, not agreed in time, a child died).
    FAILED = 1
    #: Bad command line or configuration, or no Zenoh router to talk to.
    USAGE = 2
    #: Stopped by SIGINT/SIGTERM before it could finish (128 + SIGINT).
    INTERRUPTED = 130


# ---- argparse value types ---------------------------------------------------------------------
def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive_float(text: str) -> float:
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number")
    return value


def non_negative_float(text: str) -> float:
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a number >= 0")
    return value


def bounded_int(low: int, high: int | None = None, what: str = "value") -> Callable[[str], int]:
    """An int type accepting low..high (inclusive; no upper bound when high is None)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < low or (high is not None and value > high):
            span = f"{low}-{high}" if high is not None else f"at least {low}"
            raise argparse.ArgumentTypeError(f"the {what} must be {span}, got {value}")
        return value

    return parse


def enum_option(parser: argparse.ArgumentParser, flag: str, default: StrEnum, help: str) -> None:
    """`flag` taking one of `default`'s enum's values (as typed), `default` when absent."""
    kind = type(default)
    parser.add_argument(flag, type=kind, choices=list(kind), default=default, help=help)


tcp_port = bounded_int(0, 65535, "TCP port")
piccolo_id = bounded_int(MIN_PICCOLO_ID, MAX_PICCOLO_ID, "Piccolo ID")


def piccolo_ids(text: str) -> tuple[int, ...]:
    """`74,112` -> (74, 112): Piccolo IDs, sorted, each once; at least one."""
    ids = [piccolo_id(part.strip()) for part in text.split(",") if part.strip()]
    if not ids:
        raise argparse.ArgumentTypeError("no Piccolo ID")
    return tuple(sorted(set(ids)))


# ---- Zenoh flags --------------------------------------------------------------------------------
#: The environment variable a process's key prefix is read from, and passed to its children.
PREFIX_ENV = "FLEET_KEY_PREFIX"


def key_space(text: str) -> KeySpace:
    """`replay` -> KeySpace("replay"); a usage error unless it is one key chunk."""
    try:
        return KeySpace(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


class _UseKeyPrefix(argparse.Action):
    """`--key-prefix P`: the key space of this process and of the processes it starts."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        assert isinstance(values, KeySpace)  # converted by its type, `key_space`
        setattr(namespace, self.dest, values)
        os.environ[PREFIX_ENV] = values.prefix  # inherited by child processes


def add_key_prefix_argument(parser: argparse.ArgumentParser) -> None:
    """`--key-prefix P`: `args.key_space`, the KeySpace every key of the command is built by
    ($FLEET_KEY_PREFIX, read when the arguments are parsed, by default)."""
    parser.add_argument(
        "--key-prefix",
        dest="key_space",
        action=_UseKeyPrefix,
        type=key_space,
        # A string default goes through `type` when parsed: a bad $FLEET_KEY_PREFIX is a
        # usage error too.
        default=os.environ.get(PREFIX_ENV, DEFAULT_PREFIX),
        metavar="P",
        help=f"the fleet's key prefix, one key chunk (default ${PREFIX_ENV} or "
        f"{DEFAULT_PREFIX}; e.g. replay, to see a `fleet replay`)",
    )


def add_zenoh_arguments(parser: argparse.ArgumentParser) -> None:
    """The Zenoh session flags; `zenoh_config(args)` turns them into a config."""
    add_key_prefix_argument(parser)
    group = parser.add_argument_group("zenoh")
    group.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help=f"endpoint to connect to; repeatable (default ${CONNECT_ENV} or {DEFAULT_ROUTER}, "
        "or the config file's)",
    )
    group.add_argument(
        "--listen", action="append", metavar="ENDPOINT", help="endpoint to listen on; repeatable"
    )
    group.add_argument(
        "--mode", choices=MODES, help="session mode (default client, or the config file's)"
    )
    group.add_argument(
        "--zenoh-config",
        metavar="FILE",
        default=os.environ.get(CONFIG_ENV) or None,
        help=f"a full Zenoh config file (JSON5); --connect, --listen and --mode override "
        f"its values (default ${CONFIG_ENV})",
    )


def add_query_timeout_argument(parser: argparse.ArgumentParser) -> None:
    """`--query-timeout S`: how long each Zenoh query of a ground tool waits."""
    parser.add_argument(
        "--query-timeout",
        type=positive_float,
        default=1.0,
        metavar="S",
        help="how long each Zenoh query waits for answers (default 1 s)",
    )


def zenoh_config(args: argparse.Namespace) -> zenoh.Config:
    """The config the Zenoh flags ask for; raises ZenohConfigError with the reason."""
    return build_config(
        mode=args.mode, connect=args.connect, listen=args.listen, config_file=args.zenoh_config
    )


def bus_spec(args: argparse.Namespace) -> str | zenoh.Config:
    """What `open_bus` opens for the Zenoh flags: `--connect memory:NAME` (the in-process
    bus, for tests driving a program's root), else the Zenoh config they ask for."""
    connect = getattr(args, "connect", None) or []
    if len(connect) == 1 and connect[0].startswith(MEMORY_SCHEME):
        return str(connect[0])
    return zenoh_config(args)


# ---- logging ------------------------------------------------------------------------------------
def add_verbose_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "-v", "--verbose", action="count", default=0, help="log more; repeat for even more"
    )


#: Set to 1 in a child's environment, Python dumps its threads' tracebacks on a fatal
#: signal from its first line on (what `enable_crash_dumps` does once it runs).
CRASH_DUMP_ENV = "PYTHONFAULTHANDLER"


def enable_crash_dumps() -> None:
    """On SIGSEGV, SIGFPE, SIGABRT, SIGBUS or SIGILL, write every thread's Python
    traceback to stderr (a child's log) before dying: a crash in a native library (Zenoh's
    callbacks, HiGHS) otherwise leaves no word. Left as it is if already on (pytest's, or
    $PYTHONFAULTHANDLER's)."""
    if faulthandler.is_enabled():
        return
    with contextlib.suppress(ValueError, OSError):  # a stderr with no descriptor
        faulthandler.enable(file=sys.stderr, all_threads=True)


def setup_logging(verbose: int, *, base: int = logging.INFO, name: str = "") -> None:
    """Log to stderr at `base`, one level lower per `-v` (DEBUG at most); crashes dump
    their tracebacks there too (`enable_crash_dumps`). With $RUST_LOG set, Zenoh's own
    log is on as it says, written by Zenoh to standard output."""
    enable_crash_dumps()
    if os.environ.get("RUST_LOG"):
        zenoh.try_init_log_from_env()
    level = max(logging.DEBUG, base - 10 * verbose)
    tag = f"{name} " if name else ""
    logging.basicConfig(
        level=level,
        format=f"%(asctime)s {tag}%(name)s %(levelname)s %(message)s",
        stream=sys.stderr,
    )


# ---- signals ------------------------------------------------------------------------------------
@contextmanager
def stop_on_signals(on_stop: Callable[[], None]) -> Iterator[None]:
    """While inside, SIGTERM and SIGINT call `on_stop`; the previous handlers come back after.

    Handlers can only be installed from the main thread; elsewhere (a test driving a
    command from a thread) the caller stops it itself.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handle(signum: int, frame: FrameType | None) -> None:
        log.info("%s: stopping", signal.Signals(signum).name)
        on_stop()

    previous = {sig: signal.signal(sig, handle) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def in_use_advice(error: OSError, flag: str | None = None) -> str:
    """For a port in use, what to do (to follow the error's text); "" for another error."""
    if error.errno != errno.EADDRINUSE:
        return ""
    elsewhere = f"give another port with {flag}" if flag else "listen on another port"
    return f" (another program listens there): stop it, or {elsewhere}"


def cannot_listen(where: str, error: OSError, flag: str | None = None) -> str:
    """Why listening on `where` failed, in a line, and for a port in use what to do: stop
    the program that listens there, or listen elsewhere (with `flag`)."""
    why = os.strerror(error.errno) if error.errno else str(error)
    return f"cannot listen on {where}: {why}{in_use_advice(error, flag)}"


def fail(prog: str, message: str, code: ExitCode = ExitCode.USAGE) -> ExitCode:
    """Print `prog: message` on stderr and return `code`, for `return fail(...)`."""
    print(f"{prog}: {message}", file=sys.stderr)
    return code


__all__ = [
    "CRASH_DUMP_ENV",
    "PREFIX_ENV",
    "ExitCode",
    "ZenohConfigError",
    "add_key_prefix_argument",
    "add_query_timeout_argument",
    "add_verbose_argument",
    "add_zenoh_arguments",
    "bounded_int",
    "bus_spec",
    "cannot_listen",
    "enable_crash_dumps",
    "fail",
    "in_use_advice",
    "non_negative_float",
    "piccolo_id",
    "piccolo_ids",
    "positive_float",
    "setup_logging",
    "stop_on_signals",
    "tcp_port",
    "zenoh_config",
]
