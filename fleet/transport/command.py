"""A program's subcommand as a function: `run(bus, options, out) -> exit code`.

Every program (`fleet`, `ground-cli`) is a thin shell: its argument parser only builds
a command's options, a frozen dataclass of what the flags said, and names the command
in one attribute, `handler` (`set_handler`). Its root then opens the bus once, from the
Zenoh flags (`open_bus`, `fleet.transport.bus_factory`), runs the command on it and
closes it (`run_parsed`). So a command runs the same on a live fleet and, in a test, on
the in-memory bus with a fake fleet: no process, no socket, no parser.

A command that needs no bus from its root (it reads files, or starts a fleet and
connects to it itself) is a `LocalCommand`: `run(options, out)`.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TextIO, TypeVar

from fleet.errors import FleetError
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.transport.bus import Bus
from fleet.transport.bus_factory import OnFirstUse, open_bus
from fleet.transport.cli import (
    ExitCode,
    ZenohConfigError,
    add_verbose_argument,
    bus_spec,
    fail,
    setup_logging,
)

Opts = TypeVar("Opts")

#: The attribute of the parsed arguments that holds the command to run.
HANDLER = "handler"


class OptionsError(FleetError, ValueError):
    """The flags cannot make the command's options. `message` says why, printed after the
    program's name ("" when it was said already); `code` is the exit status."""

    def __init__(self, message: str, code: ExitCode = ExitCode.USAGE) -> None:
        super().__init__(message)
        self.message = message
        self.code = code


@dataclass(frozen=True)
class Command(Generic[Opts]):
    """A subcommand run on the bus its program's root opened."""

    #: Builds the options from the parsed flags; raises OptionsError if it cannot.
    options: Callable[[argparse.Namespace], Opts]
    run: Callable[[Bus, Opts, TextIO], int]


@dataclass(frozen=True)
class LocalCommand(Generic[Opts]):
    """A subcommand that needs no bus from its root."""

    options: Callable[[argparse.Namespace], Opts]
    run: Callable[[Opts, TextIO], int]


@dataclass(frozen=True, kw_only=True)
class BusOptions:
    """What every command on the bus is told: the fleet's key space (`--key-prefix`) and
    how long each of its queries waits (`--query-timeout`)."""

    key_space: KeySpace = DEFAULT_SPACE
    query_timeout: float = 1.0


def fields_from(kind: type[Opts], args: argparse.Namespace, **given: Any) -> Opts:
    """The dataclass `kind` from the parsed flags of its fields' names (a flag not on the
    command line leaves the field's default), and `given` for the fields the flags do not
    say as they are (read from a file, checked, renamed)."""
    names = [field.name for field in dataclasses.fields(kind)]  # type: ignore[arg-type]
    flags = {name: getattr(args, name) for name in names if hasattr(args, name)}
    return kind(**(flags | given))


def key_expr_option(text: str | None) -> str | None:
    """The key expression a flag or argument gave (None: none given), in canonical form;
    a one-line usage error (OptionsError) if it is not one."""
    from fleet.transport.key_expr import KeyExprError, checked_key_expr

    if text is None:
        return None
    try:
        return checked_key_expr(text)
    except KeyExprError as error:
        raise OptionsError(f"error: {error}") from None


def options_from(kind: type[Opts]) -> Callable[[argparse.Namespace], Opts]:
    """A builder of the dataclass `kind` from the parsed flags of its fields' names."""

    def build(args: argparse.Namespace) -> Opts:
        return fields_from(kind, args)

    return build


def set_handler(parser: argparse.ArgumentParser, command: Command[Any] | LocalCommand[Any]) -> None:
    """Name `command` as what `parser`'s subcommand runs."""
    parser.set_defaults(**{HANDLER: command})


def add_command(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
    name: str,
    command: Command[Any] | LocalCommand[Any],
    *,
    help: str,
    description: str | None = None,
    doc: str | None = None,
    configure: Callable[[argparse.ArgumentParser], None] | None = None,
) -> argparse.ArgumentParser:
    """Register the subcommand `name`, which runs `command`, with its one-line `help` and
    either a `description` (one paragraph, wrapped) or a `doc` (its module's docstring,
    printed as written); `configure` adds its arguments. Returns its parser."""
    parser = subparsers.add_parser(
        name,
        help=help,
        description=doc if doc is not None else description,
        formatter_class=(
            argparse.RawDescriptionHelpFormatter if doc is not None else argparse.HelpFormatter
        ),
    )
    if configure is not None:
        configure(parser)
    set_handler(parser, command)
    return parser


def run_parsed(args: argparse.Namespace, prog: str, out: TextIO | None = None) -> int:
    """Run the command the parsed `args` name: build its options, open the bus the Zenoh
    flags ask for (`OnFirstUse`; none for a LocalCommand), run it, close the bus. Usage
    errors, a bad Zenoh config and an unreachable router are one line on stderr and exit
    status 2."""
    from fleet.transport.zenoh_bus import BusConnectError

    out = out if out is not None else sys.stdout
    command: Command[Any] | LocalCommand[Any] = getattr(args, HANDLER)
    try:
        options = command.options(args)
    except OptionsError as error:
        return fail(prog, error.message, error.code) if error.message else error.code
    if isinstance(command, LocalCommand):
        return command.run(options, out)
    # Opened by the command's first use of it: what it checks before (its files, its
    # own port) is said first, and a command that finds it needs no fleet never dials.
    bus = OnFirstUse(lambda: open_bus(bus_spec(args)))
    try:
        return command.run(bus, options, out)
    except ZenohConfigError as error:
        return fail(prog, f"error: {error}")
    except BusConnectError as error:
        return fail(prog, f"error: {error}")
    finally:
        bus.close()


def run_standalone(
    prog: str,
    description: str,
    configure: Callable[[argparse.ArgumentParser], None],
    command: Command[Any] | LocalCommand[Any],
    argv: Sequence[str] | None = None,
) -> int:
    """Run one `fleet` subcommand on its own (``python -m its.module``): its arguments
    (`configure`), ``-v`` and logging, then `command` as `run_parsed` runs it."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    configure(parser)
    add_verbose_argument(parser)
    set_handler(parser, command)
    args = parser.parse_args(argv)
    setup_logging(args.verbose)
    return run_parsed(args, prog)
