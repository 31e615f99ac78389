"""What the ground knows about each UAV: the thesis's UAV list (3.1.2) and map state.

Two ways to learn it:

* `fleet_snapshot`: one look, for `ground-cli uavs`. The live UAVs are the liveliness
  tokens `fleet/uav/*/alive` (a UAV whose process died is gone within milliseconds);
  each one's position, waypoint, module state and telemetry age come from a
  `fleet/uav/*/state` query, which a UAV answers with its UavState.
* `FleetView`: a live picture, for `watch` and `fleet demo`: a liveliness subscription
  (with history, so UAVs already up are reported too) plus telemetry, track, waypoint
  and status subscriptions, and state queries on demand to fill in what is not
  published (module on/off, mission phase).

A liveliness token carries no signature: any router on the way, or any client the
router lets declare it, can make one up for a Piccolo ID of the roster. So in the secure
profile (`Bus.signed`) both show a UAV only once it has spoken for itself: its state
answered, signed by its own key, or its streams heard (each sample is delivered only
once the UAV's signed digest lists it, `fleet.transport.stream_auth`). A token alone
shows no aircraft.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from fleet.mission.key_check import WrongKey, uav_of
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionProgress, StatusText, UavState
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from fleet.transport.bus import Bus, BusSample, decode_sample
from fleet.transport.bus_codec import DropReason, refuse
from ground.alerts import Alerts, StatusRecord
from ground.declarations import Declarations, Enter

log = logging.getLogger(__name__)


#: The selector parameter asking teammates to relay a UAV's signed state (the onboard's
#: `RELAYED`; the ground imports no onboard).
RELAYED = "relayed"

#: How many status messages the live view keeps (the thesis's status box).
STATUS_HISTORY = 200


@dataclass(frozen=True)
class UavView:
    """One row of the UAV list. None wherever the ground has not heard the value."""

    id: int
    lat: float | None = None
    lon: float | None = None
    alt: float | None = None
    ground_speed: float | None = None  #: m/s, from the GPS velocity
    airspeed: float | None = None  #: m/s indicated
    heading: float | None = None  #: degrees true, 0-360
    tracked_waypoint: int | None = None
    enabled: bool | None = None  #: the onboard planning module on/off
    status_rate_hz: float | None = None
    telemetry_age_s: float | None = None
    mission: int | None = None
    phase: str | None = None  #: a `fleet.mission.phase.Phase` value, as the UAV reported it
    reason: str | None = None  #: why the phase is what it is (preempted, failed, link_lost)
    target: int | None = None
    last_status: str | None = None
    #: The turns of its route to its target around no-fly zones, (lat, lon) each.
    route: tuple[tuple[float, float], ...] = ()
    #: How many targets its queue holds, None before a commitment.
    queue: int | None = None
    #: The targets of its mission it reported reaching itself, in index order.
    reached: tuple[int, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "lat": self.lat,
            "lon": self.lon,
            "alt": self.alt,
            "ground_speed": self.ground_speed,
            "airspeed": self.airspeed,
            "heading": self.heading,
            "tracked_waypoint": self.tracked_waypoint,
            "enabled": self.enabled,
            "status_rate_hz": self.status_rate_hz,
            "telemetry_age_s": self.telemetry_age_s,
            # The autopilot link's age as the UAV measured it (same value, the name the
            # operator's docs use).
            "link_age_s": self.telemetry_age_s,
            "mission": self.mission,
            "phase": self.phase,
            "reason": self.reason,
            "target": self.target,
            "last_status": self.last_status,
            "route": [list(turn) for turn in self.route],
            "queue": self.queue,
            "reached": list(self.reached),
        }


def with_telemetry(view: UavView, telemetry: Telemetry) -> UavView:
    """`view` updated with what a telemetry packet says."""
    gps, sensor = telemetry.gps, telemetry.sensor
    changes: dict[str, Any] = {}
    if gps is not None:
        changes.update(
            lat=gps.lat,
            lon=gps.lon,
            alt=gps.alt,
            ground_speed=math.hypot(gps.vel_north, gps.vel_east),
        )
        if sensor is None and (gps.vel_north or gps.vel_east):
            # No attitude block: the GPS course is the best heading there is.
            changes["heading"] = math.degrees(math.atan2(gps.vel_east, gps.vel_north)) % 360
    if sensor is not None:
        changes.update(heading=sensor.yaw % 360, airspeed=sensor.indicated_airspeed)
    return replace(view, **changes)


def _age(seconds: float | None) -> float | None:
    # Clocks sampled a hair apart can report a few milliseconds below zero; an age is
    # never negative.
    return None if seconds is None else max(0.0, seconds)


def view_from_state(state: UavState) -> UavView:
    view = UavView(
        id=state.uav,
        tracked_waypoint=state.tracked_waypoint,
        enabled=state.enabled,
        status_rate_hz=state.status_rate_hz,
        telemetry_age_s=_age(state.link.telemetry_age_s) if state.link is not None else None,
        last_status=state.last_status,
        phase=str(state.phase),
        reason=state.reason,
    )
    if state.telemetry is not None:
        view = with_telemetry(view, state.telemetry)
    if state.mission is not None:
        assignment = state.mission.assignment
        view = replace(
            view,
            mission=state.mission.mission,
            target=current_target(state.mission),
            route=state.mission.route,
            queue=queue_length(assignment, state.uav),
            reached=tuple(
                sorted(t for t, uav in state.mission.reached.items() if uav == state.uav)
            ),
        )
    return view


def current_target(progress: MissionProgress) -> int | None:
    """The target the UAV flies to now (or last flew to): what it says, else, from a UAV
    that does not say, the first of its queue."""
    if progress.current_target is not None:
        return progress.current_target
    return progress.assignment.target if progress.assignment is not None else None


def queue_length(assignment: AssignmentReport | None, uav: int) -> int | None:
    """How many targets `uav`'s queue holds in `assignment` (a report without queues: its
    one target or none); None without an assignment."""
    if assignment is None:
        return None
    if assignment.queues:
        return len(assignment.queues.get(uav, ()))
    return 0 if assignment.target is None else 1


def _token_ids(bus: Bus, space: KeySpace, timeout_s: float) -> list[int]:
    """The Piccolo IDs whose liveliness token `fleet/uav/{id}/alive` is declared."""
    ids: set[int] = set()
    for key in bus.live_tokens(space.all_alive, timeout_s):
        try:
            ids.add(uav_of(key, space))
        except WrongKey as error:
            log.warning("ignored liveliness token: %s", refuse(str(error), DropReason.WRONG_KEY))
    return sorted(ids)


def _vouched(bus: Bus, ids: list[int], states: Mapping[int, UavState | None]) -> list[int]:
    """`ids`, in the secure profile only those whose own signed state answered (or, for
    the team, was relayed: `live_uav_ids`)."""
    if not bus.signed:
        return ids
    unvouched = [uav for uav in ids if uav not in states]
    if unvouched:
        log.info(
            "not listed: UAV(s) %s: a liveliness token, but no state signed by the UAV",
            ", ".join(map(str, unvouched)),
        )
    return [uav for uav in ids if uav in states]


def live_uav_ids(bus: Bus, space: KeySpace, timeout_s: float) -> list[int]:
    """The Piccolo IDs whose liveliness token is declared: the UAVs `send-targets` picks a
    team from. In the secure profile only those that spoke for themselves: their own
    state answered, signed by their own key, or, for a UAV that did not answer (frozen,
    or cut off, a moment ago: it must stay in the team, and fetches the mission when it
    resumes), its latest state as it signed it, relayed by a teammate that heard it put.
    Either is refused when signed longer ago than the replay window, so a ghost token
    (no key of the UAV's behind it) never joins a team."""
    ids = _token_ids(bus, space, timeout_s)
    if not bus.signed or not ids:
        return ids
    states = query_states(bus, space, timeout_s)
    silent = [uav for uav in ids if uav not in states]
    relayed = {uav for uav in silent if _relayed_state(bus, space, uav, timeout_s) is not None}
    if relayed:
        log.info(
            "UAV(s) %s did not answer: counted on their own signed state, relayed by a teammate",
            ", ".join(map(str, sorted(relayed))),
        )
    return _vouched(bus, ids, {**{uav: None for uav in relayed}, **states})


def _relayed_state(bus: Bus, space: KeySpace, uav: int, timeout_s: float) -> UavState | None:
    """UAV `uav`'s latest state as it signed it, relayed by a teammate (the bus checks the
    signature is `uav`'s own and its age); None if none came."""
    key = space.state(uav)
    for reply_key, state in bus.query_messages(f"{key}?{RELAYED}", UavState, timeout_s):
        if reply_key == key and state.uav == uav:
            return state
    return None


def query_states(bus: Bus, space: KeySpace, timeout_s: float) -> dict[int, UavState]:
    return {
        state.uav: state for _, state in bus.query_messages(space.all_state, UavState, timeout_s)
    }


def fleet_snapshot(bus: Bus, space: KeySpace, timeout_s: float) -> list[UavView]:
    """Every live UAV, with what its state query said (just its id if it did not answer)."""
    ids = _token_ids(bus, space, timeout_s)
    states = query_states(bus, space, timeout_s) if ids else {}
    ids = _vouched(bus, ids, states)
    return [view_from_state(states[i]) if i in states else UavView(id=i) for i in ids]


@dataclass
class _Uav:
    view: UavView
    alive: bool = True
    telemetry_at: float | None = None  #: monotonic time the last telemetry arrived
    waypoints: dict[int, Waypoint] = field(default_factory=dict)
    track_history: list[int] = field(default_factory=list)
    telemetry: Telemetry | None = None  #: the latest packet, whole (attitude, rates)
    #: The UAV spoke for itself (its streams or its state): in the secure profile, a
    #: token alone does not show it.
    vouched: bool = False


class FleetView(Declarations):
    """A live, thread-safe picture of the fleet, fed by subscriptions.

    Zenoh runs the callbacks on its own threads; everything they touch is under one
    lock, and readers get copies. `on_status` (if given) is called for every status
    message, outside the lock, e.g. to print it as it arrives. Warnings and errors are
    also pinned (`alerts`, the rules of `ground.alerts`).
    """

    def __init__(
        self,
        bus: Bus,
        space: KeySpace,
        on_status: Callable[[StatusRecord], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._bus = bus
        self._space = space
        self._on_status = on_status
        self._clock = clock
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._uavs: dict[int, _Uav] = {}
        self._records: deque[StatusRecord] = deque(maxlen=STATUS_HISTORY)
        self._alerts = Alerts()
        #: Whether a UAV must speak for itself to be shown (the secure profile).
        self._signed = bus.signed
        super().__init__()

    def _declare(self, enter: Enter) -> None:
        bus, space = self._bus, self._space
        enter(bus.subscribe_presence(space.all_alive, self._on_alive))
        enter(bus.subscribe(space.all_telemetry, self._on_telemetry))
        enter(bus.subscribe(space.all_track, self._on_track))
        enter(bus.subscribe(space.all_waypoints, self._on_waypoint))
        enter(bus.subscribe(space.all_status, self._on_status_sample))

    # ---- callbacks (Zenoh threads) ------------------------------------------------
    def _entry(self, uav_id: int, vouched: bool = True) -> _Uav:
        """The UAV's entry; `vouched`: what is heard of it came from the UAV itself (a
        stream sample, its state: signed in the secure profile), not from a token."""
        entry = self._uavs.get(uav_id)
        if entry is None:
            entry = self._uavs[uav_id] = _Uav(UavView(id=uav_id))
        entry.vouched = entry.vouched or vouched
        return entry

    def _shown(self, entry: _Uav, include_gone: bool = False) -> bool:
        return (entry.alive or include_gone) and (entry.vouched or not self._signed)

    def _on_alive(self, key: str, alive: bool) -> None:
        uav_id = _uav_of(key, self._space)
        if uav_id is None:
            return
        with self._changed:
            self._entry(uav_id, vouched=False).alive = alive
            self._changed.notify_all()
        log.info("UAV %d %s", uav_id, "joined" if alive else "left")

    def _on_telemetry(self, sample: BusSample) -> None:
        uav_id = _uav_of(sample.key, self._space)
        telemetry = decode_sample(sample, Telemetry)
        if uav_id is None or telemetry is None:
            return
        with self._changed:
            entry = self._entry(uav_id)
            entry.view = with_telemetry(entry.view, telemetry)
            entry.telemetry = telemetry
            entry.telemetry_at = self._clock()
            self._changed.notify_all()

    def _on_track(self, sample: BusSample) -> None:
        uav_id = _uav_of(sample.key, self._space)
        track = decode_sample(sample, Track)
        if uav_id is None or track is None:
            return
        with self._changed:
            entry = self._entry(uav_id)
            entry.view = replace(entry.view, tracked_waypoint=track.waypoint)
            if not entry.track_history or entry.track_history[-1] != track.waypoint:
                entry.track_history.append(track.waypoint)
            self._changed.notify_all()

    def _on_waypoint(self, sample: BusSample) -> None:
        uav_id = _uav_of(sample.key, self._space)
        waypoint = decode_sample(sample, Waypoint)
        if uav_id is None or waypoint is None:
            return
        with self._changed:
            self._entry(uav_id).waypoints[waypoint.index] = waypoint
            self._changed.notify_all()

    def _on_status_sample(self, sample: BusSample) -> None:
        uav_id = _uav_of(sample.key, self._space)
        status = decode_sample(sample, StatusText)
        if uav_id is None or status is None:
            return
        record = StatusRecord(time.time(), uav_id, status.text, status.kind, status.mission)
        with self._changed:
            entry = self._entry(uav_id)
            entry.view = replace(entry.view, last_status=status.text)
            self._records.append(record)
            self._alerts.add(record)
            self._changed.notify_all()
        if self._on_status is not None:
            self._on_status(record)

    # ---- queries and readers (caller's thread) --------------------------------------
    def refresh_states(self, timeout_s: float) -> None:
        """Fill in what is only in state answers (module on/off, mission phase, target)."""
        states = query_states(self._bus, self._space, timeout_s)
        with self._changed:
            for uav_id, state in states.items():
                entry = self._entry(uav_id)
                fresh = view_from_state(state)
                if entry.telemetry_at is not None:
                    # The subscription's telemetry is newer than the state's copy.
                    fresh = replace(
                        fresh,
                        lat=entry.view.lat,
                        lon=entry.view.lon,
                        alt=entry.view.alt,
                        ground_speed=entry.view.ground_speed,
                        airspeed=entry.view.airspeed,
                        heading=entry.view.heading,
                        telemetry_age_s=None,
                    )
                entry.view = fresh
            self._changed.notify_all()

    def snapshot(self, include_gone: bool = False) -> list[UavView]:
        """The UAVs (live ones only unless `include_gone`), by Piccolo ID."""
        now = self._clock()
        with self._lock:
            views = []
            for uav_id in sorted(self._uavs):
                entry = self._uavs[uav_id]
                if not self._shown(entry, include_gone):
                    continue
                view = entry.view
                if entry.telemetry_at is not None:
                    view = replace(view, telemetry_age_s=now - entry.telemetry_at)
                views.append(view)
            return views

    def live_ids(self) -> list[int]:
        with self._lock:
            return sorted(i for i, entry in self._uavs.items() if self._shown(entry))

    def waypoints(self, uav_id: int) -> dict[int, Waypoint]:
        with self._lock:
            entry = self._uavs.get(uav_id)
            return dict(entry.waypoints) if entry else {}

    def telemetry(self, uav_id: int) -> Telemetry | None:
        """The latest telemetry packet from `uav_id`, None before any."""
        with self._lock:
            entry = self._uavs.get(uav_id)
            return entry.telemetry if entry else None

    def track_history(self, uav_id: int) -> list[int]:
        with self._lock:
            entry = self._uavs.get(uav_id)
            return list(entry.track_history) if entry else []

    def recent_records(self, count: int = STATUS_HISTORY) -> list[StatusRecord]:
        """The last `count` status messages with their kind, oldest first."""
        with self._lock:
            return list(self._records)[-count:]

    def alerts(self) -> list[StatusRecord]:
        """The warnings and errors kept in view (`ground.alerts`), oldest first."""
        with self._lock:
            return self._alerts.pinned()

    def statuses_of(self, uav_id: int) -> list[str]:
        with self._lock:
            return [record.text for record in self._records if record.uav == uav_id]

    def wait_changed(self, timeout_s: float) -> None:
        """Block until a callback changed something, or `timeout_s` passed."""
        with self._changed:
            self._changed.wait(timeout_s)

    def wait_for(self, ids: set[int], timeout_s: float) -> set[int]:
        """Wait until every UAV in `ids` is live; returns those still missing."""
        deadline = self._clock() + timeout_s
        while True:
            missing = ids - set(self.live_ids())
            remaining = deadline - self._clock()
            if not missing or remaining <= 0:
                return missing
            self.wait_changed(min(remaining, 0.5))


def _uav_of(key: str, space: KeySpace) -> int | None:
    try:
        return uav_of(key, space)
    except WrongKey as error:
        log.warning("ignored: %s", refuse(str(error), DropReason.WRONG_KEY))
        return None


# ---- presentation ------------------------------------------------------------------------
_COLUMNS = (
    ("ID", 5),
    ("LAT", 11),
    ("LON", 12),
    ("ALT m", 7),
    ("GS m/s", 6),
    ("HDG", 5),
    ("WP", 4),
    ("OPM", 4),
    ("MISSION", 8),
    ("PHASE", 10),
    ("TGT", 4),
    ("QUEUE", 5),
    ("TLM AGE", 8),
)


def _cell(value: object, digits: int = 1) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def format_table(views: list[UavView]) -> str:
    """The UAV list as a fixed-width text table, one row per UAV."""
    header = " ".join(name.rjust(width) for name, width in _COLUMNS)
    lines = [header]
    for v in views:
        age = f"{v.telemetry_age_s:.1f} s" if v.telemetry_age_s is not None else "-"
        cells = (
            _cell(v.id),
            _cell(v.lat, 6),
            _cell(v.lon, 6),
            _cell(v.alt),
            _cell(v.ground_speed),
            _cell(v.heading, 0),
            _cell(v.tracked_waypoint),
            _cell(v.enabled),
            _cell(v.mission),
            _cell(v.phase),
            _cell(v.target),
            _cell(v.queue),
            age,
        )
        lines.append(" ".join(c.rjust(w) for c, (_, w) in zip(cells, _COLUMNS, strict=True)))
    return "\n".join(lines)
