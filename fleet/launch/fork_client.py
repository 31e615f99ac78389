"""The launcher's side of the fork server (fleet.launch.fork_server).

`ForkServer.start()` runs the server as a child of its own; `spawn()` asks it for a
child and returns a `ForkedProcess`, which has what the launcher uses of a
`subprocess.Popen` (pid, poll, wait, send_signal, kill, returncode). Exit statuses come
from the server, which collects its children; signals go through a pidfd, so a PID
reused after its child ended is never signalled. A child ends with its server (the
kernel kills it: `fleet.lifeline`), and reports `UNKNOWN_STATUS` then, as no one could
collect its status.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import select
import signal
import subprocess
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from fleet.errors import FleetError
from fleet.launch import fork_server

log = logging.getLogger(__name__)

#: The status a `ForkedProcess` reports when it ended after its server did, so that no
#: one could collect its real status (as a shell reports an unknown one).
UNKNOWN_STATUS = 255
#: Seconds the launcher waits for the server's imports and its first word.
READY_TIMEOUT_S = 120.0
#: Seconds the launcher waits for a reply to one request.
REPLY_TIMEOUT_S = 30.0


class ForkServerError(FleetError, RuntimeError):
    """The fork server could not be started, or it refused or could not fork a child."""


@dataclass
class ForkedProcess:
    """A child of the fork server, seen from the launcher as a `subprocess.Popen`."""

    pid: int
    args: tuple[str, ...]
    returncode: int | None = None
    stdout: IO[bytes] | None = None
    _ended: threading.Event = field(default_factory=threading.Event)
    _pidfd: int | None = None
    _server_gone: threading.Event = field(default_factory=threading.Event)
    _collected: bool = False

    def __post_init__(self) -> None:
        try:
            self._pidfd = os.pidfd_open(self.pid)
        except ProcessLookupError:
            self._collected = True  # ended already: its exit event brings the status
        except (OSError, AttributeError):  # no pidfds (a kernel before 5.3): signal the PID
            self._pidfd = None

    def _set_status(self, status: int) -> None:
        if self.returncode is None:
            self.returncode = status
        self._ended.set()

    def _orphaned(self) -> bool:
        """Whether it ended after its server did (its status is then unknown)."""
        if not self._server_gone.is_set():
            return False
        if self._pidfd is not None and not select.select([self._pidfd], [], [], 0)[0]:
            return False  # a pidfd turns readable when its process ends
        self._set_status(UNKNOWN_STATUS)
        return True

    def poll(self) -> int | None:
        if self.returncode is None:
            self._orphaned()
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise subprocess.TimeoutExpired(list(self.args), timeout or 0.0)
            if self._server_gone.is_set() and self._pidfd is not None:
                select.select([self._pidfd], [], [], left)  # only the pidfd can tell now
            else:
                self._ended.wait(left)
        assert self.returncode is not None
        return self.returncode

    def close(self) -> None:
        """Forget its pidfd (once it is not needed: after the child is stopped)."""
        if self._pidfd is not None:
            os.close(self._pidfd)
            self._pidfd = None

    def send_signal(self, number: int) -> None:
        if self.returncode is not None or self._collected:
            return  # ended: its PID may be another process's now
        with contextlib.suppress(ProcessLookupError):
            if self._pidfd is not None:
                signal.pidfd_send_signal(self._pidfd, number)
            else:
                os.kill(self.pid, number)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


class ForkServer:
    """The launcher's handle on a running fork server (its own process is `process`)."""

    def __init__(self, process: subprocess.Popen[bytes], modules: Sequence[str]) -> None:
        self.process = process
        self.modules = tuple(modules)
        self._children: dict[int, ForkedProcess] = {}
        self._replies: dict[int, dict[str, Any]] = {}
        self._next_id = 0
        self._lock = threading.Lock()  # one request at a time
        self._changed = threading.Condition()
        self._ready = False
        self._gone = False
        self._reader = threading.Thread(target=self._read, name="fork-server", daemon=True)
        self._reader.start()

    @classmethod
    def start(
        cls, python: str, modules: Sequence[str], log_path: Path, env: dict[str, str]
    ) -> ForkServer:
        """Start a server that imports `modules`; its stderr goes to `log_path`."""
        with open(log_path, "ab") as errors:
            process = subprocess.Popen(
                [python, "-m", fork_server.__name__, *modules],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=errors,
                start_new_session=True,
                env=env,
            )
        return cls(process, modules)

    def wait_ready(self, timeout_s: float = READY_TIMEOUT_S) -> None:
        with self._changed:
            if not self._changed.wait_for(lambda: self._ready or self._gone, timeout_s):
                raise ForkServerError(f"the fork server was not ready in {timeout_s:g} s")
        if not self._ready:
            status = self.process.wait()  # its output ended: it has exited, or is exiting
            raise ForkServerError(f"the fork server exited with status {status}")

    def spawn(
        self, module: str, argv: Sequence[str], log_path: Path, env: dict[str, str]
    ) -> ForkedProcess:
        """Fork ``python -m module *argv``, its output appended to `log_path`."""
        with self._lock:
            self._next_id += 1
            request_id = self._next_id
            request = {
                "id": request_id,
                "module": module,
                "argv": list(argv),
                "log": str(log_path),
                "env": env,
            }
            stdin = self.process.stdin
            if stdin is None or self.process.poll() is not None:
                raise ForkServerError("the fork server is not running")
            try:
                stdin.write(json.dumps(request).encode() + b"\n")
                stdin.flush()
            except OSError as error:
                raise ForkServerError(f"the fork server is not listening: {error}") from None
            with self._changed:
                if not self._changed.wait_for(
                    lambda: request_id in self._replies or self._gone, REPLY_TIMEOUT_S
                ):
                    raise ForkServerError(f"no reply from the fork server in {REPLY_TIMEOUT_S:g} s")
                reply = self._replies.pop(request_id, {"error": "the fork server exited"})
        if "error" in reply:
            raise ForkServerError(str(reply["error"]))
        child = self._children[int(reply["pid"])]
        child.args = (module, *argv)
        return child

    def _read(self) -> None:
        assert self.process.stdout is not None
        for raw in self.process.stdout:
            try:
                self._take(json.loads(raw))
            except (ValueError, TypeError, KeyError, AttributeError):
                log.warning("ignored a line from the fork server: %r", raw[:200])
        with self._changed:
            for child in self._children.values():
                child._server_gone.set()
                if child.returncode is None:
                    child._ended.set()  # wake a waiter, which then asks the pidfd
            self._gone = True
            self._changed.notify_all()

    def _take(self, message: dict[str, Any]) -> None:
        with self._changed:
            if "exit" in message:
                child = self._children.get(int(message["exit"]))
                if child is not None:
                    child._set_status(int(message["status"]))
            elif "pid" in message:
                pid = int(message["pid"])
                self._children[pid] = ForkedProcess(pid, ("fork", str(pid)))
                self._replies[int(message.get("id", 0))] = message
            elif "error" in message:
                if "id" not in message:
                    log.warning("the fork server refused a line: %s", message["error"])
                self._replies[int(message.get("id", 0))] = message
            elif message.get("ready"):
                self._ready = True
            self._changed.notify_all()

    def close(self) -> None:
        """Close its stdin (it ends) and collect it; the children are the caller's to stop."""
        if self.process.stdin is not None:
            with contextlib.suppress(OSError):
                self.process.stdin.close()
        try:
            self.process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._reader.join(timeout=5.0)
        if self.process.stdout is not None:
            self.process.stdout.close()
        for child in self._children.values():
            child.close()
