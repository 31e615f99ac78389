"""Running `ground-cli` (and `fleet`) from a test: in the test's process (the program's
root, `ground.cli.main`, on any bus, the in-process one included: `--connect
memory:NAME`) or as a user runs it (`python -m ground.cli` in a process of its own, for
the end-to-end tests: run to its end, `ground_cli`, or started in the background and
finished later, `start_ground_cli` and `finish_ground_cli`; after a `prefix` command, such
as `ip netns exec NAME`, where it must run elsewhere)."""

from __future__ import annotations

import io
import logging
import os
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

from fleet.transport.zenoh_config import CONFIG_ENV, CONNECT_ENV
from tests.support.waiting import stretched

REPO = Path(__file__).resolve().parents[2]
#: How long a `ground-cli` process may run before the test gives up on it.
CLI_TIMEOUT_S = 60.0


def _connect(connect: str | Sequence[str] | None) -> list[str]:
    if connect is None:
        return []
    endpoints = [connect] if isinstance(connect, str) else list(connect)
    return [arg for endpoint in endpoints for arg in ("--connect", endpoint)]


def run_here(
    main: Callable[[list[str]], int], argv: list[str], prog: str
) -> subprocess.CompletedProcess[str]:
    """A program's root `main(argv)` run in this process: its exit status, and what it
    printed on stdout and stderr (a usage error's exit is its status). It gets what a
    process of its own would have: its warnings on its stderr, and its own count of the
    bus messages it refused."""
    from fleet.transport import bus_codec

    out, err = io.StringIO(), io.StringIO()
    handler = logging.StreamHandler(err)
    handler.setLevel(logging.WARNING)
    root = logging.getLogger()
    root.addHandler(handler)
    dropped, bus_codec.DROPPED = bus_codec.DROPPED, bus_codec.DropCounter()
    try:
        with redirect_stdout(out), redirect_stderr(err):
            try:
                status = main(argv)
            except SystemExit as exited:  # argparse's usage errors
                status = exited.code if isinstance(exited.code, int) else 2
    finally:
        bus_codec.DROPPED = dropped
        root.removeHandler(handler)
    return subprocess.CompletedProcess([prog, *argv], status, out.getvalue(), err.getvalue())


def ground_cli_here(
    *argv: str, connect: str | Sequence[str] | None = None
) -> subprocess.CompletedProcess[str]:
    """`ground-cli [--connect C] ARGV` run by its root in this process (`run_here`)."""
    from ground.cli import main

    return run_here(main, [*_connect(connect), *argv], "ground-cli")


def fleet_here(*argv: str) -> subprocess.CompletedProcess[str]:
    """`fleet ARGV` run by its root in this process (`run_here`)."""
    from programs.fleet_cli import main

    return run_here(main, list(argv), "fleet")


def _command(
    argv: Sequence[str], connect: str | Sequence[str] | None, prefix: Sequence[str]
) -> list[str]:
    return [*prefix, sys.executable, "-m", "ground.cli", *_connect(connect), *argv]


def _environment(env: Mapping[str, str] | None) -> dict[str, str]:
    """This one's without $FLEET_ZENOH_CONNECT and $FLEET_ZENOH_CONFIG (a test names its
    router), plus `env`."""
    environment = {k: v for k, v in os.environ.items() if k not in (CONNECT_ENV, CONFIG_ENV)}
    environment.update(env or {})
    return environment


def ground_cli(
    *argv: str,
    connect: str | Sequence[str] | None = None,
    env: Mapping[str, str] | None = None,
    timeout: float = CLI_TIMEOUT_S,
    prefix: Sequence[str] = (),
) -> subprocess.CompletedProcess[str]:
    """`[PREFIX] python -m ground.cli [--connect C] ARGV` in a process of its own, run to
    its end (within `timeout` s, `stretched` when loaded); its environment is
    `_environment(env)`."""
    return subprocess.run(
        _command(argv, connect, prefix),
        cwd=REPO,
        env=_environment(env),
        capture_output=True,
        text=True,
        timeout=stretched(timeout),
        check=False,
    )


def start_ground_cli(
    *argv: str,
    connect: str | Sequence[str] | None = None,
    env: Mapping[str, str] | None = None,
    prefix: Sequence[str] = (),
) -> subprocess.Popen[str]:
    """`ground_cli`'s command started in the background, in a session of its own: the
    test reads its stdout and stderr (pipes) as it goes, and `finish_ground_cli` ends it."""
    return subprocess.Popen(
        _command(argv, connect, prefix),
        cwd=REPO,
        env=_environment(env),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def finish_ground_cli(process: subprocess.Popen[str], timeout: float) -> tuple[int, str, str]:
    """A started `ground-cli`'s exit status, stdout and stderr once it ends (killed if it
    has not within `timeout`, `stretched` when loaded, which then raises
    subprocess.TimeoutExpired)."""
    try:
        out, err = process.communicate(timeout=stretched(timeout))
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    return process.returncode, out, err
