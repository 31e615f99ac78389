"""The onboard process: wires the link adapter, the bus edge and the module logic.

Threads: the link loop (onboard.link_adapter), the planner worker
(onboard.planner.planner_worker), Zenoh's own callback threads, and this main loop, which alone
touches the module's state: every other thread hands it events through one queue,
except telemetry, which the link loop publishes itself and leaves in a one-message slot
that the main loop reads on its next turn (`_from_link`), unless an echo from the
autopilot waits in the queue: telemetry then queues behind it, so that the module sees
the aircraft's positions and its track changes in the order the autopilot sent them.
The main loop sleeps on that queue until an event comes (a query or a planner result
too) or its next timer is due (the module's timers, command retries and status and
result fetches, need no finer than `TICK_PERIOD`), so an idle module does not wake
every few milliseconds.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from dataclasses import dataclass

import msgspec
import zenoh

from fleet.mission.key_check import WrongKey, parse_key
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.mission.messages import (
    BROADCAST,
    MISSION_MANAGER,
    AssignmentReport,
    CommandResult,
    LinkHealth,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    PlanProposal,
    StatusText,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.payload.link import AutopilotEvent, LinkEvent, PlanningEvent
from fleet.payload.protocol import encode_message
from fleet.piccolo.stream_packet import ALL_GROUND_STATIONS
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusQuery
from fleet.transport.bus_codec import BadMessage, decode
from fleet.transport.link import Link
from fleet.transport.refusal_log import RefusalLog
from fleet.transport.serial_port import DEFAULT_BAUD, SerialLink
from fleet.transport.zenoh_bus import ZenohBus
from onboard.autopilot_commands import AutopilotCommand
from onboard.bus_edge import (
    BusEdge,
    BusEvent,
    PresenceEvent,
    standing_asked,
    standing_selector,
)
from onboard.core import CONFIRM_LIMIT_S, LINK_RELEASE_S, OnboardCore
from onboard.link_adapter import LinkAdapter
from onboard.planner.planner_worker import PlannerWorker

log = logging.getLogger(__name__)
#: Refused input, logged at most every few seconds (a flood cannot fill the log).
_refusals = RefusalLog(log)


@dataclass(frozen=True)
class _QueuedTelemetry:
    """Telemetry that came after an autopilot echo still queued: handled after it."""

    telemetry: Telemetry
    at: float


#: What the link and bus threads hand the main loop.
Event = LinkEvent | BusEvent | PresenceEvent | _QueuedTelemetry

LINK_HEALTH_PERIOD = 1.0
#: The main loop runs the module's timers at least this often (events run them too).
TICK_PERIOD = 0.25
#: How often (s) a teammate whose liveliness token does not count yet is asked for its
#: signed state (the secure profile): a UAV just started may not serve it yet, a ghost
#: never will.
WORD_ASK_S = 1.0
#: At most this many queued events are handled before the timers run again.
MAX_EVENTS_PER_TICK = 200
#: The state's link drop counting the payload port's messages refused (secure profile).
PAYLOAD_REFUSED = "payload_commands_refused"


@dataclass
class OnboardSettings:
    uav_id: int
    program_url: str
    payload_url: str
    #: The Zenoh session's config; None when the process is given its bus.
    zenoh_config: zenoh.Config | None = None
    baud: int = DEFAULT_BAUD
    payload_ground: bool = False
    status_rate_hz: float = 1.0
    planning_budget_s: float = 2.0
    confirm_limit_s: float = CONFIRM_LIMIT_S
    link_release_s: float = LINK_RELEASE_S
    #: Telemetry published on the bus at most this often; None: every packet relayed.
    telemetry_hz: float | None = None
    #: The fleet's keys ($FLEET_KEY_PREFIX or --key-prefix).
    key_space: KeySpace = DEFAULT_SPACE
    #: Whether messages heard on the payload port (the ground station's relay) are
    #: obeyed. Off in the secure profile: anyone on that pipe would command the UAV
    #: without any identity, so there the ground commands over Zenoh only.
    payload_commands: bool = True
    #: Propose plans (PyVRP) for the missions that name this UAV (onboard.plan_proposer).
    propose: bool = False


@dataclass
class _Outputs:
    """OnboardCore's outputs, wired to the link adapter and the bus edge."""

    process: OnboardProcess

    def send_autopilot(self, command: AutopilotCommand) -> None:
        self.process.link.send_autopilot(command)

    def publish(self, key: str, message: msgspec.Struct) -> None:
        if message is self.process.telemetry_published:
            return  # an arrival's fix the telemetry rate put on the bus already
        if isinstance(message, UavState):
            message = self.process.with_link(message, time.monotonic())
        self.process.node.publish(key, message)

    def send_ground(self, message: StatusText | UavResult) -> None:
        if self.process.settings.payload_ground:
            data = encode_message(message, self.process.settings.uav_id, MISSION_MANAGER)
            self.process.link.send_payload(data, ALL_GROUND_STATIONS)

    def fetch_results(self, mission: int, uavs: tuple[int, ...]) -> None:
        """Ask for the missing results only, each from the teammate that owes it."""
        for uav in uavs:
            self.process.node.fetch(self.process.space.mission_result(mission, uav), UavResult)

    def fetch_assignments(self, mission: int) -> None:
        """What the team decided on `mission` while this UAV was away: the assignments,
        the outcomes (who reached which target: not flown again; who dropped out)
        and an abort (which teammates relay by query)."""
        self.process.node.fetch(self.process.space.mission_assignments(mission), AssignmentReport)
        self.process.node.fetch(self.process.space.mission_outcomes(mission), TargetOutcome)
        self.process.node.fetch(self.process.space.mission_abort(mission), MissionAbort)

    def fetch_missions(self) -> None:
        self.process.node.fetch(self.process.space.all_mission_targets, MissionTargets)

    def fetch_standings(self, mission: int, uavs: tuple[int, ...], basis: str | None) -> None:
        """Ask these teammates (none: every one) for their standings for append plan
        `basis` (None: the one each waits on); each answers its own, as it signed it."""
        space = self.process.space
        keys = [space.mission_result(mission, uav) for uav in uavs] or [
            space.mission_results(mission)
        ]
        for key in keys:
            self.process.node.fetch(standing_selector(key, basis), UavResult)

    def fetch_outcomes(self, mission: int, uavs: tuple[int, ...]) -> None:
        """Ask for these teammates' own outcomes, by name: each teammate that heard one
        relays it with its author's signature (the UAV itself may be gone)."""
        for uav in uavs:
            key = self.process.space.mission_outcome(mission, uav)
            self.process.node.fetch(key, TargetOutcome)


class OnboardProcess:
    """One UAV's module. Its edges come from `settings` (serial ports by URL, a Zenoh
    session) unless given: `links` (program, payload) and `bus`, e.g. in-memory ones.

    Raises zenoh.ZError when it opens a Zenoh session and none can be opened.
    """

    def __init__(
        self,
        settings: OnboardSettings,
        *,
        links: tuple[Link, Link] | None = None,
        bus: Bus | None = None,
    ) -> None:
        self.settings = settings
        self.payload_refused = 0  #: messages from the payload port refused
        self.space = settings.key_space
        #: None only wakes the loop (a query or a planner result waits for it).
        self.events: queue.SimpleQueue[Event | None] = queue.SimpleQueue()
        self.stop_requested = threading.Event()
        if bus is None:
            if settings.zenoh_config is None:
                raise ValueError("an onboard process needs a bus or a Zenoh config")
            bus = ZenohBus.open(settings.zenoh_config)
        # The model is built at the aircraft's cruise speed, on the first GPS telemetry.
        self.planner = PlannerWorker(notify=self._wake, build_at_start=False)
        #: When each teammate not counted yet was last asked for its signed state.
        self._word_asked: dict[int, float] = {}
        #: The latest sample the telemetry rate put on the bus (`_Outputs.publish`).
        self.telemetry_published: Telemetry | None = None
        self.core = OnboardCore(
            uav_id=settings.uav_id,
            outputs=_Outputs(self),
            planner=self.planner,
            planning_budget_s=settings.planning_budget_s,
            status_rate_hz=settings.status_rate_hz,
            confirm_limit_s=settings.confirm_limit_s,
            link_release_s=settings.link_release_s,
            key_space=settings.key_space,
            # A ghost liveliness token (anyone on the way can declare one) never counts.
            vouch_teammates=bus.signed,
            propose=settings.propose,
        )
        program, payload = links or (
            SerialLink("program", settings.program_url, settings.baud),
            SerialLink("payload", settings.payload_url, settings.baud),
        )
        self._latest_telemetry: tuple[Telemetry, float] | None = None
        #: Autopilot echoes (tracks, waypoints) queued and not handled yet: while any
        #: is, telemetry queues behind it instead of waiting in the slot (`_from_link`).
        self._echoes_queued = 0
        self._telemetry_lock = threading.Lock()
        self._telemetry_published_at = -math.inf
        self._telemetry_key = self.space.telemetry(settings.uav_id)
        self.link = LinkAdapter(
            settings.uav_id,
            program,
            payload,
            sink=self._from_link,
        )
        self.node = BusEdge(
            settings.uav_id,
            bus,
            sink=self.events.put,
            wake=self._wake,
            # The core replaces its snapshot whole: a bus thread reads one or the other.
            settled=lambda: self.core.settled,
            key_space=settings.key_space,
        )

    def run(self) -> None:
        self.link.start()
        log.info("onboard module %d up", self.settings.uav_id)
        # Catch up with a mission in progress (late join or restart).
        self.core.start(time.monotonic())
        next_health = 0.0
        try:
            while not self.stop_requested.is_set():
                now = time.monotonic()
                self._take_telemetry()
                self._serve_queries(now)
                self.core.tick(now)
                self._ask_word(now)
                if now >= next_health:
                    next_health = now + LINK_HEALTH_PERIOD
                    self.node.publish(self.space.link(self.settings.uav_id), self._link_health(now))
                self._drain_events(min(now + TICK_PERIOD, next_health))
        finally:
            self.close()

    def close(self) -> None:
        self.link.stop()
        self.planner.close()
        self.node.close()
        log.info("onboard module %d stopped", self.settings.uav_id)

    # ---- events ---------------------------------------------------------------------
    def _wake(self) -> None:
        """Wake the main loop (a query or a planner result waits for it)."""
        self.events.put(None)

    def _drain_events(self, until: float) -> None:
        """Wait for an event until `until` (the next timer), then take what else is queued."""
        timeout = max(0.0, until - time.monotonic())
        for _ in range(MAX_EVENTS_PER_TICK):
            try:
                event = self.events.get(timeout=timeout)
            except queue.Empty:
                return
            timeout = 0.0
            try:
                self._on_event(event, time.monotonic())
            except Exception:  # a bad event is logged; the module keeps serving
                log.exception("error handling event %r", event)

    def _from_link(self, event: LinkEvent) -> None:
        """The link thread's hand-off. Telemetry, the bulk of the traffic, goes on the
        bus from the link thread itself and waits in one slot for the main loop's next
        turn (at most TICK_PERIOD away): it neither wakes the main loop nor queues up.
        Everything else is queued as an event.

        The order of positions and echoes is kept: an echo is queued behind the
        telemetry waiting in the slot, and telemetry that comes while an echo is queued
        queues behind it. Otherwise a main loop running late would judge a track change
        (the autopilot moving on from the target waypoint) against a position sent after
        it, the aircraft already well past the target, and miss the arrival."""
        if isinstance(event, AutopilotEvent) and isinstance(event.message, Telemetry):
            now = time.monotonic()
            self.link.note_telemetry(now)
            self._publish_telemetry(event.message, now)
            with self._telemetry_lock:
                if self._echoes_queued:
                    self.events.put(_QueuedTelemetry(event.message, now))
                else:
                    self._latest_telemetry = (event.message, now)
            return
        if isinstance(event, AutopilotEvent):
            with self._telemetry_lock:
                before, self._latest_telemetry = self._latest_telemetry, None
                if before is not None:
                    self.events.put(_QueuedTelemetry(*before))
                self._echoes_queued += 1
        self.events.put(event)

    def _publish_telemetry(self, telemetry: Telemetry, now: float) -> None:
        hz = self.settings.telemetry_hz
        if hz and now - self._telemetry_published_at < 1.0 / hz:
            return  # the bus gets telemetry at its own rate, not the autopilot's
        self._telemetry_published_at = now
        self.telemetry_published = telemetry
        self.node.publish(self._telemetry_key, telemetry)

    def _take_telemetry(self) -> None:
        """Hand the module the latest telemetry, if any arrived since the last turn."""
        with self._telemetry_lock:
            latest, self._latest_telemetry = self._latest_telemetry, None
        if latest is not None:
            self._apply_telemetry(*latest)

    def _apply_telemetry(self, telemetry: Telemetry, at: float) -> None:
        self.core.on_telemetry(telemetry, at)
        speed = self.core.link.airspeed()  # the one the plans use, this telemetry taken in
        if speed is not None:
            self.planner.prepare(speed)

    def _on_event(self, event: Event | None, now: float) -> None:
        if isinstance(event, _QueuedTelemetry):
            self._apply_telemetry(event.telemetry, event.at)
            return
        # The aircraft's latest position first: a track change is judged against it. (Of
        # the positions the autopilot sent before the change: while an echo is queued,
        # the slot stays empty; `_from_link`.)
        self._take_telemetry()
        if isinstance(event, AutopilotEvent):
            try:
                self._on_link(event, now)
            finally:
                with self._telemetry_lock:
                    self._echoes_queued -= 1
        elif isinstance(event, PresenceEvent):
            self.core.on_alive(event.uav, event.alive, now)
            if event.alive:
                self._ask_word(now)
        elif isinstance(event, BusEvent):
            if not event.replayed and self.node.bus.signed:
                # A teammate's own signed word, heard live (fresh: the bus checked its
                # signature and time): its token counts, before its message is handled.
                author = _author_uav(event.message)
                if author is not None:
                    self.core.on_spoke(author, now)
            self._on_message(event.message, now, via_payload=False, replayed=event.replayed)
        elif event is not None:
            self._on_link(event, now)

    def _ask_word(self, now: float) -> None:
        """Ask each teammate whose token does not count yet for its signed state, at most
        every WORD_ASK_S (the secure profile; nobody waits in the open one)."""
        waiting = self.core.awaits_word()
        for uav in list(self._word_asked):
            if uav not in waiting:
                del self._word_asked[uav]
        for uav in waiting:
            if now - self._word_asked.get(uav, -math.inf) >= WORD_ASK_S:
                self._word_asked[uav] = now
                self.node.ask_state(uav)

    def _on_link(self, event: LinkEvent, now: float) -> None:
        if isinstance(event, AutopilotEvent):
            message = event.message
            if isinstance(message, Track):
                self.core.on_track(message, now)
            elif isinstance(message, Waypoint):
                self.core.on_waypoint(message, now)
            return
        if isinstance(event, PlanningEvent):
            envelope = event.envelope
            if envelope.destination not in (self.settings.uav_id, BROADCAST):
                return
            if not self.settings.payload_commands:
                self.payload_refused += 1
                _refusals.warn(
                    f"refused {type(envelope.message).__name__} from the payload port: in "
                    "the secure profile commands come over Zenoh only"
                )
                return
            self._on_message(envelope.message, now, via_payload=True)

    def _on_message(
        self, message: object, now: float, via_payload: bool, replayed: bool = False
    ) -> None:
        """One path for a command, whether it came over Zenoh or the payload port;
        `replayed`: in reply to this UAV's catch-up query, not live."""
        core = self.core
        uav = self.settings.uav_id
        if isinstance(message, OpmCommand):
            if via_payload:
                self.node.publish(self.space.opm(uav), message)
            core.on_opm(message, now)
        elif isinstance(message, MissionTargets):
            if via_payload and uav in message.team:
                self.node.publish(self.space.mission_targets(message.mission), message)
            core.on_targets(message, now, replayed=replayed)
        elif isinstance(message, UavResult):
            if via_payload:
                self.node.publish(self.space.mission_result(message.mission, message.uav), message)
            core.on_result(message, now)
        elif isinstance(message, AssignmentReport):
            core.on_assignment(message, now)
        elif isinstance(message, TargetOutcome):
            core.on_outcome(message, now)
        elif isinstance(message, PlanProposal):
            core.on_proposal(message, now)
        elif isinstance(message, UavState) and not via_payload:
            # A teammate's state, signed by its own key, answered this UAV's question
            # (`_ask_word`): its liveliness token is no ghost's.
            core.on_spoke(message.uav, now)
        elif isinstance(message, MissionAbort):
            if via_payload:
                self.node.publish(self.space.mission_abort(message.mission), message)
            core.on_abort(message, now)
        else:
            log.info("ignored %r", message)

    # ---- queries --------------------------------------------------------------------
    def _serve_queries(self, now: float) -> None:
        while (query := self.node.state_queries.try_recv()) is not None:
            query.reply(
                self.space.state(self.settings.uav_id),
                self.with_link(self.core.state(now), now),
            )
            query.drop()
        relays = self.node.state_relays
        while relays is not None and (query := relays.try_recv()) is not None:
            relayed = self.node.relayed_state(query)
            if relayed is not None:
                query.reply_bytes(*relayed)
            query.drop()
        while (query := self.node.command_queries.try_recv()) is not None:
            self._on_command_query(query, now)
        for queryable in self.node.mission_queries:
            while (query := queryable.try_recv()) is not None:
                self._on_mission_query(query)
                query.drop()

    def with_link(self, state: UavState, now: float) -> UavState:
        """The module's state with what only the process knows: the link's health and
        the model's speed."""
        return msgspec.structs.replace(
            state,
            link=self._link_health(now),
            model_speed=self.planner.model_speed(),
        )

    def _link_health(self, now: float) -> LinkHealth:
        """The serial link's health, with the bus messages refused counted as drops too."""
        health = self.link.health(now)
        refused = {f"bus_{reason}": n for reason, n in bus_codec.DROPPED.counts().items()}
        if self.payload_refused:
            refused[PAYLOAD_REFUSED] = self.payload_refused
        return msgspec.structs.replace(health, drops={**health.drops, **refused})

    def _on_command_query(self, query: BusQuery, now: float) -> None:
        key = query.key
        name = key.rsplit("/", 1)[-1]
        kinds: dict[str, type[Waypoint] | type[Track]] = {"waypoint": Waypoint, "track": Track}
        kind = kinds.get(name)
        if kind is None:
            query.reply_err(f"unknown command {name!r}: expected waypoint or track")
            query.drop()
            return
        try:
            command = decode(query.payload, kind, key)
        except BadMessage as error:
            _refusals.warn(f"command refused: {error}")
            query.reply_err(str(error))
            query.drop()
            return
        reply_key = self.space.command(self.settings.uav_id, name)

        def done(result: CommandResult) -> None:
            query.reply(reply_key, result)
            query.drop()

        self.core.command_autopilot(command, now, done)

    def _on_mission_query(self, query: BusQuery) -> None:
        """Serve the current mission's targets, our result, assignment and outcome."""
        targets = self.core.mission_targets()
        if targets is None:
            return
        mission = targets.mission
        asked, basis = standing_asked(query.parameters)
        if asked:  # a standing, not the first result: its own, as it put it
            key = self.space.mission_result(mission, self.settings.uav_id)
            standing = self.core.own_standing(mission, basis)
            if standing is not None and query.intersects(key):
                query.reply(key, standing)
            self._relay_standing(query, mission, basis)
            return
        answers: list[tuple[str, msgspec.Struct | None]] = [
            (self.space.mission_targets(mission), targets),
            (
                self.space.mission_result(mission, self.settings.uav_id),
                self.core.own_result(mission),
            ),
            (
                self.space.mission_assignment(mission, self.settings.uav_id),
                self.core.own_assignment(mission),
            ),
            (
                self.space.mission_outcome(mission, self.settings.uav_id),
                self.core.own_outcome(mission),
            ),
            (self.space.mission_abort(mission), self.core.abort_of(mission)),
        ]
        for key, message in answers:
            # Reply with the concrete key, or consolidation would merge the replies.
            if message is not None and query.intersects(key):
                query.reply(key, message)
        # A teammate's outcome only to a query naming it: relayed as its UAV signed it
        # (the bus passes its envelope on), for a UAV or a ground that heard it named
        # in a hint; a query for every outcome gets each UAV's own from that UAV.
        for uav, relayed in self.core.teammate_outcomes(mission).items():
            key = self.space.mission_outcome(mission, uav)
            if query.key == key:
                query.reply(key, relayed)

    def _relay_standing(self, query: BusQuery, mission: int, basis: str | None) -> None:
        """A teammate's standing for append plan `basis`, only to a query naming that
        UAV and that plan: relayed as its UAV signed it (the bus passes its envelope on),
        for a UAV that heard a teammate's report say it asked for a re-plan in changed
        air, which is believed from the asker's own standing alone (the asker may be
        gone). A query for every standing gets each from its own UAV."""
        if basis is None:
            return
        try:
            uav = parse_key(query.key, self.space).uav
        except WrongKey:
            return
        if uav is None or query.key != self.space.mission_result(mission, uav):
            return
        relayed = self.core.teammate_standing(mission, uav, basis)
        if relayed is not None:
            query.reply(query.key, relayed)


def _author_uav(message: object) -> int | None:
    """The UAV that signed `message`, for the messages a UAV signs about itself."""
    if isinstance(message, UavResult | AssignmentReport | TargetOutcome):
        return message.uav
    return None
