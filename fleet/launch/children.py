"""The launcher's child processes: what it holds of each, and how it stops them (by PID:
SIGTERM, then SIGKILL after a grace period)."""

from __future__ import annotations

import logging
import signal
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Protocol

log = logging.getLogger(__name__)

#: Seconds a child gets between SIGTERM and SIGKILL.
STOP_GRACE_S = 5.0


class ChildProcess(Protocol):
    """What the launcher uses of a child's process: a `subprocess.Popen`, or a
    `fleet.launch.fork_server.ForkedProcess`."""

    @property
    def pid(self) -> int: ...
    @property
    def returncode(self) -> int | Any: ...
    @property
    def stdout(self) -> IO[Any] | None: ...
    def poll(self) -> int | None: ...
    def wait(self, timeout: float | None = None) -> int: ...
    def send_signal(self, sig: int) -> None: ...
    def kill(self) -> None: ...


@dataclass
class Child:
    """A process the launcher started, and where its output goes."""

    name: str
    process: ChildProcess
    log_path: Path
    #: Whether the fleet stops when this child dies (a router of a mesh, or a UAV's
    #: onboard module, is not: the others fly on).
    essential: bool = True
    #: The command it was started with, for a restart (fleet.launch.supervisor).
    argv: tuple[str, ...] = ()

    @property
    def pid(self) -> int:
        return self.process.pid

    def tail(self, lines: int = 15) -> str:
        try:
            text = self.log_path.read_text(errors="replace")
        except OSError:
            return ""
        return "\n".join(text.splitlines()[-lines:])


class Stoppable(Protocol):
    """What `stop_children` needs of a child: the launcher's, or a test's."""

    @property
    def name(self) -> str: ...
    @property
    def process(self) -> ChildProcess: ...
    @property
    def pid(self) -> int: ...


def stop_children(children: Sequence[Stoppable], grace_s: float = STOP_GRACE_S) -> None:
    """SIGTERM each child by PID, wait up to `grace_s` in all, then SIGKILL the rest."""
    for child in children:
        if child.process.poll() is None:
            log.debug("SIGTERM %s (pid %d)", child.name, child.pid)
            child.process.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    for child in children:
        try:
            child.process.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            log.warning("%s (pid %d) ignored SIGTERM: killing it", child.name, child.pid)
            child.process.kill()
            child.process.wait()
