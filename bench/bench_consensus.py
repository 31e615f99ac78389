"""Time from the ground's send to every UAV's committed assignment, split in two.

For N UAVs (separate onboard processes against `fleet sim`, a real Zenoh router) and
10 targets: *model time* is from the send to the last UAV result published (each UAV's
approach-time model runs in it); *consensus time* is from that last result to the last
assignment committed (the exchange, the greedy, the commit: the model excluded).
All timestamps are taken by the ground process on arrival, on one machine.

Run: .venv/bin/python -m bench.bench_consensus [--sizes 2 5 10 20] [--missions 3]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import msgspec
import zenoh

from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.mission.messages import AssignmentReport, MissionTargets, UavResult
from fleet.transport.bus_codec import ENCODING, encode
from tests.support.processes import Fleet, client_session, router_session
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()


class Arrivals:
    def __init__(self, session: zenoh.Session) -> None:
        self.lock = threading.Lock()
        self.results: dict[tuple[int, int], float] = {}
        self.commits: dict[tuple[int, int], float] = {}
        self.digests: dict[int, set[str]] = {}
        self.live: set[int] = set()
        self.subscribers = [
            session.declare_subscriber(SPACE.all_mission_results, self.on_result),
            session.declare_subscriber(SPACE.all_mission_assignments, self.on_commit),
            session.declare_subscriber(SPACE.uav("*", "link"), self.on_link),
        ]

    def on_result(self, sample: zenoh.Sample) -> None:
        now = time.perf_counter()
        result = msgspec.json.decode(sample.payload.to_bytes(), type=UavResult)
        with self.lock:
            self.results[(result.mission, result.uav)] = now

    def on_commit(self, sample: zenoh.Sample) -> None:
        now = time.perf_counter()
        report = msgspec.json.decode(sample.payload.to_bytes(), type=AssignmentReport)
        with self.lock:
            self.commits[(report.mission, report.uav)] = now
            self.digests.setdefault(report.mission, set()).add(report.digest)

    def on_link(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.live.add(uav_id_of(str(sample.key_expr)))

    def close(self) -> None:
        for subscriber in self.subscribers:
            subscriber.undeclare()


def measure(size: int, missions: int, workdir: Path) -> list[tuple[float, float, bool]]:
    fleet = Fleet()
    rows = []
    try:
        with router_session() as running, client_session(running.endpoints[0]) as ground:
            router = running.endpoints[0]
            arrivals = Arrivals(ground)
            scenario = workdir / f"ring{size}.toml"
            scenario.write_text(ring_scenario(size))
            endpoints = fleet.sim(str(scenario), 1.0, 5.0)
            for uav, where in endpoints.items():
                fleet.onboard(uav, where, router)
            team = tuple(sorted(endpoints))
            wait_until(lambda: set(team) <= arrivals.live, 120.0, "every UAV up")
            time.sleep(2.0)  # let every process settle after start-up
            for mission in range(1, missions + 1):
                message = MissionTargets(mission, team, ring_targets(10, seed=mission))
                sent = time.perf_counter()
                ground.put(SPACE.mission_targets(mission), encode(message), encoding=ENCODING)

                def committed(mission: int = mission) -> bool:
                    return all((mission, u) in arrivals.commits for u in team)

                wait_until(committed, 60.0, f"mission {mission} committed")
                with arrivals.lock:
                    last_result = max(arrivals.results.get((mission, u), sent) for u in team)
                    last_commit = max(arrivals.commits[(mission, u)] for u in team)
                    agreed = len(arrivals.digests[mission]) == 1
                rows.append((last_result - sent, last_commit - last_result, agreed))
                print(
                    f"  N={size:<3} mission {mission}: model {1000 * (last_result - sent):7.1f} ms"
                    f"  consensus {1000 * (last_commit - last_result):6.1f} ms  agreed={agreed}",
                    file=sys.stderr,
                )
                time.sleep(1.0)
            arrivals.close()
    finally:
        fleet.stop_all()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 5, 10, 20])
    parser.add_argument("--missions", type=int, default=3)
    args = parser.parse_args()
    print(
        f"{'N':>3} {'model ms (median)':>18} {'consensus ms (median)':>22} {'whole ms':>9} agreed"
    )
    with tempfile.TemporaryDirectory() as workdir:
        for size in args.sizes:
            rows = measure(size, args.missions, Path(workdir))
            model = statistics.median(r[0] for r in rows) * 1000
            consensus = statistics.median(r[1] for r in rows) * 1000
            whole = statistics.median(r[0] + r[1] for r in rows) * 1000
            agreed = all(r[2] for r in rows)
            print(f"{size:>3} {model:>18.1f} {consensus:>22.1f} {whole:>9.1f} {agreed}")
            assert not math.isnan(whole)


if __name__ == "__main__":
    main()
