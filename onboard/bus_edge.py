"""The onboard module's bus edge: presence, subscriptions, queryables, publications.

The bus is Zenoh in flight (`fleet.transport.zenoh_bus`) and in-memory in unit tests
(`fleet.transport.memory`). Every callback only decodes and hands an event to `sink`
(or drops an assignment report that changes nothing, on its header: `_changes_nothing`);
the main loop does the rest, so no bus thread ever waits on the module. Queryables are
polled by the main loop, so a command's reply can wait for the autopilot's echo.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import msgspec

from fleet.consensus.mission_round import Settled
from fleet.mission.key_check import WrongKey, parse_key
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.mission.messages import (
    AssignmentHeader,
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    PlanProposal,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.transport.bus import Bus, BusQuery, BusSample, Declaration, Queryable
from fleet.transport.bus_codec import BadMessage, DropReason, decode, decode_header, refuse
from fleet.transport.refusal_log import RefusalLog

log = logging.getLogger(__name__)
#: Refused input, logged at most every few seconds (a flood cannot fill the log).
_refusals = RefusalLog(log)


@dataclass(frozen=True)
class BusEvent:
    """A decoded message that arrived on the bus, with the key it arrived on."""

    key: str
    message: msgspec.Struct  #: one of the messages in fleet.mission.messages
    #: A reply to this UAV's query (a catch-up), not a live publication: it may be old.
    replayed: bool = False


@dataclass(frozen=True)
class PresenceEvent:
    """A teammate's liveliness token appeared (alive) or went away."""

    uav: int
    alive: bool


Sink = Callable[[BusEvent | PresenceEvent], None]
#: The selector parameter by which a query asks teammates to relay a UAV's state.
RELAYED = "relayed"
#: The selector parameter by which a query on a result key asks for the UAV's standing
#: (fleet.consensus.resolve), not its first result: `standing=DIGEST` for the one of
#: that append plan, a bare `standing` for the one of the plan the UAV waits on.
STANDING = "standing"


def standing_asked(parameters: str) -> tuple[bool, str | None]:
    """Whether a query's `parameters` ask for a standing, and for which append plan."""
    for part in parameters.replace("&", ";").split(";"):
        name, equals, value = part.partition("=")
        if name == STANDING:
            return True, (value or None) if equals else None
    return False, None


def standing_selector(key: str, basis: str | None) -> str:
    """A query on result `key` (one UAV's, or a wildcard) for the standing of `basis`."""
    return f"{key}?{STANDING}" if basis is None else f"{key}?{STANDING}={basis}"


M = TypeVar("M", bound=msgspec.Struct)


def _decoded(sample: BusSample, kind: type[M]) -> M | None:
    """`sample`'s message of `kind`; None, the refusal logged, if it is not one."""
    try:
        return decode(sample.payload, kind, sample.key)
    except BadMessage as error:
        _refusals.warn(f"dropped: {error}")
        return None


def _mission_subscriptions(space: KeySpace) -> tuple[tuple[str, type[msgspec.Struct]], ...]:
    return (
        (space.all_mission_targets, MissionTargets),
        (space.all_mission_results, UavResult),
        # Re-plans only: a teammate's epoch-0 commitment changes nothing for a UAV that
        # committed too, and one that has not learns it by query (`fetch`).
        (space.all_mission_replans, AssignmentReport),
        (space.all_mission_aborts, MissionAbort),
        (space.all_mission_proposals, PlanProposal),
        (space.all_uav_proposals, PlanProposal),
        (space.all_mission_outcomes, TargetOutcome),
    )


class BusEdge:
    """The onboard's declarations on its bus, which it owns (closed by `close`)."""

    def __init__(
        self,
        uav_id: int,
        bus: Bus,
        sink: Sink,
        wake: Callable[[], None] | None = None,
        settled: Callable[[], Settled | None] | None = None,
        key_space: KeySpace = DEFAULT_SPACE,
    ) -> None:
        """`sink` gets every event; `wake` is called when a query waits to be served;
        `settled` gives the module's latest `Settled` snapshot, if any: an assignment
        report it covers changes nothing, and is dropped on its header alone."""
        self.uav_id = uav_id
        self.key_space = key_space
        self.sink = sink
        self.wake = wake
        self.settled = settled
        self.bus = bus
        self._declared: list[Declaration] = []
        try:
            self._declare()
        except Exception:
            bus.close()
            raise

    def _declare(self) -> None:
        bus, space = self.bus, self.key_space
        self.token = bus.declare_token(space.alive(self.uav_id))
        self._declared.append(bus.subscribe_presence(space.all_alive, self._on_presence))
        subscriptions: tuple[tuple[str, type[msgspec.Struct]], ...] = (
            (space.opm(self.uav_id), OpmCommand),
            *_mission_subscriptions(space),
        )
        for key, kind in subscriptions:
            self._declared.append(bus.subscribe(key, self._decoder(kind)))
        self.state_queries = bus.declare_queryable(space.state(self.uav_id), self.wake)
        # In the secure profile each teammate's latest state, as it signed it, is kept to
        # relay to a query that asks for relays (`relayed_state`): the ground learns so
        # that a UAV frozen or cut off a moment ago is a real one, not a ghost token.
        self.state_relays: Queryable | None = None
        kept = bus.keep_latest(space.all_state)
        if kept is not None:
            self._declared.append(kept)
            self.state_relays = bus.declare_queryable(space.all_state, self.wake)
        self.command_queries = bus.declare_queryable(space.command(self.uav_id, "*"), self.wake)
        # Each UAV answers for the targets and the abort of its current mission, for its
        # own assignment only, so a teammate's query for a missing one reaches the UAV
        # that owes it, and for every result and outcome: its own, and a teammate's
        # standing or outcome relayed to a query naming it (a claim about another UAV is
        # fetched from it, by name: its own word, which outlives it).
        self.mission_queries = [
            bus.declare_queryable(key, self.wake)
            for key in (
                space.all_mission_targets,
                space.all_mission_aborts,
                space.all_mission_results,
                space.assignments_of(self.uav_id),
                space.all_mission_outcomes,
            )
        ]

    def _on_presence(self, key: str, alive: bool) -> None:
        try:
            uav = parse_key(key, self.key_space).uav
        except WrongKey as error:
            log.warning("dropped liveliness token: %s", refuse(str(error), DropReason.WRONG_KEY))
            return
        if uav is None:
            return
        self.sink(PresenceEvent(uav, alive))

    def _decoder(
        self, kind: type[msgspec.Struct], *, replayed: bool = False
    ) -> Callable[[BusSample], None]:
        full = self._full_decoder(kind, replayed=replayed)
        if kind is not AssignmentReport or self.settled is None:
            return full

        def on_assignment(sample: BusSample) -> None:
            if not self._changes_nothing(sample):
                full(sample)

        return on_assignment

    def _changes_nothing(self, sample: BusSample) -> bool:
        """An assignment report the module's `Settled` snapshot covers, judged on its
        header (at each re-plan epoch, the N-2 teammates' re-plans of the epoch this UAV
        re-planned too; and catch-up replies). A header that does not decode or that its
        key does not vouch for goes the full way, where it is refused and counted."""
        settled = self.settled() if self.settled is not None else None
        if settled is None:
            return False
        header = decode_header(sample.payload, AssignmentHeader, sample.key)
        return header is not None and settled.covers(header)

    def _full_decoder(
        self, kind: type[msgspec.Struct], *, replayed: bool = False
    ) -> Callable[[BusSample], None]:
        def on_sample(sample: BusSample) -> None:
            message = _decoded(sample, kind)
            if message is not None:
                self.sink(BusEvent(sample.key, message, replayed))

        return on_sample

    def ask_state(self, uav: int, timeout: float = 1.0) -> None:
        """Ask teammate `uav` for its state; its own signed answer (the bus checks the
        signature, and that it is fresh) comes back through the sink, `replayed`: in
        the secure profile, the word that makes its liveliness token count."""
        key = self.key_space.state(uav)

        def on_reply(sample: BusSample) -> None:
            state = _decoded(sample, UavState)
            if state is not None and sample.key == key and state.uav == uav:
                self.sink(BusEvent(sample.key, state, replayed=True))

        self.bus.get(key, on_reply, timeout)

    def relayed_state(self, query: BusQuery) -> tuple[str, bytes] | None:
        """What to relay to a query on a teammate's state: its latest state as it signed
        it, only to a query naming that one UAV and asking for relays (a query for every
        state gets each from its own UAV, and a plain one from the UAV alone)."""
        if RELAYED not in query.parameters.replace("&", ";").split(";"):
            return None
        try:
            uav = parse_key(query.key, self.key_space).uav
        except WrongKey:
            return None
        if uav is None or uav == self.uav_id or query.key != self.key_space.state(uav):
            return None
        payload = self.bus.latest(query.key)
        return None if payload is None else (query.key, payload)

    def publish(self, key: str, message: msgspec.Struct) -> None:
        self.bus.publish(key, message)

    def fetch(self, selector: str, kind: type[msgspec.Struct], timeout: float = 1.0) -> None:
        """Query `selector`; replies come back through the sink like publications,
        marked `replayed`."""
        self.bus.get(selector, self._decoder(kind, replayed=True), timeout)

    def close(self) -> None:
        for declared in self._declared:
            declared.undeclare()
        relays = (self.state_relays,) if self.state_relays is not None else ()
        for queryable in (self.state_queries, *relays, self.command_queries, *self.mission_queries):
            queryable.undeclare()
        self.token.undeclare()
        self.bus.close()
