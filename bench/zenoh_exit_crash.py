"""A minimal reproduction: a Python process that exits with a Zenoh session open crashes.

Zenoh 1.10 (eclipse-zenoh 1.10.2) on CPython 3.11: this process opens a router and
publishes on `k/x` from a thread as fast as it can. Each trial is a new process, a
client of it, that declares a subscriber on `k/**` whose callback runs on Zenoh's
thread (`zenoh.handlers.Callback(f, indirect=False)`, as `fleet.transport.zenoh_bus`
declares them), waits for 500 samples, and returns from its main module:

* `open`: without closing its session. Zenoh's threads go on calling the callback while
  the interpreter finalizes. Seen: SIGABRT after glibc's "FATAL: exception not
  rethrown" (CPython ends a thread that wants the interpreter back during finalization
  with `pthread_exit`, whose unwinding the binding's Rust code catches), and SIGSEGV in
  `PyGILState_Ensure` -> `new_threadstate` (a callback after the interpreter is gone);
* `atexit`: the same, with `session.close` registered with `atexit` (what
  `fleet.transport.zenoh_exit` does for every session the project opens).

    python -m bench.zenoh_exit_crash [--trials 30]

prints, for each, how many trials ended cleanly, with SIGABRT and with SIGSEGV.
"""

from __future__ import annotations

import argparse
import collections
import signal
import subprocess
import sys
import threading

import zenoh

from fleet.launch.endpoints import free_port
from fleet.transport.zenoh_config import make_config

SAMPLES = 500
TRIAL_S = 120.0

CHILD = """
import atexit, sys, threading, zenoh
from fleet.transport.zenoh_config import make_config
session = zenoh.open(make_config("client", [sys.argv[1]]))
if sys.argv[2] == "atexit":
    atexit.register(session.close)
heard, enough = [0], threading.Event()
def on_sample(sample):
    sample.payload.to_bytes()
    sum(range(2000))  # some Python work per sample, as a decoding callback does
    heard[0] += 1
    if heard[0] >= SAMPLES:
        enough.set()
session.declare_subscriber("k/**", zenoh.handlers.Callback(on_sample, indirect=False))
enough.wait(60)
""".replace("SAMPLES", str(SAMPLES))


def outcome(status: int) -> str:
    if status == 0:
        return "clean"
    if status < 0:
        return signal.Signals(-status).name
    return f"status {status}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=30)
    args = parser.parse_args()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(make_config("router", listen=[endpoint]))
    stop = threading.Event()

    def flood() -> None:
        publisher = router.declare_publisher("k/x")
        while not stop.is_set():
            publisher.put(b"x")

    flooder = threading.Thread(target=flood)
    flooder.start()
    try:
        for variant in ("open", "atexit"):
            counts: collections.Counter[str] = collections.Counter()
            for _ in range(args.trials):
                trial = subprocess.run(
                    [sys.executable, "-c", CHILD, endpoint, variant],
                    capture_output=True,
                    timeout=TRIAL_S,
                    check=False,
                )
                counts[outcome(trial.returncode)] += 1
            told = ", ".join(f"{name} {n}" for name, n in counts.most_common())
            print(f"{variant}: {args.trials} trials: {told}", flush=True)
    finally:
        stop.set()
        flooder.join()
        router.close()


if __name__ == "__main__":
    main()
