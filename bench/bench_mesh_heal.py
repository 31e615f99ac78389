"""How long the router-per-UAV mesh takes to heal when the ground's router dies.

The mesh of `fleet up --topology router-per-uav` (fleet.launch.topology): N UAV routers
on a ring, each linked to the ground's router, every router its own process. Three
client sessions in this process: a publisher on the first UAV's router (a sample every
`--period` ms), a subscriber on the UAV router half-way round the ring (its shortest
path runs through the ground's router when N >= 5), and a ground client on the ground's
router with the UAV routers as fallbacks. The ground's router is then SIGKILLed; for
each subscriber, *gap* is the time from the kill to the first sample after it, and
*lost* the samples published meanwhile that never arrived.

Run: .venv/bin/python -m bench.bench_mesh_heal [--sizes 4 8] [--runs 3] [--period 5]
"""

from __future__ import annotations

import argparse
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

import zenoh

from fleet.launch.endpoints import free_port
from fleet.launch.topology import fallbacks, ring_links
from fleet.transport.zenoh_config import make_config
from tests.support.waiting import wait_until

KEY = "bench/heal/seq"


@dataclass
class Arrivals:
    lock: threading.Lock = field(default_factory=threading.Lock)
    seen: dict[int, float] = field(default_factory=dict)

    def on_sample(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.seen[int(sample.payload.to_bytes())] = time.monotonic()

    def first_after(self, moment: float) -> float | None:
        with self.lock:
            later = [t for t in self.seen.values() if t > moment]
        return min(later) if later else None

    def missing(self, sent: dict[int, float], start: float, end: float) -> int:
        with self.lock:
            return sum(1 for seq, t in sent.items() if start <= t <= end and seq not in self.seen)


def router(listen: str, connect: list[str]) -> subprocess.Popen[bytes]:
    argv = [sys.executable, "-m", "fleet.transport.router", "--listen", listen]
    for endpoint in connect:
        argv += ["--connect", endpoint]
    return subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def accepts(endpoint: str) -> bool:
    host, _, port = endpoint.partition("/")[2].rpartition(":")
    try:
        with socket.create_connection((host, int(port)), timeout=0.5):
            return True
    except OSError:
        return False


def endpoint() -> str:
    return f"tcp/127.0.0.1:{free_port()}"


def start_mesh(ground: str, uav: dict[int, str], processes: list[subprocess.Popen[bytes]]) -> None:
    """The ground's router (processes[0]), then the UAV routers on a ring, all listening."""
    processes.append(router(ground, []))
    wait_until(lambda: accepts(ground), 30.0, "the ground's router")
    for u, neighbours in ring_links(list(uav)).items():
        processes.append(router(uav[u], [ground, *(uav[n] for n in neighbours)]))
    wait_until(lambda: all(accepts(e) for e in uav.values()), 30.0, "the UAV routers")


def one_run(size: int, period_s: float) -> tuple[float, float, int, int]:
    """(mesh gap s, ground-client gap s, mesh lost, ground-client lost) for one kill."""
    ids = list(range(1, size + 1))
    ground = endpoint()
    uav = {u: endpoint() for u in ids}
    processes: list[subprocess.Popen[bytes]] = []
    sessions: list[zenoh.Session] = []
    try:
        start_mesh(ground, uav, processes)
        far = ids[size // 2]
        publisher = zenoh.open(make_config("client", [uav[u] for u in fallbacks(ids, ids[0])]))
        subscriber = zenoh.open(make_config("client", [uav[u] for u in fallbacks(ids, far)]))
        ground_client = zenoh.open(make_config("client", [ground, *uav.values()]))
        sessions = [publisher, subscriber, ground_client]
        mesh, at_ground = Arrivals(), Arrivals()
        subscriber.declare_subscriber(KEY, mesh.on_sample)
        ground_client.declare_subscriber(KEY, at_ground.on_sample)
        sent: dict[int, float] = {}
        stop = threading.Event()

        def publish() -> None:
            seq = 0
            while not stop.wait(period_s):
                sent[seq] = time.monotonic()
                publisher.put(KEY, str(seq).encode())
                seq += 1

        thread = threading.Thread(target=publish, daemon=True)
        thread.start()
        wait_until(lambda: len(mesh.seen) > 20 and len(at_ground.seen) > 20, 10.0, "traffic")
        killed = time.monotonic()
        processes[0].send_signal(signal.SIGKILL)
        wait_until(
            lambda: (
                mesh.first_after(killed) is not None and at_ground.first_after(killed) is not None
            ),
            30.0,
            "traffic after the kill",
        )
        time.sleep(0.5)
        stop.set()
        thread.join()
        mesh_back = mesh.first_after(killed)
        ground_back = at_ground.first_after(killed)
        assert mesh_back is not None and ground_back is not None
        return (
            mesh_back - killed,
            ground_back - killed,
            mesh.missing(sent, killed, mesh_back),
            at_ground.missing(sent, killed, ground_back),
        )
    finally:
        for session in sessions:
            session.close()
        for process in processes:
            if process.poll() is None:
                process.terminate()
            process.wait(10)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--period", type=float, default=5.0, help="ms between samples")
    args = parser.parse_args(argv)
    print("| UAV routers | runs | mesh gap ms (median / max) | lost | ground client gap ms "
          "(median / max) | lost |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for size in args.sizes:
        runs = [one_run(size, args.period / 1000) for _ in range(args.runs)]
        mesh = [r[0] * 1000 for r in runs]
        ground = [r[1] * 1000 for r in runs]
        print(
            f"| {size} | {len(runs)} | {statistics.median(mesh):.0f} / {max(mesh):.0f} "
            f"| {max(r[2] for r in runs)} | {statistics.median(ground):.0f} / {max(ground):.0f} "
            f"| {max(r[3] for r in runs)} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
