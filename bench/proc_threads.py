"""Per-thread CPU time and wake-ups of running processes, from /proc (Linux).

Threads are grouped by kind, from their kernel names: Zenoh names its runtime's threads
(tx-0, rx-1, net-0, app-0, acc-0), an onboard names its link loop (link-ID) and its
planner (onboard/native_thread.py); what is left (the main loop, a previous release's
unnamed threads) is "python".
"""

from __future__ import annotations

import collections
import contextlib
import os
from pathlib import Path

#: (pid, tid) -> (thread kind, run time ns, voluntary switches)
Snapshot = dict[tuple[int, int], tuple[str, int, int]]
KINDS = ("planner", "link", "python", "tx", "rx", "net", "app", "acc")


def kind_of(comm: str) -> str:
    head = comm.split("-", 1)[0]
    return head if head in KINDS else "python"


def snapshot(pids: list[int]) -> Snapshot:
    found: Snapshot = {}
    for pid in pids:
        with contextlib.suppress(OSError):
            for tid in os.listdir(f"/proc/{pid}/task"):
                task = f"/proc/{pid}/task/{tid}"
                try:
                    comm = Path(f"{task}/comm").read_text().strip()
                    run_ns = int(Path(f"{task}/schedstat").read_text().split()[0])
                    status = Path(f"{task}/status").read_text()
                except OSError:
                    continue  # the thread ended
                switches = next(
                    int(line.split()[1])
                    for line in status.splitlines()
                    if line.startswith("voluntary_ctxt_switches")
                )
                found[(pid, int(tid))] = (kind_of(comm), run_ns, switches)
    return found


def by_kind(before: Snapshot, after: Snapshot) -> dict[str, tuple[float, int]]:
    """{kind: (CPU seconds, wake-ups)} between two snapshots, and "total" (threads that
    started in between count from zero)."""
    sums: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0])
    for key, (kind, run_ns, switches) in after.items():
        _, run0, switches0 = before.get(key, (kind, 0, 0))
        for name in (kind, "total"):
            sums[name][0] += (run_ns - run0) / 1e9
            sums[name][1] += switches - switches0
    return {name: (seconds, int(wakes)) for name, (seconds, wakes) in sums.items()}
