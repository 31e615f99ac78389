"""A child process that ends with its parent: the kernel's parent-death signal.

Why: the launcher starts every child in a session of its own (so a Ctrl-C reaches only
the launcher, which then stops them in order). A launcher that dies without stopping
them (SIGKILL, a crash) would leave them running: the simulator and every onboard kept
flying, reconnected to the next fleet on the same port and joined it with the same
Piccolo IDs. Linux's `PR_SET_PDEATHSIG` has the kernel send a signal to a process when
its parent dies, whatever kills the parent; the signal here is SIGKILL, which nothing
blocks or delays.

A parent asks for it by starting the child with ``FLEET_PARENT_PID`` set to its own PID
(`child_env`). The child arms the signal as the project's package is imported (`fleet`'s
``__init__``), so before its seconds of imports, not after them, and then checks that
its parent is still that PID: a parent that died between the fork and the arming would
never send it, and the child ends at once instead. The variable is then removed, so the
child's own children are not bound to a PID that is not their parent's.

The kernel sends the signal when the *thread* that started the child ends, not only the
process: start children from a thread that lives as long as they should (the launcher
starts them from its main thread). A forked child is not bound by its parent's
binding: the fork server binds each child it forks to itself (`bind_to_parent`).
On a system without `prctl` (not Linux), nothing is armed and children outlive their
parent as before.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os
import signal
from collections.abc import Callable

log = logging.getLogger(__name__)

#: The environment variable a parent names itself in; its children bind to that PID.
PARENT_ENV = "FLEET_PARENT_PID"
#: From <linux/prctl.h>.
PR_SET_PDEATHSIG = 1
PR_SET_CHILD_SUBREAPER = 36


@functools.cache
def _libc_prctl() -> Callable[..., int] | None:
    # The C library the interpreter is linked with (no search: `find_library` would run
    # a program, in a child just forked).
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
    prctl.restype = ctypes.c_int
    return prctl


def _prctl(option: int, value: int) -> bool:
    """prctl(option, value); False where there is no prctl or it refused."""
    prctl = _libc_prctl()
    return prctl is not None and prctl(option, value, 0, 0, 0) == 0


def bind_to_parent(parent_pid: int) -> bool:
    """End this process (SIGKILL) when its parent dies; at once if its parent is no
    longer `parent_pid` (it died before the binding). False where it cannot be armed."""
    if not _prctl(PR_SET_PDEATHSIG, signal.SIGKILL):
        return False
    if os.getppid() != parent_pid:
        # Adopted already: the parent died before the signal was armed.
        os.kill(os.getpid(), signal.SIGKILL)
    return True


def bind_from_env() -> None:
    """Bind to the parent named in $FLEET_PARENT_PID, if any; then forget the variable."""
    value = os.environ.pop(PARENT_ENV, None)
    if not value:
        return
    try:
        parent = int(value)
    except ValueError:
        log.warning("ignored %s=%r: not a process id", PARENT_ENV, value)
        return
    bind_to_parent(parent)


def child_env(env: dict[str, str]) -> dict[str, str]:
    """`env` for a child that is to end with this process."""
    return {**env, PARENT_ENV: str(os.getpid())}


def become_subreaper() -> bool:
    """Adopt this process's orphaned descendants (instead of init), so that they can be
    found, and waited for, here: a test session checks none is left. False if not armed."""
    return _prctl(PR_SET_CHILD_SUBREAPER, 1)
