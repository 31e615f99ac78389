"""The gateway: every live UAV as a MAVLink 2 vehicle on one endpoint.

One thread runs the MAVLink side (`run`): it reads the endpoint, answers, and streams
each UAV's messages from its system id (HEARTBEAT, SYS_STATUS, EXTENDED_SYS_STATE,
GPS_RAW_INT, HOME_POSITION and MISSION_CURRENT at 1 Hz, GLOBAL_POSITION_INT, ATTITUDE
and VFR_HUD at `POSITION_HZ`; STATUSTEXT as status messages arrive). The fleet side is
the ground's `FleetView` (subscriptions) refreshed by state queries once a second on a
thread of its own; what blocks on the fleet
(sending a mission, confirming an abort) runs on worker threads whose answers come
back to the loop through the outbox, so a ground station is never kept waiting by
Zenoh, and the loop alone writes to the endpoint.
"""

from __future__ import annotations

import logging
import queue
import struct
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets
from fleet.mission.phase import Phase, Severity
from fleet.transport.bus import Bus
from ground.alerts import StatusRecord
from ground.fleet_view import FleetView, UavView
from ground.mavlink import signing, vehicle
from ground.mavlink.endpoint import Address, Endpoint, Incoming, InputDrops
from ground.mavlink.fleet_link import FleetLink
from ground.mavlink.signing import StationKey, signing_encoder
from ground.mavlink.sysids import SysIdMap

log = logging.getLogger(__name__)

POSITION_HZ = 4.0
STATE_REFRESH_S = 1.0
#: Status messages waiting to be sent at most (a burst beyond is dropped, oldest first).
STATUS_BACKLOG = 200


@dataclass
class Vehicle:
    """What the loop keeps about one UAV shown as a system id."""

    piccolo: int
    sysid: int
    reached: set[tuple[int, int]] = field(default_factory=set)  #: (mission, target) told


class Gateway:
    def __init__(
        self,
        bus: Bus,
        space: KeySpace,
        fleet: FleetLink,
        endpoint: Endpoint,
        sysids: SysIdMap,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        #: The live picture; the caller enters it (its subscriptions) for as long as it runs.
        self.view = FleetView(bus, space, on_status=self.on_status)
        self.fleet = fleet
        self.endpoint = endpoint
        self.sysids = sysids
        self.drops: InputDrops = endpoint.drops
        self._clock = clock
        self._started = clock()
        self._encoders: dict[tuple[int, str | None], mavlink2.MAVLink] = {}
        #: (from system, message, to the station at this address or None: every station)
        self.outbox: queue.SimpleQueue[tuple[int, mavlink2.MAVLink_message, Address | None]] = (
            queue.SimpleQueue()
        )
        self._statuses: queue.Queue[StatusRecord] = queue.Queue(STATUS_BACKLOG)
        self._chunk_id = 0
        self.statuses_lost = 0  #: status messages not sent: more came than the loop sent
        self._chunk_lock = threading.Lock()
        self.vehicles: dict[int, Vehicle] = {}  #: by system id
        self._homes: dict[int, tuple[float, float]] = {}  #: by Piccolo ID
        self._hidden_said: set[int] = set()
        self._missions: dict[int, MissionTargets] = {}
        self._missions_lock = threading.Lock()
        self.workers = ThreadPoolExecutor(max_workers=2, thread_name_prefix="mavlink-fleet")
        self._next_slow = 0.0
        self._next_fast = 0.0

    # ---- the fleet side (other threads) --------------------------------------------------
    def on_status(self, record: StatusRecord) -> None:
        """FleetView's status callback (a Zenoh thread): queue it for the loop."""
        try:
            self._statuses.put_nowait(record)
        except queue.Full:
            self.statuses_lost += 1
            if self.statuses_lost == 1 or self.statuses_lost % STATUS_BACKLOG == 0:
                log.warning(
                    "status backlog full: %d status message(s) not sent (UAV %d's last)",
                    self.statuses_lost,
                    record.uav,
                )

    def refresh_forever(self, stop: threading.Event, timeout_s: float) -> None:
        """Fill in the phases, missions and targets the subscriptions do not carry."""
        while not stop.is_set():
            try:
                self.view.refresh_states(timeout_s)
                flown = {v.mission for v in self.view.snapshot() if v.mission is not None}
                for mission in flown:
                    with self._missions_lock:
                        known = mission in self._missions
                    if not known and (found := self.fleet.mission_targets(mission)) is not None:
                        with self._missions_lock:
                            self._missions[mission] = found
                with self._missions_lock:
                    # Only the missions some UAV is on are needed: a long run stays bounded.
                    for mission in [m for m in self._missions if m not in flown]:
                        del self._missions[mission]
            except Exception:  # a bad answer must not end the refresh
                log.exception("refreshing the fleet's state failed; trying again")
            stop.wait(STATE_REFRESH_S)

    def mission_of(self, mission: int | None) -> MissionTargets | None:
        if mission is None:
            return None
        with self._missions_lock:
            return self._missions.get(mission)

    def remember_mission(self, targets: MissionTargets) -> None:
        with self._missions_lock:
            self._missions[targets.mission] = targets

    # ---- the loop ------------------------------------------------------------------------
    def boot_ms(self) -> int:
        return int((self._clock() - self._started) * 1000)

    def send(
        self, sysid: int, message: mavlink2.MAVLink_message, to: Address | None = None
    ) -> None:
        """`message` from system `sysid` to every station (or the one at `to`: an answer
        goes to the station that asked), signed with each station's secret when the
        gateway signs (an encoder per system and secret)."""

        def pack(key: StationKey | None) -> bytes:
            slot = (sysid, key.name if key is not None else None)
            encoder = self._encoders.get(slot)
            if encoder is None:
                encoder = self._encoders[slot] = signing_encoder(sysid, key)
            return signing.pack(encoder, message, time.time)

        self.endpoint.send(pack, to)

    def run(
        self,
        stop: threading.Event,
        handle: Callable[[Incoming], None],
        tick: Callable[[], None],
    ) -> None:
        """Until `stop`: read and `handle` input, send what workers answered, `tick`
        (the transfers' timeouts), stream."""
        while not stop.is_set():
            for incoming in self.endpoint.receive(0.05):
                try:
                    handle(incoming)
                except Exception:  # one bad message must not end the gateway
                    log.exception("handling %s failed", incoming.message.get_type())
            self.send_answers()
            tick()
            self._tick()

    def send_answers(self) -> None:
        """Send what the workers answered (the loop does it after each read)."""
        while True:
            try:
                sysid, message, to = self.outbox.get_nowait()
            except queue.Empty:
                return
            self.send(sysid, message, to)

    def live_vehicles(self) -> list[tuple[Vehicle, UavView]]:
        """The live UAVs that have a system id, with their view."""
        shown: list[tuple[Vehicle, UavView]] = []
        for view in self.view.snapshot():
            sysid = self.sysids.sysid_of(view.id)
            if sysid is None:
                if view.id not in self._hidden_said:
                    self._hidden_said.add(view.id)
                    log.error("%s", self.sysids.why_hidden(view.id))
                continue
            found = self.vehicles.get(sysid)
            if found is None or found.piccolo != view.id:
                found = self.vehicles[sysid] = Vehicle(view.id, sysid)
                log.info("UAV %d shown as MAVLink system %d", view.id, sysid)
            shown.append((found, view))
        return shown

    def vehicle(self, sysid: int) -> tuple[Vehicle, UavView] | None:
        for found, view in self.live_vehicles():
            if found.sysid == sysid:
                return found, view
        return None

    def _tick(self) -> None:
        now = self._clock()
        self._send_statuses()
        if now >= self._next_fast:
            self._next_fast = now + 1.0 / POSITION_HZ
            slow = now >= self._next_slow
            if slow:
                self._next_slow = now + 1.0
            for found, view in self.live_vehicles():
                try:
                    self._stream(found, view, slow)
                except (ValueError, OverflowError, struct.error) as error:
                    # A value no MAVLink field can hold, from the bus: skip this turn.
                    log.warning("UAV %d: a message not sent: %s", found.piccolo, error)

    def home_of(self, piccolo: int) -> tuple[float, float] | None:
        """Where the gateway first heard UAV `piccolo` (its HOME_POSITION), None before."""
        home = self._homes.get(piccolo)
        telemetry = self.view.telemetry(piccolo) if home is None else None
        if telemetry is not None and telemetry.gps is not None:
            home = self._homes[piccolo] = (telemetry.gps.lat, telemetry.gps.lon)
        return home

    def _stream(self, found: Vehicle, view: UavView, slow: bool) -> None:
        sysid, boot = found.sysid, self.boot_ms()
        telemetry = self.view.telemetry(found.piccolo)
        if slow:
            self.send(sysid, vehicle.heartbeat(view, telemetry))
            self.send(sysid, vehicle.sys_status(view, telemetry, self.drops.total()))
            self.send(sysid, vehicle.extended_sys_state(telemetry))
            if telemetry is not None and (raw := vehicle.gps_raw(telemetry, boot)) is not None:
                self.send(sysid, raw)
            if (home := self.home_of(found.piccolo)) is not None:
                self.send(sysid, vehicle.home_position(*home))
            self._mission_progress(found, view)
        if telemetry is not None:
            for message in (
                vehicle.global_position(telemetry, boot),
                vehicle.attitude(telemetry, boot),
                vehicle.vfr_hud(view, telemetry),
            ):
                if message is not None:
                    self.send(sysid, message)

    def _mission_progress(self, found: Vehicle, view: UavView) -> None:
        """MISSION_CURRENT from the UAV's target; MISSION_ITEM_REACHED once per target
        the UAV reported reached: what it observed, never what was asked."""
        targets = self.mission_of(view.mission)
        if targets is None or view.mission is None or view.target is None:
            return
        # Each target of its queue it reported reaching on the way (task queues), then
        # the one it flies to if its state says reached.
        for target in view.reached:
            if target < len(targets.targets) and (view.mission, target) not in found.reached:
                found.reached.add((view.mission, target))
                self.send(found.sysid, mavlink2.MAVLink_mission_item_reached_message(target))
        reached = vehicle.phase_of(view) == Phase.REACHED
        if reached and (view.mission, view.target) not in found.reached:
            found.reached.add((view.mission, view.target))
            self.send(found.sysid, mavlink2.MAVLink_mission_item_reached_message(view.target))
        self.send(found.sysid, vehicle.mission_current(view.target, len(targets.targets), reached))

    def _send_statuses(self) -> None:
        while True:
            try:
                record = self._statuses.get_nowait()
            except queue.Empty:
                return
            self.say(record.uav, record.text, record.severity)

    def say(self, piccolo: int, text: str, severity: Severity) -> None:
        """STATUSTEXT from UAV `piccolo`'s system id (nothing if it has none)."""
        sysid = self.sysids.sysid_of(piccolo)
        if sysid is None:
            return
        for message in self.status_texts(text, severity):
            self.send(sysid, message)

    def status_texts(self, text: str, severity: Severity) -> list[mavlink2.MAVLink_message]:
        """`text` as STATUSTEXT, with a chunk id of its own (any thread)."""
        with self._chunk_lock:
            self._chunk_id = self._chunk_id % 65535 + 1
            chunk_id = self._chunk_id
        return list(vehicle.status_texts(text, severity, chunk_id))
