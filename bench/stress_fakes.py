"""One process of fake-onboard cycles, the pattern of the ground's end-to-end tests.

    python -m bench.stress_fakes [--cycles 10] [--leave-open [--no-exit-close]]

Each cycle, in this process: an embedded router (`Router`), the two fake UAVs of the
ground's tests on it (`fake_pair`: client sessions with queryables, subscribers, a
token and a publishing thread, every callback on Zenoh's threads), and a ground
client that, from a thread of its own, puts aborts, OPM commands and targets and
queries the UAVs' states while the fakes are opened and closed under it; then the
fakes, the ground and the router are closed in that order, the ground's thread still
putting while the fakes close. `--leave-open`: after the last cycle, one more router
and fake pair are left open, callbacks still firing, when the interpreter exits: the
project closes them at exit (`fleet.transport.zenoh_exit`) unless `--no-exit-close`.

`bench.bench_stress --fake-runs N` runs it N times and counts the runs that died of a
signal or left faulthandler's dump.
"""

from __future__ import annotations

import argparse
import atexit
import threading

from fleet.launch.endpoints import free_port
from fleet.mission.messages import MissionAbort, OpmCommand
from fleet.transport import bus_codec, zenoh_exit
from fleet.transport.cli import enable_crash_dumps
from fleet.transport.router import Router
from fleet.transport.zenoh_bus import client_bus
from tests.support.fake_onboard import SPACE, FakeOnboard, fake_pair

#: Messages the ground puts a cycle (each kind), and queries it makes.
PUTS = 40


def ground_traffic(endpoint: str, stop: threading.Event, fakes_up: threading.Event) -> None:
    """Aborts, OPM commands and state queries, until `stop`: some land on fakes that are
    closing."""
    with client_bus(endpoint) as bus:
        fakes_up.wait(5.0)
        mission = 0
        while not stop.is_set():
            mission += 1
            bus.put(SPACE.mission_abort(mission), bus_codec.encode(MissionAbort(mission)))
            bus.put(SPACE.opm(74), bus_codec.encode(OpmCommand(enabled=mission % 2 == 0)))
            if mission % 4 == 0:
                bus.query(SPACE.state(112), timeout=0.5)
            stop.wait(0.002)


def one_cycle() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Router([endpoint]):
        stop, fakes_up = threading.Event(), threading.Event()
        ground = threading.Thread(target=ground_traffic, args=(endpoint, stop, fakes_up))
        ground.start()
        try:
            with fake_pair(endpoint) as fakes:
                fakes_up.set()
                # Each fake has heard some aborts: the callbacks run when the fakes close.
                for fake in fakes.values():
                    wait_for_aborts(fake, PUTS)
        finally:
            fakes_up.set()
            stop.set()
            ground.join()


def wait_for_aborts(fake: FakeOnboard, count: int) -> None:
    done = threading.Event()
    for _ in range(500):
        if len(fake.aborts) >= count or done.wait(0.01):
            return


def leave_open() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = Router([endpoint])
    router.open()
    fakes = [FakeOnboard(endpoint, uav, 42.35, -71.1, 150.0) for uav in (74, 112)]
    stop, fakes_up = threading.Event(), threading.Event()
    fakes_up.set()
    threading.Thread(target=ground_traffic, args=(endpoint, stop, fakes_up), daemon=True).start()
    wait_for_aborts(fakes[0], 5)
    # Exits with the router, the fakes and the ground open and talking.


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--leave-open", action="store_true")
    parser.add_argument("--no-exit-close", action="store_true")
    args = parser.parse_args()
    enable_crash_dumps()
    for _ in range(args.cycles):
        one_cycle()
    if args.leave_open:
        leave_open()
        if args.no_exit_close:
            atexit.unregister(zenoh_exit.AT_EXIT.close_all)
    print("done", flush=True)


if __name__ == "__main__":
    main()
