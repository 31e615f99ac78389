"""Mission ids: choosing one, claiming it against another ground, serving the targets.

The ground picks a mission id one above every id the key space still answers for (the
UAVs serve their current mission and report it in their state, so this survives a
ground restart); `claim_mission` then serves the MissionTargets under that id and asks
who else does, so two ground tools never send two missions under one id (docs/ground.md
lists the residual cases). `TargetsServer` answers queries for a mission's targets while
it is open, so a UAV that joins or reconnects late can fetch the mission.
"""

from __future__ import annotations

import logging
import random
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    TargetOutcome,
    UavResult,
)
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusQuery, BusReply, Queryable
from fleet.transport.refusal_log import RefusalLog
from ground.declarations import Declarations, Enter
from ground.fleet_view import query_states
from ground.mission_control import MissionError

log = logging.getLogger(__name__)
#: Refused input, logged at most every few seconds (a flood cannot fill the log).
_refusals = RefusalLog(log)


#: Mission ids are u32 on the planning protocol.
MAX_MISSION_ID = 0xFFFF_FFFF


#: What each mission key carries, by its kind (`fleet/mission/{m}/KIND[/{id}]`).
MissionMessage = MissionTargets | UavResult | AssignmentReport | MissionAbort | TargetOutcome
_MISSION_KINDS: dict[str, type[MissionMessage]] = {
    "targets": MissionTargets,
    "result": UavResult,
    "assignment": AssignmentReport,
    "abort": MissionAbort,
    "outcome": TargetOutcome,
}


def _mission_message(reply: BusReply) -> MissionMessage | None:
    """The message a mission reply carries, if it is one its key vouches for (else logged)."""
    if not reply.ok:
        log.debug("error reply %r", reply.payload)
        return None
    parts = reply.key.split("/")
    kind = _MISSION_KINDS.get(parts[3]) if len(parts) >= 4 else None
    if kind is None:
        log.debug("not a mission message: %s", reply.key)
        return None
    try:
        return bus_codec.decode(reply.payload, kind, reply.key)
    except bus_codec.BadMessage as error:
        _refusals.warn(f"ignored reply {error}")
        return None


def _ground_command(message: MissionMessage) -> bool:
    return isinstance(message, MissionTargets | MissionAbort)


def _mission_queries(bus: Bus, space: KeySpace) -> tuple[str, ...]:
    """The keys to ask for the mission ids in use.

    In the secure profile only the ground's targets and aborts count, so only they are
    asked for, each on its own key: every identity may fetch those (a UAV's, say that
    of a gateway started with the wrong config), whereas the router drops a UAV
    identity's query on the whole mission tree without an error, and the ids in use
    would come back empty (mission 1 again, already taken).
    """
    if bus.signed:
        return (space.all_mission_targets, space.all_mission_aborts)
    return (space.all_mission_keys,)


def missions_seen(bus: Bus, space: KeySpace, timeout_s: float) -> set[int]:
    """Every mission id anything in the key space still answers for.

    The UAVs serve their current mission's targets, results and assignments by query,
    and report it in their state, so this sees the latest mission even after the ground
    that sent it has gone.
    """
    seen: set[int] = set()
    for key in _mission_queries(bus, space):
        for reply in bus.query(key, timeout_s):
            message = _mission_message(reply)
            if message is not None and (_ground_command(message) or not bus.signed):
                seen.add(message.mission)
    if bus.signed:
        # A UAV's own result, and its state, are signed by that UAV only: a captured
        # aircraft could name mission 2^32-1 there. The ground's signed targets and
        # aborts (which the UAVs relay with the ground's signature) say which ids are taken.
        return seen
    for state in query_states(bus, space, timeout_s).values():
        if state.mission is not None:
            seen.add(state.mission.mission)
    return seen


def next_mission_id(bus: Bus, space: KeySpace, timeout_s: float) -> int:
    """One more than the highest mission id seen, or 1 on a fresh fleet.

    A UAV ignores a mission id not above its current one (a higher id supersedes a
    lower one), and every UAV reports its current mission, so max + 1 is always new to
    every live UAV, stays small and readable, and survives a ground restart.
    """
    seen = missions_seen(bus, space, timeout_s)
    mission = max(seen, default=0) + 1
    if mission > MAX_MISSION_ID:
        raise MissionError(f"mission id {mission} does not fit in 32 bits")
    return mission


#: How many mission ids `claim_mission` tries before it gives up.
CLAIM_ATTEMPTS = 5
#: The random pause (s) before choosing again after a collision, so that two grounds
#: that collided do not choose again in lockstep.
CLAIM_BACKOFF_S = (0.02, 0.2)
#: After a collision the next id is the highest seen + 1 + a random step below this.
CLAIM_STEP = 4


def rival_claims(bus: Bus, space: KeySpace, targets: MissionTargets, timeout_s: float) -> int:
    """How many others serve a different MissionTargets under `targets`' mission id.

    Every reply is kept (no consolidation: two grounds serving the same key must both
    be heard). A reply with the same content is no rival: our own queryable, or a UAV
    that already holds this very mission.
    """
    rivals = 0
    key = space.mission_targets(targets.mission)
    # The query carries our candidate: a ground already serving this id learns that it
    # was contested (TargetsServer.contested).
    candidate = bus_codec.encode(targets)
    for reply in bus.query(key, timeout_s, candidate, every_reply=True):
        message = _mission_message(reply)
        if isinstance(message, MissionTargets) and message != targets:
            rivals += 1
    return rivals


@contextmanager
def claim_mission(
    bus: Bus,
    space: KeySpace,
    make: Callable[[int], MissionTargets],
    timeout_s: float,
    *,
    mission: int | None = None,
    attempts: int = CLAIM_ATTEMPTS,
    rng: random.Random | None = None,
) -> Iterator[TargetsServer]:
    """Choose a mission id no other ground is using and serve its targets while open.

    The rule (docs/ground.md): choose m (`mission`, else `next_mission_id`); serve
    `make(m)` on `fleet/mission/{m}/targets` *first*, then query that key. A reply with
    different content means another ground (or a UAV holding another ground's mission)
    claimed m: withdraw, wait a random moment and choose again, above everything seen
    and by a random step, at most `attempts` times. Two grounds that choose together
    each declare before they query, so at least one of them hears the other. A given
    `mission` is never changed: its collision is a MissionError, as is running out of
    attempts.

    Yields the entered TargetsServer of the claimed mission (`.targets`); its
    `contested` is set when this claim met a rival, or a rival's claim met it later:
    a mission of the rival may then supersede this one at any moment (`contest_grace_s`).
    """
    rng = rng if rng is not None else random.Random()
    chosen = mission if mission is not None else next_mission_id(bus, space, timeout_s)
    for attempt in range(1, attempts + 1):
        targets = make(chosen)
        with TargetsServer(bus, space, targets) as server:
            rivals = rival_claims(bus, space, targets, timeout_s)
            if not rivals:
                if attempt > 1:
                    log.warning("mission %d: claimed at attempt %d", chosen, attempt)
                    server.contested.set()
                yield server
                return
        if mission is not None:
            raise MissionError(
                f"mission {mission} is already in use with other targets (another ground "
                "sent it); choose another --mission or leave it out"
            )
        pause = rng.uniform(*CLAIM_BACKOFF_S)
        log.warning(
            "mission %d: another ground chose it too (%d rival claim(s)); choosing again "
            "in %.0f ms (attempt %d of %d)",
            chosen,
            rivals,
            pause * 1000,
            attempt,
            attempts,
        )
        time.sleep(pause)  # a random back-off, so the two grounds do not collide again
        chosen = max(next_mission_id(bus, space, timeout_s), chosen + 1) + rng.randrange(CLAIM_STEP)
        if chosen > MAX_MISSION_ID:
            raise MissionError(f"mission id {chosen} does not fit in 32 bits")
    raise MissionError(
        f"no free mission id after {attempts} attempts (other grounds kept choosing the same)"
    )


def contest_grace_s(timeout_s: float) -> float:
    """How long a rival that collided with us may take to send its own mission: its
    back-off, its look for missions seen (two queries) and its claim (one query)."""
    return CLAIM_BACKOFF_S[1] + 3 * timeout_s


def current_mission_id(bus: Bus, space: KeySpace, timeout_s: float) -> int | None:
    seen = missions_seen(bus, space, timeout_s)
    return max(seen) if seen else None


class TargetsServer(Declarations):
    """Answers queries on `fleet/mission/{m}/targets` with the mission, while open.

    A UAV that starts, or reconnects, after the put can still fetch the mission.
    """

    def __init__(self, bus: Bus, space: KeySpace, targets: MissionTargets) -> None:
        self._bus = bus
        self.targets = targets
        self._key = space.mission_targets(targets.mission)
        self._payload = bus_codec.encode(targets)
        #: Another ground asked for this id with other targets (see `claim_mission`).
        self.contested = threading.Event()
        self._revising = threading.Lock()
        self._queryable: Queryable | None = None
        super().__init__()

    def _declare(self, enter: Enter) -> None:
        # Answered as each query arrives, on the bus's thread: nothing else polls this.
        self._queryable = self._bus.declare_queryable(self._key, self._answer_waiting)
        enter(self._queryable)
        self._answer_waiting()  # any query that arrived before the assignment above

    def _answer_waiting(self) -> None:
        queryable = self._queryable
        if queryable is None:
            return
        while (query := queryable.try_recv()) is not None:
            try:
                self._answer(query)
            finally:
                query.drop()

    def revise(self, targets: MissionTargets) -> None:
        """Serve `targets`, a later revision of the same mission (changed in flight), from
        now on: a UAV that joins late gets the mission as it is now."""
        with self._revising:  # heard on the bus's thread and fetched on the caller's
            held = self.targets
            if targets.mission != held.mission or targets.revision <= held.revision:
                return
            self._payload = bus_codec.encode(targets)
            self.targets = targets

    def _answer(self, query: BusQuery) -> None:
        # The concrete key, not the query's (possibly wildcard) one: otherwise Zenoh's
        # consolidation would merge this reply with another mission's.
        query.reply_bytes(self._key, self._payload)
        candidate = query.payload
        if candidate and candidate != self._payload and not self.contested.is_set():
            self.contested.set()
            log.warning(
                "mission %d: another ground asked to use this id with other targets",
                self.targets.mission,
            )
