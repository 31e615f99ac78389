"""What a revoked client that keeps dialling costs a secure router, and what gets through.

A secure router (`fleet.transport.router.Router`, in this process) with a ground
session subscribed to two UAVs' telemetry; UAVs 74 and 112 are client processes that put
their telemetry every 10 ms. UAV 74 is revoked (its CA-signed roster put on
`fleet/roster`) and the router's `RevocationGuard` closes its session; 74's client dials
again at once, every time. For each way of refusing the reconnections, over `--seconds`
after the revocation:

* `held`: the router's way: the new link held `HOLD_S` (5 s), then cut, from a direct
  link-event callback (run before Zenoh reads the link);
* `at once`: the same callback cutting with no hold;
* `indirect`: no hold, from an ordinary Python callback (zenoh-python runs it on a
  thread of its own, after Zenoh may already have read the link).

it prints the reconnections refused per second, the router process's CPU (its share of
one core: the router, the ground session and this script), 74's puts that reached the
ground after the first close against those it made, and 112's puts that reached the
ground (the honest UAV, for reference).

    python -m bench.bench_revocation [--seconds 10]
"""

from __future__ import annotations

import argparse
import logging
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import zenoh

from fleet.files.certs import write_identities
from fleet.files.signers import revoke, roster_document
from fleet.launch.endpoints import free_port
from fleet.mission.key_space import KeySpace
from fleet.transport.live_revocation import HOLD_S, RevocationGuard
from fleet.transport.router import Router
from fleet.transport.secure import SecureProfile
from fleet.transport.zenoh_config import build_config

SPACE = KeySpace()
PUT_EVERY_S = 0.01
#: How long the clients run before the revocation.
SETTLE_S = 2.0


class IndirectGuard(RevocationGuard):
    """The guard with its link callback run the ordinary way, on a thread of its own."""

    def start(self) -> None:
        super().start()
        self._declared[0].undeclare()
        self._declared[0] = self.session.info.declare_link_events_listener(self._on_link)


def client(certs: Path, endpoint: str, identity: str, uav: int, seconds: float) -> None:
    """Put numbered telemetry as `identity` for `seconds`."""
    config = build_config(config_file=str(certs / f"{identity}.json5"), connect=[endpoint])
    with zenoh.open(config) as session:
        number, end = 0, time.monotonic() + seconds
        while time.monotonic() < end:
            number += 1
            session.put(SPACE.telemetry(uav), str(number).encode())
            time.sleep(PUT_EVERY_S)
        print(number, flush=True)


def run(mode: str, seconds: float) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as directory:
        certs = Path(directory)
        endpoint = f"tls/127.0.0.1:{free_port()}"
        write_identities(certs, ["router", "ground", "uav-74", "uav-112"], [endpoint])
        router = Router([endpoint], secure=SecureProfile.load(certs))
        with router:
            guard = router.revocations
            assert guard is not None
            if mode != "held":
                guard.stop()
                kind = IndirectGuard if mode == "indirect" else RevocationGuard
                guard = kind(router.session, SPACE.roster(), certs / "ca.pem", hold_s=0.0)
                guard.start()
            heard: dict[int, list[tuple[float, int]]] = {74: [], 112: []}
            lock = threading.Lock()
            ground_config = build_config(
                config_file=str(certs / "ground.json5"), connect=[endpoint]
            )
            with zenoh.open(ground_config) as ground:

                def on_sample(sample: zenoh.Sample) -> None:
                    uav = int(str(sample.key_expr).split("/")[2])
                    with lock:
                        heard[uav].append((time.monotonic(), int(sample.payload.to_bytes())))

                subscriber = ground.declare_subscriber(SPACE.all_telemetry, on_sample)
                clients = [
                    subprocess.Popen(
                        [
                            sys.executable,
                            "-m",
                            "bench.bench_revocation",
                            "--client",
                            str(certs),
                            endpoint,
                            f"uav-{uav}",
                            str(uav),
                            str(SETTLE_S + seconds + 1.0),
                        ],
                        stdout=subprocess.PIPE,
                        text=True,
                    )
                    for uav in (74, 112)
                ]
                try:
                    time.sleep(SETTLE_S)
                    revoke(certs, ["uav-74"])
                    cpu0, since = time.process_time(), time.monotonic()
                    ground.put(SPACE.roster(), roster_document(certs))
                    while guard.closed == 0 and time.monotonic() - since < seconds:
                        time.sleep(0.01)
                    closed_at = time.monotonic()
                    refused0 = guard.refused
                    time.sleep(seconds)
                    cpu = time.process_time() - cpu0
                    elapsed = time.monotonic() - since
                    refused = guard.refused - refused0
                finally:
                    puts = [int(process.communicate(timeout=60.0)[0] or 0) for process in clients]
                subscriber.undeclare()
            guard.stop()
        with lock:
            before = max((n for at, n in heard[74] if at < since), default=0)
            after = [n for at, n in heard[74] if at > closed_at + 0.2]
            honest = [n for at, n in heard[112] if at > since]
        return {
            "close_s": closed_at - since,
            "reconnections_per_s": refused / seconds,
            "cpu_share": cpu / elapsed,
            "leaked": len(after),
            "put": puts[0],
            "before": before,
            "honest": len(honest),
        }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.bench_revocation")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--client", nargs=5, metavar="ARG", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.client:
        certs, endpoint, identity, uav, seconds = args.client
        client(Path(certs), endpoint, identity, int(uav), float(seconds))
        return 0
    logging.disable(logging.WARNING)  # each refused link is logged: the table is the output
    print(f"{os.cpu_count()} cores, hold {HOLD_S:g} s, "
          f"{args.seconds:g} s after the revocation, 74 and 112 put every "
          f"{PUT_EVERY_S * 1000:g} ms")  # fmt: skip
    print(f"{'mode':<9} {'closed in':>9} {'reconn./s':>9} {'CPU':>6} "
          f"{'74 routed after close':>22} {'112 routed after':>16}")  # fmt: skip
    for mode in ("held", "at once", "indirect"):
        figures = run(mode, args.seconds)
        closed_ms, put_after = figures["close_s"] * 1000, figures["put"] - figures["before"]
        print(
            f"{mode:<9} {closed_ms:>7.0f}ms {figures['reconnections_per_s']:>9.1f} "
            f"{figures['cpu_share']:>6.0%} {figures['leaked']:>9.0f} of {put_after:<6.0f} "
            f"{figures['honest']:>16.0f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
