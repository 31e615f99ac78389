"""A whole fleet in one test process: the real onboard process logic and the real
simulated autopilots, joined by in-memory links and an in-memory bus (no socket, no
Zenoh session, no process).

The ground's commands run against it as they run against a live fleet: `run(bus,
options, out)` on a bus of the fleet's network (`MemoryFleet.bus`), or a program's
root with `--connect memory:NAME` (`MemoryFleet.spec`). Simulated time runs `speedup`
times faster than the wall clock, from one thread for every aircraft; a test may change
the speedup mid-run (`MemoryFleet.clock`), e.g. plan at the wall clock's pace, then fly
the plan fast.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import NoFlyZone, UavState
from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
from fleet.sim.linked import LinkedAutopilot
from fleet.sim.scenario import resolve_scenario
from fleet.transport.bus import Bus
from fleet.transport.bus_factory import MEMORY_SCHEME, forget_memory_network, memory_network
from fleet.transport.faulty_bus import FaultRule, FaultyBus
from fleet.transport.memory import MemoryNetwork, memory_link_pair
from onboard.planner.approach_highs import load_highs_core
from onboard.process import OnboardProcess, OnboardSettings
from tests.support.waiting import wait_until

SPACE = KeySpace()
#: Simulated seconds per wall second, unless told.
SPEEDUP = 10.0
#: How long a test waits for every UAV to be up with a GPS fix.
READY_S = 60.0

_names = itertools.count(1)


class SimClock:
    """Simulated time, `speedup` times the wall clock's pace; the speedup may change
    while it runs (the simulated time flown so far is kept)."""

    def __init__(self, speedup: float) -> None:
        self._lock = threading.Lock()
        self._speedup = speedup
        self._wall = time.monotonic()
        self._ms = 0.0  #: simulated ms at `_wall`

    def now_ms(self) -> int:
        with self._lock:
            return int(self._ms + (time.monotonic() - self._wall) * self._speedup * 1000.0)

    def set_speedup(self, speedup: float) -> None:
        with self._lock:
            wall = time.monotonic()
            self._ms += (wall - self._wall) * self._speedup * 1000.0
            self._wall, self._speedup = wall, speedup


@dataclass
class MemoryFleet:
    """A running fleet in memory (`memory_fleet`)."""

    name: str
    network: MemoryNetwork
    aircraft: dict[int, LinkedAutopilot]
    processes: dict[int, OnboardProcess]
    #: The aircraft's simulated time (its speedup can be changed mid-run).
    clock: SimClock
    #: Buses handed out by `bus`, closed when the fleet stops.
    _buses: list[Bus] = field(default_factory=list)

    @property
    def spec(self) -> str:
        """What `open_bus` (and `--connect`) takes for this fleet's bus."""
        return f"{MEMORY_SCHEME}{self.name}"

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(sorted(self.aircraft))

    def bus(self) -> Bus:
        """A new participant of the fleet's bus (a ground)."""
        bus = self.network.bus()
        self._buses.append(bus)
        return bus

    def stop_uav(self, uav: int) -> None:
        """Its onboard stops as a killed process would: its token and queryables go."""
        self.processes[uav].stop_requested.set()

    def wait_ready(self, timeout_s: float = READY_S) -> None:
        """Until every UAV is live and its state holds a GPS fix."""
        bus = self.bus()

        def ready() -> bool:
            fixed = set()
            for _, state in bus.query_messages(SPACE.all_state, UavState, 1.0):
                if state.telemetry is not None and state.telemetry.gps is not None:
                    fixed.add(state.uav)
            return fixed >= set(self.aircraft)

        wait_until(ready, timeout_s, "every UAV live with a GPS fix")


def _fly(aircraft: list[LinkedAutopilot], clock: SimClock, stop: threading.Event) -> None:
    while not stop.wait(0.002):
        now_ms = clock.now_ms()
        for one in aircraft:
            one.pump(now_ms)


def ring_file(folder: Path, uavs: int) -> str:
    """The ring scenario of `uavs` UAVs (`fleet up --uavs N`'s), written to
    folder/ring.toml: its path, as `memory_fleet` takes it."""
    path = folder / "ring.toml"
    path.write_text(ring_scenario(uavs))
    return str(path)


@contextmanager
def memory_fleet(
    scenario: str = "head_on",
    *,
    speedup: float = SPEEDUP,
    zones: tuple[NoFlyZone, ...] = (),
    ready: bool = True,
    status_rate_hz: float = 1.0,
    telemetry_hz: float = 5.0,
    relay_hz: float | None = None,
    faults: Mapping[int, tuple[FaultRule, ...]] | None = None,
    bus_of: Callable[[int], Bus] | None = None,
    proposers: frozenset[int] = frozenset(),
) -> Iterator[MemoryFleet]:
    """Every UAV of `scenario`, each an onboard process and a simulated autopilot; with
    `ready`, returned once every UAV is live with a GPS fix. Stopped on exit.

    `telemetry_hz`: how often each autopilot sends telemetry (simulated time);
    `relay_hz`: how often each onboard relays it on the bus (`--telemetry-hz`).
    `faults`: a UAV's onboard puts through the fault-injecting bus with these rules.
    `bus_of`: each UAV's onboard on the bus it gives (a real Zenoh session, say), not on
    the in-process one (then `ready` waits on nothing: the test knows where to look).
    `proposers`: these UAVs' onboards propose plans (`--propose`)."""
    faults = faults or {}
    # Loaded once before the onboards start: each would load it on its planner thread,
    # and a second thread can see the first's half-initialised module.
    load_highs_core()
    loaded = resolve_scenario(scenario)
    name = f"fleet-{next(_names)}"
    network = memory_network(name)
    settings = AutopilotSettings(
        telemetry_hz=telemetry_hz,
        limits=loaded.limits,
        wind=loaded.wind,
        zones=zones or loaded.zones,
    )
    aircraft: dict[int, LinkedAutopilot] = {}
    processes: dict[int, OnboardProcess] = {}
    for uav in loaded.uavs:
        program_onboard, program_sim = memory_link_pair(f"program-{uav.piccolo_id}")
        payload_onboard, payload_sim = memory_link_pair(f"payload-{uav.piccolo_id}")
        autopilot = SimulatedAutopilot(uav, settings, loaded.weather)
        aircraft[uav.piccolo_id] = LinkedAutopilot(autopilot, program_sim, payload_sim)
        onboard = OnboardSettings(
            uav_id=uav.piccolo_id,
            program_url="memory",
            payload_url="memory",
            status_rate_hz=status_rate_hz,
            telemetry_hz=relay_hz,
            propose=uav.piccolo_id in proposers,
        )
        bus: Bus = network.bus() if bus_of is None else bus_of(uav.piccolo_id)
        if uav.piccolo_id in faults:
            bus = FaultyBus(bus, *faults[uav.piccolo_id])
        processes[uav.piccolo_id] = OnboardProcess(
            onboard, links=(program_onboard, payload_onboard), bus=bus
        )
    fleet = MemoryFleet(name, network, aircraft, processes, SimClock(speedup))
    stop = threading.Event()
    threads = [
        threading.Thread(target=_fly, args=(list(aircraft.values()), fleet.clock, stop), name="sim")
    ]
    threads += [
        threading.Thread(target=process.run, name=f"onboard-{uav}")
        for uav, process in processes.items()
    ]
    for thread in threads:
        thread.start()
    try:
        if ready and bus_of is None:
            fleet.wait_ready()
        yield fleet
    finally:
        for process in processes.values():
            process.stop_requested.set()
        stop.set()
        for thread in threads:
            thread.join(timeout=10.0)
        for bus in fleet._buses:
            bus.close()
        forget_memory_network(name)
    assert not any(thread.is_alive() for thread in threads), "a fleet thread did not stop"
