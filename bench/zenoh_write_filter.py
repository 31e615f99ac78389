"""A minimal reproduction: a client's declared publisher loses a router's subscribers.

Zenoh 1.10 (eclipse-zenoh 1.10.2, Python): a router session holds a subscriber on
`fleet/**` and a liveliness subscriber on `fleet/uav/*/alive`; four clients each
declare a liveliness token, then a publisher on `fleet/uav/I/telemetry` (priority
DATA_LOW, congestion control DROP, as an onboard's) and put on it (and `put` on
`fleet/uav/I/link` with the session) every 5 ms. While the publishers
are being declared, the router's session declares, then undeclares, a second
subscriber on `fleet/uav/*/telemetry`. In some trials, a client's publisher then
reaches nobody: the `fleet/**` subscriber gets none of its telemetry, while the same
client's session puts still arrive. That is what `fleet up` did: its start-up watch
was such a subscriber, and one UAV's telemetry went missing from the recording.

    python -m bench.zenoh_write_filter [--trials 30]

prints, for the trigger (`undeclared`) and for the workaround `fleet up` uses (the
second subscriber kept declared, `kept`), how many trials had a client whose
telemetry stopped.
"""

from __future__ import annotations

import argparse
import random
import threading
import time

import zenoh

from fleet.launch.endpoints import free_port
from fleet.transport.zenoh_config import make_config

CLIENTS = 4
PERIOD_S = 0.005


def trial(undeclare: bool, rng: random.Random) -> list[int]:
    """Telemetry samples the router's `fleet/**` subscriber got from each client in
    the 0.3 s after the second subscriber's life (0: that client's stopped)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(make_config("router", listen=[endpoint]))
    ring = router.declare_subscriber("fleet/**", zenoh.handlers.RingChannel(100_000))
    alive = router.liveliness().declare_subscriber(
        "fleet/uav/*/alive", lambda sample: None, history=True
    )
    clients = [zenoh.open(make_config("client", connect=[endpoint])) for _ in range(CLIENTS)]
    stop = threading.Event()

    def publish(index: int) -> None:
        session = clients[index]
        token = session.liveliness().declare_token(f"fleet/uav/{index}/alive")
        time.sleep(rng.random() * 0.05)
        publisher = session.declare_publisher(
            f"fleet/uav/{index}/telemetry",
            priority=zenoh.Priority.DATA_LOW,
            congestion_control=zenoh.CongestionControl.DROP,
        )
        while not stop.is_set():
            publisher.put(b"t")
            session.put(f"fleet/uav/{index}/link", b"l")
            time.sleep(PERIOD_S)
        token.undeclare()

    threads = [threading.Thread(target=publish, args=(i,)) for i in range(CLIENTS)]
    for thread in threads:
        thread.start()
    time.sleep(rng.random() * 0.1)
    second = router.declare_subscriber("fleet/uav/*/telemetry", lambda sample: None)
    time.sleep(rng.random() * 0.05)
    if undeclare:
        second.undeclare()
    time.sleep(0.3)
    while ring.try_recv() is not None:
        pass
    time.sleep(0.3)
    counts = [0] * CLIENTS
    while (sample := ring.try_recv()) is not None:
        parts = str(sample.key_expr).split("/")
        if parts[-1] == "telemetry":
            counts[int(parts[2])] += 1
    stop.set()
    for thread in threads:
        thread.join()
    for session in clients:
        session.close()
    alive.undeclare()
    router.close()
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=30)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    for name, undeclare in (("undeclared", True), ("kept", False)):
        bad = sum(min(trial(undeclare, rng)) == 0 for _ in range(args.trials))
        print(f"{name}: {bad} of {args.trials} trials had a client whose telemetry stopped")


if __name__ == "__main__":
    main()
