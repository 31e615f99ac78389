"""The calling thread's Python name, given to the kernel too (Linux: /proc, no ctypes).

`top -H`, `ps -L` and /proc/PID/task/TID/comm then tell an onboard's threads apart: the
link loop and the planner next to Zenoh's own (tx-0, rx-0, ...), where Python leaves
every thread named after the executable. bench/bench_fleet_scale.py reads the names to
say where a mission's CPU went. The kernel keeps 15 bytes of a name.
"""

from __future__ import annotations

import contextlib
import threading

__all__ = ["name_native_thread"]

_COMM_BYTES = 15


def name_native_thread() -> None:
    """Name the calling thread, for the kernel, after its `threading` name."""
    thread = threading.current_thread()
    name = thread.name.encode("ascii", "replace")[:_COMM_BYTES]
    path = f"/proc/self/task/{threading.get_native_id()}/comm"
    with contextlib.suppress(OSError), open(path, "wb") as comm:  # not Linux: unnamed
        comm.write(name)
