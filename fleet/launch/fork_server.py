"""Start many processes of one Python program by fork, from one process that imported it.

Why: fifty onboard processes each imported the same ~250 modules (Zenoh, msgspec, the
planner, HiGHS's compiled core) into memory of their own: ~18 MB private each, 0.92 GB
of PSS at N = 50. A fork server imports them once; each onboard is then
forked from it, and the imported pages stay shared, copy-on-write, until a child writes
them. The server calls `gc.freeze()` before it forks, so the collector never walks (and
so writes) the imported objects in a child; what a child still dirties is the objects
it touches (reference counts) and what it allocates itself (its Zenoh session, its
mission state).

The server is `python -m fleet.launch.fork_server MODULE...`, started by the launcher
like any child, with pipes for its stdin and stdout. It imports each MODULE and, where
one defines `fork_preload()`, calls it (to load what the module otherwise loads
lazily); then it says ``{"ready": true}`` and serves requests, one JSON line each:

* request (stdin): ``{"id": I, "module": M, "argv": [...], "log": PATH, "env": {...}}``
* reply (stdout): ``{"id": I, "pid": N}``, or ``{"id": I, "error": "why"}`` (no id if
  the line had none)
* event (stdout): ``{"exit": N, "status": S}`` when child N ends; S as
  `subprocess.Popen.returncode` gives it (-K for signal K)

Each child is what ``python -m M *argv`` with that environment would be, started as the
launcher starts its children: a session (process group) of its own, stdin from
/dev/null, stdout and stderr appended to PATH, every other descriptor closed. What
differs: the modules come imported, and an environment variable read only at import
time is the server's. A malformed request is answered with an error, and the server
goes on. The server ends when its stdin closes (the launcher is gone), and each child
it forked is bound to it (`fleet.lifeline`): when the server dies, however, the kernel
kills its children, as the server is itself killed when its launcher dies. A crash of
the server or of a child dumps its Python traceback into its log (`faulthandler`).

The launcher's side is `fleet.launch.fork_client`.
"""

from __future__ import annotations

import atexit
import contextlib
import faulthandler
import gc
import importlib
import json
import os
import runpy
import selectors
import signal
import sys
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from fleet import lifeline

#: The longest request line the server reads, bytes: an argv and an environment.
MAX_REQUEST_BYTES = 1 << 20


@dataclass(frozen=True)
class Request:
    """One child to start; `parse_request` checks a line into one."""

    module: str
    argv: tuple[str, ...]
    log: str
    env: dict[str, str]


def parse_request(line: bytes, modules: Sequence[str]) -> Request:
    """A request line -> Request; ValueError says what is wrong with it."""
    try:
        fields = json.loads(line)
    except (ValueError, UnicodeDecodeError) as error:
        raise ValueError(f"not a JSON line: {error}") from None
    if not isinstance(fields, dict):
        raise ValueError("a request is a JSON object")
    module, argv, log_path, env = (fields.get(k) for k in ("module", "argv", "log", "env"))
    if not isinstance(module, str) or module not in modules:
        raise ValueError(f"module {module!r} is not one this server imported ({list(modules)})")
    if not isinstance(argv, list) or not all(isinstance(a, str) for a in argv):
        raise ValueError("argv is a list of strings")
    if not isinstance(log_path, str) or not log_path:
        raise ValueError("log is a file path")
    if not isinstance(env, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in env.items()
    ):
        raise ValueError("env maps strings to strings")
    return Request(module, tuple(argv), log_path, env)


def _say(message: dict[str, Any]) -> None:
    # Straight to the descriptor: nothing buffered in sys.stdout that a child would
    # inherit and write again.
    os.write(1, json.dumps(message).encode() + b"\n")


def _preload(modules: Sequence[str]) -> None:
    for name in modules:
        module = importlib.import_module(name)
        hook = getattr(module, "fork_preload", None)
        if callable(hook):
            hook()


def _run_child(request: Request, output: int, server: int) -> int:
    """In the forked child: become ``python -m MODULE *argv`` writing to `output` (its
    log, opened by the server), ending with the `server`; its exit status."""
    lifeline.bind_to_parent(server)  # a fork does not inherit its parent's binding
    os.setsid()
    signal.set_wakeup_fd(-1)
    for number in (signal.SIGCHLD, signal.SIGINT, signal.SIGTERM):
        signal.signal(number, signal.SIG_DFL)
    nothing = os.open(os.devnull, os.O_RDONLY)
    os.dup2(nothing, 0)
    os.dup2(output, 1)
    os.dup2(output, 2)
    os.closerange(3, os.sysconf("SC_OPEN_MAX"))
    os.environ.clear()
    os.environ.update(request.env)
    os.environ.pop(lifeline.PARENT_ENV, None)  # bound to the server above, not to that
    sys.argv = [request.module, *request.argv]
    # As `python -m` finds it: not imported yet (its imports are, which is the point).
    sys.modules.pop(request.module, None)
    code = 0
    try:
        runpy.run_module(request.module, run_name="__main__", alter_sys=True)
    except SystemExit as stop:
        code = _exit_code(stop.code)
    except BaseException:  # the child's uncaught error: told as Python tells it
        traceback.print_exc()
        code = 1
    with contextlib.suppress(BaseException):
        atexit._run_exitfuncs()  # logging.shutdown and the program's own: as at a normal exit
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    return code


def _exit_code(code: object) -> int:
    if code is None:
        return 0
    if isinstance(code, int):
        return code & 0xFF
    print(code, file=sys.stderr)  # as the interpreter does with `sys.exit("message")`
    return 1


def _fork(request: Request) -> int:
    # The log is opened here, so a log that cannot be written is the request's error,
    # not a child that dies at once with nowhere to say why.
    output = os.open(request.log, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    server = os.getpid()
    try:
        pid = os.fork()
    except OSError:
        os.close(output)
        raise
    if pid == 0:
        code = 1
        try:
            code = _run_child(request, output, server)
        finally:
            os._exit(code)
    os.close(output)
    return pid


def _reap() -> None:
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        _say({"exit": pid, "status": os.waitstatus_to_exitcode(status)})


def serve(modules: Sequence[str]) -> int:
    """Import `modules`, then fork a child per request until stdin closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C is the launcher's to handle
    if not faulthandler.is_enabled():  # on stderr: the server's log, then each child's
        faulthandler.enable(all_threads=True)
    _preload(modules)
    gc.collect()
    gc.freeze()  # the children's collector leaves the imported objects (and their pages) alone
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_r, False)
    os.set_blocking(wake_w, False)
    signal.signal(signal.SIGCHLD, lambda *_: None)
    signal.set_wakeup_fd(wake_w)
    _say({"ready": True})
    pending = b""
    with selectors.DefaultSelector() as selector:
        selector.register(0, selectors.EVENT_READ)
        selector.register(wake_r, selectors.EVENT_READ)
        while True:
            ready = {key.fd for key, _ in selector.select()}
            if wake_r in ready:
                with contextlib.suppress(BlockingIOError):
                    os.read(wake_r, 4096)
                _reap()
            if 0 not in ready:
                continue
            chunk = os.read(0, 65536)
            if not chunk:
                return 0  # the launcher is gone
            pending += chunk
            *lines, pending = pending.split(b"\n")
            if len(pending) > MAX_REQUEST_BYTES:
                _say({"error": f"a request line longer than {MAX_REQUEST_BYTES} bytes"})
                pending = b""
            for line in lines:
                _answer(line, modules)


def _request_id(line: bytes) -> dict[str, Any]:
    """The request's id, to put in its reply, if the line has one."""
    with contextlib.suppress(ValueError, UnicodeDecodeError, AttributeError):
        request_id = json.loads(line).get("id")
        if isinstance(request_id, int):
            return {"id": request_id}
    return {}


def _answer(line: bytes, modules: Sequence[str]) -> None:
    reply = _request_id(line)
    try:
        request = parse_request(line, modules)
    except ValueError as error:
        _say({**reply, "error": str(error)})
        return
    try:
        pid = _fork(request)
    except OSError as error:
        _say({**reply, "error": f"cannot start {request.module}: {error}"})
        return
    _say({**reply, "pid": pid})


if __name__ == "__main__":
    sys.exit(serve(sys.argv[1:]))
