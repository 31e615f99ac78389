"""Test doubles of the onboard process, as the ground and the launcher see it on the bus.

`FakeOnboard` runs in the test's process (the ground's tests and bench_ground_scale), on
any bus: a Zenoh router's endpoint, or `memory:NAME` for the in-process bus the fast
tier's ground tests use (`open_bus`). `FAKE_ONBOARD` is a script the launcher runs in
place of `onboard.main` (`python -c`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import msgspec

from fleet.consensus.assignment import greedy_assign, results_digest
from fleet.consensus.targets_digest import targets_digest
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    OpmCommand,
    StatusText,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.piccolo.telemetry import GpsBlock, SensorBlock, Telemetry
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusSample, Queryable
from fleet.transport.bus_factory import MEMORY_SCHEME, forget_memory_network, open_bus

SPACE = KeySpace()

#: A test double of `onboard`: joins Zenoh, declares its liveliness token, publishes a
#: telemetry sample with a GPS fix five times a second (what the launcher waits for), and
#: exits cleanly on SIGTERM. Nothing else. With --silent it publishes no telemetry.
FAKE_ONBOARD = """
import argparse, signal, threading, zenoh
from fleet.transport.cli import add_key_prefix_argument
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.transport import bus_codec
from fleet.transport.zenoh_config import make_config
parser = argparse.ArgumentParser()
parser.add_argument("--id", type=int, required=True)
parser.add_argument("--connect", required=True)
parser.add_argument("--silent", action="store_true")
add_key_prefix_argument(parser)  # $FLEET_KEY_PREFIX, as onboard
args, _ = parser.parse_known_args()
stop = threading.Event()
signal.signal(signal.SIGTERM, lambda *_: stop.set())
fix = Telemetry(system_time_ms=0, gps=GpsBlock(35.72, -120.76, 600.0, 0.0, 22.0, 0.0))
with zenoh.open(make_config("client", [args.connect])) as session:
    token = session.liveliness().declare_token(args.key_space.alive(args.id))
    while not stop.wait(0.2):
        if not args.silent:
            session.put(args.key_space.telemetry(args.id), bus_codec.encode(fix))
"""


def approach_time(uav: int, target: int) -> float:
    """The fake's approach-time model: arbitrary, but the same on every fake."""
    return 20.0 + float((uav * 7 + target * 13) % 41)


class FakeOnboard:
    """Test double of the `onboard` process, as seen on the bus."""

    def __init__(self, where: str | Bus, uav_id: int, lat: float, lon: float, alt: float) -> None:
        self.uav_id = uav_id
        self.lat, self.lon, self.alt = lat, lon, alt
        self.targets: list[MissionTargets] = []
        self.opms: list[OpmCommand] = []
        self.aborts: list[MissionAbort] = []
        self.publish_assignment = True  #: False: serve it by query only
        self.disagree = False  #: True: commit a different assignment from the others
        self.enabled = True
        #: True: ignore a mission whose id is not above the current one, as the onboard does
        self.keeps_current = False
        #: True: answer queries for a mission's targets, as an onboard holding it does
        self.serves_targets = False
        self.mission: MissionProgress | None = None
        self._served: dict[str, bytes] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        #: Its own bus (an endpoint or memory:NAME opened here), or the one it was given.
        self.bus = open_bus(where) if isinstance(where, str) else where
        try:
            self._state: Queryable = self.bus.declare_queryable(
                SPACE.state(uav_id), self._on_state_query
            )
            self._missions: Queryable = self.bus.declare_queryable(
                f"{SPACE.prefix}/mission/*/**", self._on_mission_query
            )
            self._declared = [
                self.bus.declare_token(SPACE.alive(uav_id)),
                self._state,
                self._missions,
                self.bus.subscribe(SPACE.all_mission_targets, self._on_targets),
                self.bus.subscribe(SPACE.all_mission_aborts, self._on_abort),
                self.bus.subscribe(SPACE.opm(uav_id), self._on_opm),
            ]
            self._thread = threading.Thread(target=self._publish_loop, daemon=True)
            self._thread.start()
        except BaseException:
            self.bus.close()
            raise

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.bus.close()

    def telemetry(self) -> Telemetry:
        return Telemetry(
            system_time_ms=int(time.monotonic() * 1000) % 2**32,
            gps=GpsBlock(self.lat, self.lon, self.alt, vel_north=0.0, vel_east=20.0, vel_down=0.0),
            sensor=SensorBlock(roll=0.0, pitch=0.0, yaw=90.0, indicated_airspeed=21.0),
        )

    def put(self, key: str, message: msgspec.Struct) -> None:
        self.bus.put(key, bus_codec.encode(message))

    def _publish_loop(self) -> None:
        ticks = 0
        while not self._stop.wait(0.1):
            self.put(SPACE.telemetry(self.uav_id), self.telemetry())
            ticks += 1
            if ticks % 5 == 0:
                self.put(SPACE.status(self.uav_id), StatusText(f"fake {self.uav_id} tick {ticks}"))

    def state(self) -> UavState:
        return UavState(
            uav=self.uav_id,
            enabled=self.enabled,
            status_rate_hz=1.0,
            tracked_waypoint=3,
            telemetry=self.telemetry(),
            link=None,
            mission=self.mission,
        )

    def _on_state_query(self) -> None:
        while (query := self._state.try_recv()) is not None:
            query.reply(SPACE.state(self.uav_id), self.state())
            query.drop()

    def _on_mission_query(self) -> None:
        while (query := self._missions.try_recv()) is not None:
            with self._lock:
                served = dict(self._served)
            for key, payload in served.items():
                if query.intersects(key):
                    query.reply_bytes(key, payload)
            query.drop()

    def _on_targets(self, sample: BusSample) -> None:
        targets = msgspec.json.decode(sample.payload, type=MissionTargets)
        with self._lock:
            self.targets.append(targets)
        if self.uav_id not in targets.team:
            return
        held = self.mission
        if self.keeps_current and held is not None and targets.mission <= held.mission:
            return
        m, n = targets.mission, len(targets.targets)
        rows = {u: [approach_time(u, i) for i in range(n)] for u in targets.team}
        result = UavResult(mission=m, uav=self.uav_id, times=tuple(rows[self.uav_id]))
        assignment = greedy_assign(rows, n)
        pairs = dict(assignment.pairs)
        digest = results_digest(rows)
        if self.disagree:
            pairs = {u: (t + 1) % n for u, t in pairs.items()}
            digest = "0" * 16
        report = AssignmentReport(
            mission=m,
            uav=self.uav_id,
            target=pairs.get(self.uav_id),
            pairs=pairs,
            unassigned=assignment.unassigned_targets,
            team=targets.team,
            digest=digest,
            eta_s=rows[self.uav_id][t] if (t := pairs.get(self.uav_id)) is not None else None,
        )
        with self._lock:
            if self.serves_targets:
                self._served[SPACE.mission_targets(m)] = bus_codec.encode(targets)
            self._served[SPACE.mission_result(m, self.uav_id)] = bus_codec.encode(result)
            self._served[SPACE.mission_assignment(m, self.uav_id)] = bus_codec.encode(report)
            self.mission = MissionProgress(
                m, Phase.COMMITTED, n, result, report, targets_digest=targets_digest(targets)
            )
        self.put(SPACE.mission_result(m, self.uav_id), result)
        if self.publish_assignment:
            self.put(SPACE.mission_assignment(m, self.uav_id), report)

    def _on_abort(self, sample: BusSample) -> None:
        abort = msgspec.json.decode(sample.payload, type=MissionAbort)
        with self._lock:
            self.aborts.append(abort)
            mine = abort.uav is None or abort.uav == self.uav_id
            if mine and self.mission is not None and self.mission.mission == abort.mission:
                self.mission = msgspec.structs.replace(self.mission, phase=Phase.ABORTED)

    def _on_opm(self, sample: BusSample) -> None:
        command = msgspec.json.decode(sample.payload, type=OpmCommand)
        with self._lock:
            self.opms.append(command)
        self.enabled = command.enabled
        self.put(
            SPACE.status(self.uav_id),
            StatusText(f"module {'on' if command.enabled else 'off'}, status every 1 s"),
        )


@contextmanager
def memory_bus(name: str) -> Iterator[str]:
    """`memory:NAME`, the spec of an in-process bus, forgotten on exit."""
    try:
        yield f"{MEMORY_SCHEME}{name}"
    finally:
        forget_memory_network(name)


@contextmanager
def fake_pair(where: str) -> Iterator[dict[int, FakeOnboard]]:
    """The ground tests' two fake UAVs near Boston, 74 and 112, on the bus `where`."""
    opened: dict[int, FakeOnboard] = {}
    try:
        opened[74] = FakeOnboard(where, 74, 42.3500, -71.1000, 150.0)
        opened[112] = FakeOnboard(where, 112, 42.3700, -71.0800, 160.0)
        yield opened
    finally:
        for fake in opened.values():
            fake.close()
