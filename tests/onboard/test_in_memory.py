"""One UAV's mission round with every edge in memory: the real onboard process logic and
the real simulated autopilot in one test process, joined by in-memory links and an
in-memory bus (no sockets, no Zenoh session). The end-to-end tests with real processes
and real Zenoh are test_process.py and test_multi_uav.py.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib.resources import files

import msgspec
import pytest

from fleet.files.targets_io import read_targets
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    CommandResult,
    MissionTargets,
    NoFlyZone,
    UavResult,
    UavState,
)
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
from fleet.sim.linked import LinkedAutopilot
from fleet.sim.scenario import resolve_scenario
from fleet.transport import bus_codec
from fleet.transport.bus import BusSample
from fleet.transport.memory import MemoryBus, MemoryNetwork, memory_link_pair
from onboard.core import TARGET_WAYPOINT
from onboard.process import OnboardProcess, OnboardSettings
from tests.support.waiting import wait_until

SPACE = KeySpace()

UAV = 112
#: Simulated seconds per wall second.
SPEEDUP = 10.0


@dataclass
class Seen:
    """What the test, as the ground, saw on the bus."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    telemetry: list[Telemetry] = field(default_factory=list)
    results: dict[int, UavResult] = field(default_factory=dict)
    assignments: dict[int, AssignmentReport] = field(default_factory=dict)
    tokens: dict[str, bool] = field(default_factory=dict)

    def on_sample(self, sample: BusSample) -> None:
        with self.lock:
            if sample.key == SPACE.telemetry(UAV):
                self.telemetry.append(msgspec.json.decode(sample.payload, type=Telemetry))
            elif "/result/" in sample.key:
                result = msgspec.json.decode(sample.payload, type=UavResult)
                self.results[result.uav] = result
            elif "/assignment/" in sample.key:
                report = msgspec.json.decode(sample.payload, type=AssignmentReport)
                self.assignments[report.uav] = report

    def on_token(self, key: str, alive: bool) -> None:
        with self.lock:
            self.tokens[key] = alive


@dataclass
class World:
    network: MemoryNetwork
    ground: MemoryBus
    seen: Seen
    aircraft: LinkedAutopilot
    process: OnboardProcess


def _fly(aircraft: LinkedAutopilot, stop: threading.Event) -> None:
    start = time.monotonic()
    while not stop.wait(0.002):
        aircraft.pump(int((time.monotonic() - start) * SPEEDUP * 1000))


@pytest.fixture
def world() -> Iterator[World]:
    with running_world() as opened:
        yield opened


@contextmanager
def running_world(zones: tuple[NoFlyZone, ...] = ()) -> Iterator[World]:
    """The single-UAV scenario in memory; the simulator logs incursions into `zones`."""
    scenario = resolve_scenario("single_uav")
    autopilot = SimulatedAutopilot(
        scenario.uav(UAV),
        AutopilotSettings(
            telemetry_hz=5.0, limits=scenario.limits, wind=scenario.wind, zones=zones
        ),
    )
    program_onboard, program_sim = memory_link_pair("program")
    payload_onboard, payload_sim = memory_link_pair("payload")
    aircraft = LinkedAutopilot(autopilot, program_sim, payload_sim)
    network = MemoryNetwork()
    ground = network.bus()
    seen = Seen()
    ground.subscribe(SPACE.telemetry(UAV), seen.on_sample)
    ground.subscribe(SPACE.all_mission_results, seen.on_sample)
    ground.subscribe(f"{SPACE.prefix}/mission/*/assignment/*", seen.on_sample)
    ground.subscribe_presence(SPACE.all_alive, seen.on_token)
    settings = OnboardSettings(uav_id=UAV, program_url="memory", payload_url="memory")
    process = OnboardProcess(settings, links=(program_onboard, payload_onboard), bus=network.bus())
    stop = threading.Event()
    threads = [
        threading.Thread(target=_fly, args=(aircraft, stop), name="sim"),
        threading.Thread(target=process.run, name="onboard"),
    ]
    for thread in threads:
        thread.start()
    try:
        yield World(network, ground, seen, aircraft, process)
    finally:
        process.stop_requested.set()
        stop.set()
        for thread in threads:
            thread.join(timeout=10.0)
        ground.close()
    assert not any(thread.is_alive() for thread in threads)


def test_one_uav_mission_round_in_memory(world: World) -> None:
    seen = world.seen
    wait_until(lambda: seen.tokens.get(SPACE.alive(UAV)) is True, 10.0, "the UAV's token")
    wait_until(lambda: len(seen.telemetry) >= 2, 30.0, "telemetry relayed from the autopilot")
    states: list[UavState] = []
    world.ground.get(
        SPACE.state(UAV),
        lambda sample: states.append(msgspec.json.decode(sample.payload, type=UavState)),
        timeout=1.0,
    )
    wait_until(lambda: bool(states), 10.0, "the state query's answer")
    assert states[0].telemetry is not None and states[0].telemetry.gps is not None

    targets = tuple(read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin")))
    mission = MissionTargets(mission=1, team=(UAV,), targets=targets, deadline_s=10.0)
    world.ground.publish(SPACE.mission_targets(1), mission)

    wait_until(lambda: UAV in seen.assignments, 60.0, "the UAV's assignment")
    times = seen.results[UAV].times
    assert all(t is not None for t in times)
    fastest = min(range(len(times)), key=lambda i: times[i] or math.inf)
    report = seen.assignments[UAV]
    assert report.target == fastest == 1  # the scenario's target ahead, 15 degrees right
    # One UAV, three targets: it queues all three, the fastest first.
    assert report.team == (UAV,) and report.unassigned == ()
    assert report.queues[UAV][0] == 1 and sorted(report.queues[UAV]) == [0, 1, 2]
    # The aircraft itself was told: the simulated autopilot now tracks the target waypoint.
    wait_until(
        lambda: world.aircraft.autopilot.tracked == TARGET_WAYPOINT,
        30.0,
        "the autopilot tracking the target waypoint",
    )
    stored = world.aircraft.autopilot.plan.get(TARGET_WAYPOINT)
    assert stored is not None
    assert abs(stored.lat - targets[1].lat) < 1e-5 and abs(stored.lon - targets[1].lon) < 1e-5


def test_closing_the_uav_bus_withdraws_its_token(world: World) -> None:
    seen = world.seen
    wait_until(lambda: seen.tokens.get(SPACE.alive(UAV)) is True, 10.0, "the UAV's token")
    world.process.stop_requested.set()
    wait_until(lambda: seen.tokens.get(SPACE.alive(UAV)) is False, 10.0, "the token to go")


def test_a_command_query_is_answered_after_the_autopilot_echo(world: World) -> None:
    wait_until(lambda: len(world.seen.telemetry) >= 1, 30.0, "telemetry (the link is up)")
    answers: list[CommandResult] = []
    world.ground.get(
        SPACE.command(UAV, "track"),
        lambda sample: answers.append(msgspec.json.decode(sample.payload, type=CommandResult)),
        timeout=5.0,
        payload=bus_codec.encode(Track(2)),
    )
    wait_until(lambda: bool(answers), 10.0, "the command's answer")
    assert answers[0].ok and answers[0].detail == "confirmed by the autopilot"
    assert world.aircraft.autopilot.tracked == 2
