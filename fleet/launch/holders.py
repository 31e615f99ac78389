"""Who else holds what a new fleet needs: its router's TCP port, its Piccolo IDs.

Why: aircraft of a fleet whose launcher died kept flying, reconnected to the next
`fleet up` on the same port and joined it with the same Piccolo IDs, so that fleet
heard two UAVs 101. Children now end with their launcher (fleet.lifeline), but a
fleet still running on the port, a module started by hand, or one left by an older
launcher would do the same: `fleet up` refuses to start then, naming each process (its
PID and command) so that the operator can stop it.

Read from Linux's /proc, for this user's processes (others' are not readable, and are
not counted): a port's holder is the process with a socket listening on it; a UAV's
holder is an onboard process (`python -m onboard.main` or `onboard`) whose command
says `--id N` and `--connect` to the port. An onboard forked by a fork server carries
the server's command line, not its own, so only its fleet's router (on the port) gives
it away.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Collection, Iterator
from dataclasses import dataclass
from pathlib import Path

#: /proc/net/tcp's state of a listening socket.
LISTEN = "0A"
PROC = Path("/proc")


@dataclass(frozen=True)
class Holder:
    pid: int
    command: str

    def __str__(self) -> str:
        return f"PID {self.pid} ({self.command})"


def _command(pid: int) -> list[str]:
    try:
        raw = (PROC / str(pid) / "cmdline").read_bytes()
    except OSError:
        return []
    return [part.decode(errors="replace") for part in raw.split(b"\0") if part]


def _pids() -> Iterator[int]:
    for entry in os.listdir(PROC):
        if entry.isdigit() and int(entry) != os.getpid():
            yield int(entry)


def _listening_inodes(port: int) -> set[str]:
    inodes: set[str] = set()
    for table in ("tcp", "tcp6"):
        with contextlib.suppress(OSError):
            for row in (PROC / "net" / table).read_text().splitlines()[1:]:
                fields = row.split()
                if (
                    len(fields) > 9
                    and fields[3] == LISTEN
                    and int(fields[1].split(":")[1], 16) == port
                ):
                    inodes.add(fields[9])
    return inodes


def port_holders(port: int) -> list[Holder]:
    """The processes listening on TCP `port` (on any address)."""
    inodes = {f"socket:[{inode}]" for inode in _listening_inodes(port)}
    if not inodes:
        return []
    holders = []
    for pid in _pids():
        with contextlib.suppress(OSError):
            fds = PROC / str(pid) / "fd"
            if any(os.readlink(fds / fd) in inodes for fd in os.listdir(fds)):
                holders.append(Holder(pid, " ".join(_command(pid))))
    return holders


def _is_onboard(argv: list[str]) -> bool:
    return "onboard.main" in argv or any(Path(arg).name == "onboard" for arg in argv[:2])


def _options(argv: list[str], name: str) -> list[str]:
    return [argv[i + 1] for i, arg in enumerate(argv[:-1]) if arg == name]


def uav_holders(port: int, ids: Collection[int]) -> list[Holder]:
    """The onboard processes (by their command lines) of one of `ids` that connect to
    TCP `port`."""
    holders = []
    wanted = {str(uav) for uav in ids}
    for pid in _pids():
        argv = _command(pid)
        if not _is_onboard(argv) or not wanted & set(_options(argv, "--id")):
            continue
        if any(endpoint.endswith(f":{port}") for endpoint in _options(argv, "--connect")):
            holders.append(Holder(pid, " ".join(argv)))
    return holders
