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

Run: .venv/bin/python -m bench.bench_signing_round [--uavs 50] [--rounds 5]
"""

from __future__ import annotations

import argparse
import queue
import statistics
import tempfile
import threading
import time
from pathlib import Path

from fleet.files.certs import write_identities
from fleet.files.signers import load_roster, load_signing_key, signing_key_path
from fleet.launch.endpoints import free_port
from fleet.mission.access import GROUND, uav_identity
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target, UavResult
from fleet.transport.bus import BusSample, SampleCallback, decode_sample
from fleet.transport.router import Router
from fleet.transport.signing import BusSigning
from fleet.transport.zenoh_bus import ZenohBus, connect

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


def signing_of(certs: Path, identity: str) -> BusSigning:
    key = load_signing_key(signing_key_path(certs, identity))
    return BusSigning(identity, key, load_roster(certs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--uavs", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=5, help="rounds of each kind")
    args = parser.parse_args()
    uavs = list(range(1, args.uavs + 1))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with tempfile.TemporaryDirectory() as directory, Router([endpoint]):
        certs = Path(directory)
        write_identities(certs, [GROUND, *(uav_identity(u) for u in uavs)], [])
        signings = {u: signing_of(certs, uav_identity(u)) for u in uavs}
        ground_signing = signing_of(certs, GROUND)
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


if __name__ == "__main__":
    main()
