"""Signed commands at N=50 on the bus: one mission round's exchange, signed
against unsigned, measured in the same run.

A router on loopback and N+1 real Zenoh sessions (a ground and N UAVs, each a `ZenohBus`
with its own identity's signing key, `fleet certs make`'s files): the ground puts the
mission's targets; each UAV, on hearing them, puts its result; the round is over when
every UAV has heard every result (N x N deliveries, each decoded as the onboard does, and
checked when signed). Rounds alternate unsigned and signed on the same sessions (signing
turned off and on), so both meet the same machine load.

All N+1 sessions live in this one Python process, so every check and decode of the
whole fleet runs under one interpreter lock: the worst case of "a fleet on one box", not
one aircraft's cost (that is `bench.bench_signing`'s per-message figure).

Signed state: then each of the N UAVs streams telemetry at 20 Hz for --stream-seconds to
the ground, which subscribes to every UAV's telemetry, unsigned and then signed (each
sample believed once its UAV's signed digest, put every 0.5 s, lists it:
`fleet.transport.stream_auth`), on fresh sessions each; the CPU time of this process (all
N+1 sessions) per second of streaming is compared, and the samples the ground received.

Run: .venv/bin/python -m bench.bench_signing_round [--uavs 50] [--rounds 5] [--stream-seconds 10]
"""

from __future__ import annotations

import argparse
import queue
import statistics
import threading
import time
from pathlib import Path

from fleet.mission.access import GROUND, uav_identity
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target, UavResult
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.transport.bus import BusSample, SampleCallback, decode_sample
from fleet.transport.bus_codec import encode
from fleet.transport.zenoh_bus import ZenohBus, connect
from tests.support.signed import bus_signing, router_and_identities

SPACE = KeySpace()
ROUND_TIMEOUT_S = 120.0


class Team:
    """N UAV buses that answer a mission with their results and count what they hear."""

    def __init__(self, buses: dict[int, ZenohBus]) -> None:
        self.buses = buses
        self.heard: dict[int, set[int]] = {uav: set() for uav in buses}
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.to_answer: queue.Queue[tuple[int, int] | None] = queue.Queue()
        self.mission = 0
        for uav, bus in buses.items():
            bus.subscribe(SPACE.all_mission_targets, self._on_targets(uav))
            bus.subscribe(SPACE.all_mission_results, self._on_result(uav))
        self.answerer = threading.Thread(target=self._answer, daemon=True)
        self.answerer.start()

    def _on_targets(self, uav: int) -> SampleCallback:
        def on_targets(sample: BusSample) -> None:
            targets = decode_sample(sample, MissionTargets)
            if targets is not None:
                self.to_answer.put((uav, targets.mission))

        return on_targets

    def _on_result(self, uav: int) -> SampleCallback:
        def on_result(sample: BusSample) -> None:
            result = decode_sample(sample, UavResult)
            if result is None or result.mission != self.mission:
                return
            with self.lock:
                self.heard[uav].add(result.uav)
                if all(len(h) == len(self.buses) for h in self.heard.values()):
                    self.done.set()

        return on_result

    def _answer(self) -> None:
        # Puts from a thread of our own, not from Zenoh's callback thread.
        while (item := self.to_answer.get()) is not None:
            uav, mission = item
            times = tuple(100.0 + uav + i for i in range(len(self.buses)))
            self.buses[uav].publish(
                SPACE.mission_result(mission, uav), UavResult(mission, uav, times)
            )

    def start(self, mission: int) -> None:
        with self.lock:
            self.mission = mission
            self.heard = {uav: set() for uav in self.buses}
            self.done.clear()

    def close(self) -> None:
        self.to_answer.put(None)
        self.answerer.join(5.0)


TELEMETRY_HZ = 20.0


def stream_cost(
    endpoint: str, certs: Path, uavs: list[int], signed: bool, seconds: float
) -> tuple[float, int, int]:
    """(CPU s per s in this process, samples put, samples the ground believed) while N
    UAVs stream telemetry at TELEMETRY_HZ to a ground subscribed to all of it."""

    def bus(identity: str) -> ZenohBus:
        return ZenohBus(connect(endpoint).session, bus_signing(certs, identity) if signed else None)

    ground = bus(GROUND)
    buses = {u: bus(uav_identity(u)) for u in uavs}
    heard = [0]
    lock = threading.Lock()

    def on_telemetry(sample: BusSample) -> None:
        with lock:
            heard[0] += 1

    ground.subscribe(SPACE.all_telemetry, on_telemetry)
    time.sleep(1.0)  # the subscriptions reach the router (a fixed wait: a bench)
    sample = encode(Telemetry(1000, gps=GpsBlock(35.7, -120.7, 600.0, 20.0, 0.0, 0.0)))
    put = 0
    cpu_start, start = time.process_time(), time.perf_counter()
    period = 1.0 / TELEMETRY_HZ
    tick = start
    while time.perf_counter() - start < seconds:
        for u, uav_bus in buses.items():
            uav_bus.put(SPACE.telemetry(u), sample)
            put += 1
        tick += period
        time.sleep(max(0.0, tick - time.perf_counter()))
    time.sleep(1.0)  # the last digests and samples arrive (counted in the CPU too)
    cpu = (time.process_time() - cpu_start) / (time.perf_counter() - start)
    for each in (ground, *buses.values()):
        each.close()
    return cpu, put, heard[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--uavs", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=5, help="rounds of each kind")
    parser.add_argument("--stream-seconds", type=float, default=10.0)
    args = parser.parse_args()
    uavs = list(range(1, args.uavs + 1))
    with router_and_identities([GROUND, *(uav_identity(u) for u in uavs)]) as (endpoint, certs):
        signings = {u: bus_signing(certs, uav_identity(u)) for u in uavs}
        ground_signing = bus_signing(certs, GROUND)
        ground = connect(endpoint)
        buses = {u: connect(endpoint) for u in uavs}
        team = Team(buses)
        time.sleep(1.0)  # the subscriptions reach the router (a fixed wait: a bench)
        targets = tuple(Target(35.7 + i / 1000, -120.7, 600.0) for i in range(args.uavs))
        times: dict[bool, list[float]] = {False: [], True: []}
        mission = 0
        try:
            for _ in range(args.rounds):
                for signed in (False, True):
                    ground.signing = ground_signing if signed else None
                    for u, bus in buses.items():
                        bus.signing = signings[u] if signed else None
                    mission += 1
                    team.start(mission)
                    start = time.perf_counter()
                    ground.publish(
                        SPACE.mission_targets(mission),
                        MissionTargets(mission, tuple(uavs), targets),
                    )
                    if not team.done.wait(ROUND_TIMEOUT_S):
                        raise SystemExit(f"round {mission} did not complete")
                    times[signed].append(time.perf_counter() - start)
        finally:
            team.close()
            for bus in (ground, *buses.values()):
                bus.close()
        streams = {
            signed: stream_cost(endpoint, certs, uavs, signed, args.stream_seconds)
            for signed in (False, True)
        }
    unsigned, signed_s = (statistics.median(times[k]) for k in (False, True))
    deliveries = args.uavs * args.uavs
    print(f"N={args.uavs}: one round = targets to {args.uavs} UAVs, {args.uavs} results, "
          f"{deliveries} result deliveries; {args.rounds} rounds of each, alternating")  # fmt: skip
    print(f"  unsigned: median {unsigned * 1000:.0f} ms "
          f"(all: {', '.join(f'{t * 1000:.0f}' for t in times[False])})")  # fmt: skip
    print(f"  signed:   median {signed_s * 1000:.0f} ms "
          f"(all: {', '.join(f'{t * 1000:.0f}' for t in times[True])})")  # fmt: skip
    print(f"  signed / unsigned: {signed_s / unsigned:.2f}; "
          f"{(signed_s - unsigned) / deliveries * 1e6:.0f} us more per delivery")  # fmt: skip
    print(f"signed state: {args.uavs} UAVs streaming telemetry at {TELEMETRY_HZ:.0f} Hz to "
          f"the ground for {args.stream_seconds:.0f} s (all in this process)")  # fmt: skip
    for signed, (cpu, put, heard) in streams.items():
        kind = "digests" if signed else "unsigned"
        print(f"  {kind:>8}: {cpu:.2f} CPU s per s; {heard} of {put} samples believed")
    ratio = streams[True][0] / streams[False][0]
    print(f"  with digests / unsigned: {ratio:.2f} "
          f"(+{(streams[True][0] - streams[False][0]) * 1000:.0f} ms CPU per s)")  # fmt: skip


if __name__ == "__main__":
    main()
