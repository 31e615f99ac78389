"""What keeping the teammates' states to relay costs a secure fleet, at N=50.

In the secure profile every onboard keeps each teammate's latest state put (one a second
per UAV), as it arrived and unchecked, so that the ground can count a UAV frozen a moment
ago by its own signed state (`ZenohBus.keep_latest`, docs/security.md "Signed state").
A router on loopback and N real Zenoh sessions, each a `ZenohBus` with its own identity's
signing key, all in this process: each UAV puts its signed state once a second, first
with nobody keeping them, then with every UAV keeping every state (N x N deliveries a
second), on fresh sessions each; the CPU time of this process (all N sessions, so every
delivery under one interpreter lock: the worst case of "a fleet on one box") per second
of each is compared, measured in the same run.

Run: .venv/bin/python -m bench.bench_state_relay [--uavs 50] [--seconds 10]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from fleet.mission.access import uav_identity
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import UavState
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.transport.zenoh_bus import ZenohBus, connect
from tests.support.signed import bus_signing, router_and_identities

SPACE = KeySpace()


def state_cost(
    endpoint: str, certs: Path, uavs: list[int], keep: bool, seconds: float
) -> tuple[float, int]:
    """(CPU s per s in this process, states kept at the end, summed over the UAVs) while
    each UAV puts its signed state once a second, every UAV keeping them (`keep`) or not."""

    def bus(uav: int) -> ZenohBus:
        return ZenohBus(connect(endpoint).session, bus_signing(certs, uav_identity(uav)))

    buses = {u: bus(u) for u in uavs}
    if keep:
        for each in buses.values():
            each.keep_latest(SPACE.all_state)
    time.sleep(1.0)  # the subscriptions reach the router (a fixed wait: a bench)
    telemetry = Telemetry(1000, gps=GpsBlock(35.7, -120.7, 600.0, 20.0, 0.0, 0.0))
    cpu_start, start = time.process_time(), time.perf_counter()
    tick = start
    while time.perf_counter() - start < seconds:
        for u, uav_bus in buses.items():
            uav_bus.publish(SPACE.state(u), UavState(u, True, 1.0, 2, telemetry, None, None))
        tick += 1.0
        time.sleep(max(0.0, tick - time.perf_counter()))
    time.sleep(0.5)  # the last states arrive (counted in the CPU too)
    cpu = (time.process_time() - cpu_start) / (time.perf_counter() - start)
    kept = sum(
        1
        for mine, holder in buses.items()
        for u in uavs
        if u != mine and holder.latest(SPACE.state(u)) is not None
    )
    for each in buses.values():
        each.close()
    return cpu, kept


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--uavs", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    uavs = list(range(1, args.uavs + 1))
    with router_and_identities(uav_identity(u) for u in uavs) as (endpoint, certs):
        runs = {
            keep: state_cost(endpoint, certs, uavs, keep, args.seconds) for keep in (False, True)
        }
    (alone, _), (kept_cpu, kept) = runs[False], runs[True]
    n = args.uavs
    print(
        f"N={n}: each UAV puts its signed state once a second for {args.seconds:g} s "
        f"(all {n} sessions in this process)"
    )
    print(f"  nobody keeping:        {alone:.3f} CPU s per s")
    print(
        f"  every UAV keeping all: {kept_cpu:.3f} CPU s per s ({n * (n - 1)} deliveries a "
        f"second; {kept} of {n * (n - 1)} teammates' states held at the end)"
    )
    print(
        f"  keeping costs {kept_cpu - alone:+.3f} CPU s per s for the fleet, "
        f"{(kept_cpu - alone) / n * 1000:+.2f} ms a second per UAV"
    )


if __name__ == "__main__":
    main()
