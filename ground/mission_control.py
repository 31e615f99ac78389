"""Mission management (thesis 3.1.4): send targets, follow the consensus, abort, OPM.

Sending a mission: the ground picks a mission id (see `next_mission_id`), declares its
subscribers to the mission's results and assignments *before* it sends, so nothing a
fast UAV publishes is missed, serves the MissionTargets by query on
`fleet/mission/{m}/targets` for UAVs that join late, and then puts them on that key.

Following it: every UAV publishes its UavResult and, once the consensus has run, its
AssignmentReport; both are collected by subscription and, at the end, by a query of
`fleet/mission/{m}/result/*` and `.../assignment/*`, which the UAVs also serve, so a
sample lost in transit is still counted.

Agreement: every team UAV runs the same deterministic greedy on the same results, so
every report must carry the same `digest` (of the results used) and the same `pairs`.
When they do not, the largest group of identical reports is taken as the reference
(ties: the group holding the lowest Piccolo ID) and everyone else is named as having
disagreed.

Re-plans: after the commitment, a UAV that drops out (liveliness gone, `failed`,
`link_lost`) is released by its teammates and its target re-planned; each re-plan is
a new *epoch* of the same mission, republished on the same assignment keys, and each
UAV publishes a TargetOutcome (`fleet/mission/{m}/outcome/{id}`) when it reaches its
target or drops out. The ground reads a target as `reached` (by whom) from those.

Taking part: a UAV whose liveliness token went away while the ground waited is *lost*;
one that published a result with no time at all *declined* (module off, link lost, no
GPS). Neither is waited for nor counted as agreeing; `agreed` is about the UAVs that
took part, and every target gets a state: `assigned` (to whom) or `unserved` (why).
"""

from __future__ import annotations

import logging
import random
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, Self

import msgspec
import zenoh

from fleet.errors import FleetError
from fleet.mission import keys
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.transport import bus_codec
from ground.fleet_view import query_states
from ground.session import decode_sample, put_message, query, query_messages

log = logging.getLogger(__name__)

#: Mission ids are u32 on the planning protocol.
MAX_MISSION_ID = 0xFFFF_FFFF


class MissionError(FleetError, RuntimeError):
    """A mission operation that cannot go ahead (no team, no mission to abort, ...)."""


# ---- mission ids ---------------------------------------------------------------------
#: What each mission key carries, by its kind (`fleet/mission/{m}/KIND[/{id}]`).
MissionMessage = MissionTargets | UavResult | AssignmentReport | MissionAbort | TargetOutcome
_MISSION_KINDS: dict[str, type[MissionMessage]] = {
    "targets": MissionTargets,
    "result": UavResult,
    "assignment": AssignmentReport,
    "abort": MissionAbort,
    "outcome": TargetOutcome,
}


def _mission_message(key: str, payload: bytes) -> MissionMessage | None:
    """The message a mission reply carries, if it is one its key vouches for (else logged)."""
    parts = key.split("/")
    kind = _MISSION_KINDS.get(parts[3]) if len(parts) >= 4 else None
    if kind is None:
        log.debug("not a mission message: %s", key)
        return None
    try:
        return bus_codec.decode(payload, kind, key)
    except bus_codec.BadMessage as error:
        log.warning("ignored reply %s", error)
        return None


def missions_seen(session: zenoh.Session, timeout_s: float) -> set[int]:
    """Every mission id anything in the key space still answers for.

    The UAVs serve their current mission's targets, results and assignments by query,
    and report it in their state, so this sees the latest mission even after the ground
    that sent it has gone.
    """
    seen: set[int] = set()
    for reply in query(session, keys.ALL_MISSION_KEYS, timeout_s):
        message = _mission_message(reply.key, reply.payload)
        if message is not None:
            seen.add(message.mission)
    for state in query_states(session, timeout_s).values():
        if state.mission is not None:
            seen.add(state.mission.mission)
    return seen


def next_mission_id(session: zenoh.Session, timeout_s: float) -> int:
    """One more than the highest mission id seen, or 1 on a fresh fleet.

    A UAV ignores a mission id not above its current one (a higher id supersedes a
    lower one), and every UAV reports its current mission, so max + 1 is always new to
    every live UAV, stays small and readable, and survives a ground restart.
    """
    seen = missions_seen(session, timeout_s)
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


def rival_claims(session: zenoh.Session, targets: MissionTargets, timeout_s: float) -> int:
    """How many others serve a different MissionTargets under `targets`' mission id.

    Every reply is kept (no consolidation: two grounds serving the same key must both
    be heard). A reply with the same content is no rival: our own queryable, or a UAV
    that already holds this very mission.
    """
    rivals = 0
    key = keys.mission_targets(targets.mission)
    # The query carries our candidate: a ground already serving this id learns that it
    # was contested (TargetsServer.contested).
    candidate = bus_codec.encode(targets)
    for reply in query(session, key, timeout_s, every_reply=True, payload=candidate):
        message = _mission_message(reply.key, reply.payload)
        if isinstance(message, MissionTargets) and message != targets:
            rivals += 1
    return rivals


@contextmanager
def claim_mission(
    session: zenoh.Session,
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
    chosen = mission if mission is not None else next_mission_id(session, timeout_s)
    for attempt in range(1, attempts + 1):
        targets = make(chosen)
        with TargetsServer(session, targets) as server:
            rivals = rival_claims(session, targets, timeout_s)
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
        chosen = max(next_mission_id(session, timeout_s), chosen + 1) + rng.randrange(CLAIM_STEP)
        if chosen > MAX_MISSION_ID:
            raise MissionError(f"mission id {chosen} does not fit in 32 bits")
    raise MissionError(
        f"no free mission id after {attempts} attempts (other grounds kept choosing the same)"
    )


def contest_grace_s(timeout_s: float) -> float:
    """How long a rival that collided with us may take to send its own mission: its
    back-off, its look for missions seen (two queries) and its claim (one query)."""
    return CLAIM_BACKOFF_S[1] + 3 * timeout_s


def current_mission_id(session: zenoh.Session, timeout_s: float) -> int | None:
    seen = missions_seen(session, timeout_s)
    return max(seen) if seen else None


# ---- the outcome -----------------------------------------------------------------------
def _report_identity(report: AssignmentReport) -> tuple[str, tuple[tuple[str, int], ...]]:
    return report.digest, tuple(sorted(report.pairs.items()))


@dataclass(frozen=True)
class Agreement:
    agreed: bool
    reference: AssignmentReport | None
    disagreed: tuple[int, ...]  #: committed, but not the reference assignment
    missing: tuple[int, ...]  #: team UAVs with no AssignmentReport


def check_agreement(team: Iterable[int], assignments: dict[int, AssignmentReport]) -> Agreement:
    """Whether every team UAV committed the same assignment (same digest and pairs)."""
    team = sorted(set(team))
    committed = [uav for uav in team if uav in assignments]
    missing = tuple(uav for uav in team if uav not in assignments)
    groups: dict[tuple[str, tuple[tuple[str, int], ...]], list[int]] = {}
    for uav in committed:
        groups.setdefault(_report_identity(assignments[uav]), []).append(uav)
    if not groups:
        return Agreement(False, None, (), missing)
    # Largest group first; among equals the one with the lowest Piccolo ID.
    reference_group = min(groups.values(), key=lambda members: (-len(members), members[0]))
    reference = assignments[reference_group[0]]
    disagreed = tuple(uav for uav in committed if uav not in reference_group)
    return Agreement(not disagreed and not missing, reference, disagreed, missing)


@dataclass
class MissionOutcome:
    mission: int
    team: tuple[int, ...]
    targets: tuple[Target, ...]
    results: dict[int, UavResult] = field(default_factory=dict)
    assignments: dict[int, AssignmentReport] = field(default_factory=dict)
    #: How each UAV's part ended (reached) or why it dropped out (failed, link_lost).
    outcomes: dict[int, TargetOutcome] = field(default_factory=dict)
    timed_out: bool = False
    lost: set[int] = field(default_factory=set)  #: liveliness gone while the ground waited
    phases: dict[int, str] = field(default_factory=dict)  #: each UAV's phase at the end
    reasons: dict[int, str] = field(default_factory=dict)
    #: A higher mission that reached the team while the ground followed this one
    superseded_by: int | None = None

    @property
    def declined(self) -> list[int]:
        """Team UAVs whose result holds no time at all: they take no part."""
        return [
            uav
            for uav in self.team
            if (result := self.results.get(uav)) is not None
            and all(time is None for time in result.times)
        ]

    @property
    def taking_part(self) -> list[int]:
        declined = set(self.declined)
        return [uav for uav in self.team if uav not in self.lost and uav not in declined]

    @property
    def epoch(self) -> int:
        """The latest re-plan epoch any UAV committed (0: the consensus itself)."""
        return max((report.epoch for report in self.assignments.values()), default=0)

    def reached_by(self) -> dict[int, int]:
        """Target index -> the UAV whose telemetry put it inside the acceptance radius."""
        return {
            outcome.target: uav
            for uav, outcome in sorted(self.outcomes.items())
            if outcome.phase == Phase.REACHED and outcome.target is not None
        }

    @property
    def agreement(self) -> Agreement:
        return check_agreement(self.taking_part, self.assignments)

    @property
    def committed(self) -> bool:
        return bool(self.taking_part) and all(uav in self.assignments for uav in self.taking_part)

    def holders(self) -> dict[int, int]:
        """Target index -> the UAV holding it at the latest epoch: a UAV still showing an
        earlier epoch (dead, or not yet re-planned) holds nothing here."""
        latest = self.epoch
        return {
            report.target: uav
            for uav, report in sorted(self.assignments.items())
            if uav in self.team and report.epoch == latest and report.target is not None
        }

    def target_states(self) -> list[dict[str, Any]]:
        """Each target's state: reached (by whom), assigned (to whom) or unserved (why;
        every target not reached is unserved once a later mission superseded this one)."""
        taking_part = set(self.taking_part)
        holders = {t: uav for t, uav in self.holders().items() if uav in taking_part}
        idle = [uav for uav in self.taking_part if self.target_of(uav) is None]
        reached = self.reached_by()
        states: list[dict[str, Any]] = []
        for index in range(len(self.targets)):
            if index in reached:
                states.append({"index": index, "state": "reached", "uav": reached[index]})
                continue
            if self.superseded_by is not None:
                why = f"mission {self.superseded_by} superseded this one"
                states.append({"index": index, "state": "unserved", "uav": None, "reason": why})
                continue
            holder = holders.get(index)
            if holder is not None:
                states.append({"index": index, "state": "assigned", "uav": holder})
                continue
            if not self.committed:
                why = "the team did not commit"
            elif idle:
                why = f"not assigned although UAV {idle[0]} had no target"
            else:
                why = "more targets than UAVs taking part"
            states.append({"index": index, "state": "unserved", "uav": None, "reason": why})
        return states

    @property
    def succeeded(self) -> bool:
        """The truth behind the exit code: the team agreed and no target was left unserved
        while a UAV taking part had none, and no later mission superseded it."""
        if self.superseded_by is not None:
            return False
        if not self.committed or not self.agreement.agreed:
            return False
        return not any(
            s["state"] == "unserved" and "had no target" in s["reason"]
            for s in self.target_states()
        )

    def target_of(self, uav: int) -> int | None:
        report = self.assignments.get(uav)
        return report.target if report is not None else None

    def unassigned(self) -> list[int]:
        taken = {self.target_of(uav) for uav in self.team}
        return [i for i in range(len(self.targets)) if i not in taken]

    def to_json(self) -> dict[str, Any]:
        """The `send-targets --json` object (docs/ground.md)."""
        agreement = self.agreement
        n = len(self.targets)
        results: dict[str, list[float | None]] = {}
        for uav in self.team:
            result = self.results.get(uav)
            times = list(result.times) if result is not None and len(result.times) == n else None
            results[str(uav)] = times if times is not None else [None] * n
        reference = agreement.reference
        return {
            "mission": self.mission,
            "team": list(self.team),
            "targets": [msgspec.to_builtins(t) for t in self.targets],
            "results": results,
            "assignment": {str(uav): self.target_of(uav) for uav in self.team},
            "eta": {
                str(uav): (report.eta_s if (report := self.assignments.get(uav)) else None)
                for uav in self.team
            },
            "unassigned": self.unassigned(),
            "agreed": agreement.agreed,
            "disagreed": list(agreement.disagreed),
            "missing_results": [uav for uav in self.team if uav not in self.results],
            "missing_assignments": list(agreement.missing),
            "digest": reference.digest if reference is not None else None,
            "complete": self.committed,
            "timed_out": self.timed_out,
            "lost": sorted(self.lost),
            "declined": self.declined,
            "taking_part": self.taking_part,
            "phases": {str(uav): self.phases.get(uav) for uav in self.team},
            "reasons": {str(uav): reason for uav, reason in sorted(self.reasons.items())},
            "target_states": self.target_states(),
            "epoch": self.epoch,
            "outcomes": {
                str(uav): msgspec.to_builtins(outcome)
                for uav, outcome in sorted(self.outcomes.items())
            },
            "superseded_by": self.superseded_by,
            "success": self.succeeded,
        }


# ---- following a mission -------------------------------------------------------------
Listener = Callable[[str, UavResult | AssignmentReport | TargetOutcome], None]


class MissionFollower:
    """Collects one mission's results and assignments; a context manager.

    `listener(kind, message)` ("result", "assignment" or "outcome") is called once per
    new or changed message, on whichever thread delivered it.

    Superseded: a MissionTargets with a higher id for any UAV of `team` (every UAV when
    `team` is empty), seen on `fleet/mission/*/targets` or in what the UAVs serve there,
    or a team UAV's state reporting a higher mission (`note_later_mission`), sets
    `superseded_by` to the highest such id and ends every wait: the team no longer
    flies this mission.
    """

    def __init__(
        self,
        session: zenoh.Session,
        mission: int,
        listener: Listener | None = None,
        team: Iterable[int] = (),
    ) -> None:
        self._session = session
        self.mission = mission
        self._listener = listener
        self._team = frozenset(team)
        self._changed = threading.Condition()
        self.results: dict[int, UavResult] = {}
        self.assignments: dict[int, AssignmentReport] = {}
        self.outcomes: dict[int, TargetOutcome] = {}
        self.lost: set[int] = set()  #: UAVs whose liveliness token went away
        self.superseded_by: int | None = None  #: the highest later mission of the team
        self._stack = ExitStack()

    def __enter__(self) -> Self:
        enter = self._stack.enter_context
        try:
            enter(
                self._session.declare_subscriber(
                    keys.mission_results(self.mission), self._on_result_sample
                )
            )
            enter(
                self._session.declare_subscriber(
                    keys.mission_assignments(self.mission), self._on_assignment_sample
                )
            )
            enter(
                self._session.declare_subscriber(
                    keys.mission_outcomes(self.mission), self._on_outcome_sample
                )
            )
            enter(self._session.liveliness().declare_subscriber(keys.ALL_ALIVE, self._on_alive))
            enter(
                self._session.declare_subscriber(keys.ALL_MISSION_TARGETS, self._on_targets_sample)
            )
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._stack.close()

    def _on_alive(self, sample: zenoh.Sample) -> None:
        try:
            uav = keys.uav_id_of(str(sample.key_expr))
        except (ValueError, IndexError):
            return
        with self._changed:
            if sample.kind == zenoh.SampleKind.DELETE:
                self.lost.add(uav)
            else:
                self.lost.discard(uav)
            self._changed.notify_all()

    def _on_targets_sample(self, sample: zenoh.Sample) -> None:
        targets = decode_sample(sample, MissionTargets)
        if targets is not None:
            self.note_targets(targets)

    def note_targets(self, targets: MissionTargets) -> None:
        """A mission sent to some team: a later one for any of ours supersedes this one."""
        if not self._team or self._team & set(targets.team):
            self.note_later_mission(targets.mission)

    def note_later_mission(self, mission: int) -> None:
        """Our team (or part of it) is on `mission`: if it is later, this one is superseded."""
        if mission <= self.mission:
            return
        with self._changed:
            if self.superseded_by is not None and self.superseded_by >= mission:
                return
            self.superseded_by = mission
            self._changed.notify_all()
        log.warning("mission %d: superseded by mission %d", self.mission, mission)

    def _on_result_sample(self, sample: zenoh.Sample) -> None:
        result = decode_sample(sample, UavResult)
        if result is not None:
            self.add_result(result)

    def _on_assignment_sample(self, sample: zenoh.Sample) -> None:
        report = decode_sample(sample, AssignmentReport)
        if report is not None:
            self.add_assignment(report)

    def _on_outcome_sample(self, sample: zenoh.Sample) -> None:
        outcome = decode_sample(sample, TargetOutcome)
        if outcome is not None:
            self.add_outcome(outcome)

    def add_outcome(self, outcome: TargetOutcome) -> None:
        self._add("outcome", self.outcomes, outcome)

    def add_result(self, result: UavResult) -> None:
        self._add("result", self.results, result)

    def add_assignment(self, report: AssignmentReport) -> None:
        self._add("assignment", self.assignments, report)

    def _add(
        self,
        kind: str,
        store: dict[int, Any],
        message: UavResult | AssignmentReport | TargetOutcome,
    ) -> None:
        """Keep a UAV's message for this mission; wake waiters and the listener on news."""
        if message.mission != self.mission:
            return
        with self._changed:
            held = store.get(message.uav)
            if held == message:
                return
            earlier = (
                isinstance(held, AssignmentReport)
                and isinstance(message, AssignmentReport)
                and message.epoch < held.epoch
            )
            if earlier:
                return  # a late copy of an earlier epoch
            store[message.uav] = message
            self._changed.notify_all()
        if self._listener is not None:
            self._listener(kind, message)

    def fetch(self, timeout_s: float) -> None:
        """Query what the UAVs serve, to catch anything the subscriptions missed."""
        for _, result in query_messages(
            self._session, keys.mission_results(self.mission), UavResult, timeout_s
        ):
            self.add_result(result)
        for _, report in query_messages(
            self._session, keys.mission_assignments(self.mission), AssignmentReport, timeout_s
        ):
            self.add_assignment(report)
        for _, outcome in query_messages(
            self._session, keys.mission_outcomes(self.mission), TargetOutcome, timeout_s
        ):
            self.add_outcome(outcome)
        # The UAVs serve their current mission's targets: a later one supersedes ours.
        for _, targets in query_messages(
            self._session, keys.ALL_MISSION_TARGETS, MissionTargets, timeout_s
        ):
            self.note_targets(targets)

    def wait_committed(self, team: Iterable[int], timeout_s: float, fetch_every_s: float) -> bool:
        """Wait until every UAV of `team` still alive has committed; True if they did in time.

        A UAV whose liveliness token goes away is not waited for (it is in `lost`).
        Queries every `fetch_every_s` as well, so a lost sample costs at most that long.
        A superseded mission is not waited for either: False at once.
        """
        members = set(team)
        return self.wait_until(
            lambda: members - self.lost <= self.assignments.keys(), timeout_s, fetch_every_s
        )

    def snapshot(self) -> tuple[dict[int, UavResult], dict[int, AssignmentReport]]:
        with self._changed:
            return dict(self.results), dict(self.assignments)

    def outcome_snapshot(self) -> dict[int, TargetOutcome]:
        with self._changed:
            return dict(self.outcomes)

    def wait_until(self, done: Callable[[], bool], timeout_s: float, fetch_every_s: float) -> bool:
        """Wait until `done()` (called under the follower's lock) holds; True if in time.

        Queries every `fetch_every_s` as well, so a lost sample costs at most that long.
        A superseded mission is not waited for: False at once.
        """
        deadline = time.monotonic() + timeout_s
        next_fetch = time.monotonic() + fetch_every_s
        while True:
            with self._changed:
                if self.superseded_by is not None:
                    return False
                if done():
                    return True
            now = time.monotonic()
            if now >= deadline:
                return False
            if now >= next_fetch:
                self.fetch(min(1.0, max(0.1, deadline - now)))
                next_fetch = time.monotonic() + fetch_every_s
                continue
            with self._changed:
                self._changed.wait(min(deadline, next_fetch) - now)

    def wait_superseded(self, timeout_s: float) -> int | None:
        """Wait up to `timeout_s` for a later mission of the team; its id, or None."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while self.superseded_by is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._changed.wait(remaining)
            return self.superseded_by


class TargetsServer:
    """Answers queries on `fleet/mission/{m}/targets` with the mission, while open.

    A UAV that starts, or reconnects, after the put can still fetch the mission.
    """

    def __init__(self, session: zenoh.Session, targets: MissionTargets) -> None:
        self._session = session
        self.targets = targets
        self._key = keys.mission_targets(targets.mission)
        self._payload = bus_codec.encode(targets)
        #: Another ground asked for this id with other targets (see `claim_mission`).
        self.contested = threading.Event()
        self._stack = ExitStack()

    def __enter__(self) -> Self:
        self._stack.enter_context(self._session.declare_queryable(self._key, self._on_query))
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._stack.close()

    def _on_query(self, query: zenoh.Query) -> None:
        # The concrete key, not the query's (possibly wildcard) one: otherwise Zenoh's
        # consolidation would merge this reply with another mission's.
        query.reply(self._key, self._payload, encoding=bus_codec.ENCODING)
        candidate = query.payload.to_bytes() if query.payload is not None else b""
        if candidate and candidate != self._payload and not self.contested.is_set():
            self.contested.set()
            log.warning(
                "mission %d: another ground asked to use this id with other targets",
                self.targets.mission,
            )


def publish_targets(session: zenoh.Session, targets: MissionTargets) -> None:
    put_message(session, keys.mission_targets(targets.mission), targets)
    log.info(
        "mission %d: %d targets sent to %s",
        targets.mission,
        len(targets.targets),
        ", ".join(map(str, targets.team)),
    )


def delivered_to(session: zenoh.Session, mission: int, timeout_s: float) -> set[int]:
    """The UAVs whose state says they have seen `mission` (or a later one)."""
    return {
        uav
        for uav, state in query_states(session, timeout_s).items()
        if state.mission is not None and state.mission.mission >= mission
    }


def wait_delivered(
    session: zenoh.Session, mission: int, team: Iterable[int], timeout_s: float
) -> set[int]:
    """Poll the UAVs' states until each of `team` has the mission; returns those that do."""
    members = set(team)
    deadline = time.monotonic() + timeout_s
    got: set[int] = set()
    while True:
        remaining = deadline - time.monotonic()
        got |= delivered_to(session, mission, max(0.1, min(1.0, remaining)))
        if members <= got or remaining <= 0:
            return got & members
        time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))


# ---- commands ----------------------------------------------------------------------------
def send_abort(session: zenoh.Session, mission: int, uav: int | None = None) -> MissionAbort:
    """Abort `mission` for its whole team, or for UAV `uav` alone."""
    abort = MissionAbort(mission=mission, uav=uav)
    put_message(session, keys.mission_abort(mission), abort)
    log.info("mission %d: abort sent to %s", mission, "the team" if uav is None else uav)
    return abort


def send_opm(session: zenoh.Session, uav: int, enabled: bool, status_rate_hz: float) -> OpmCommand:
    command = OpmCommand(enabled=enabled, status_rate_hz=status_rate_hz)
    put_message(session, keys.opm(uav), command)
    log.info("UAV %d: planning module %s", uav, "on" if enabled else "off")
    return command


# ---- a mission's status, after the fact --------------------------------------------------
def mission_targets_of(session: zenoh.Session, mission: int, timeout_s: float) -> MissionTargets:
    """The mission's targets and team, as the UAVs (or a ground still sending) serve them."""
    for _, targets in query_messages(
        session, keys.mission_targets(mission), MissionTargets, timeout_s
    ):
        if targets.mission == mission:
            return targets
    raise MissionError(f"mission {mission}: no UAV or ground answers for it")


def mission_status(
    session: zenoh.Session,
    mission: int,
    timeout_s: float,
    until_reached_s: float | None = None,
) -> MissionOutcome:
    """Mission `mission` as the fleet reports it now: results, the latest epoch's
    assignment, outcomes; with `until_reached_s`, first wait that long at most for every
    target to be reached. MissionError if nothing answers for the mission."""
    targets = mission_targets_of(session, mission, timeout_s)
    outcome = MissionOutcome(mission=mission, team=targets.team, targets=targets.targets)
    with MissionFollower(session, mission) as follower:
        follower.fetch(timeout_s)
        if until_reached_s is not None:
            everything = set(range(len(targets.targets)))

            def all_reached() -> bool:
                reached = {o.target for o in follower.outcomes.values() if o.phase == Phase.REACHED}
                return reached >= everything

            follower.wait_until(all_reached, until_reached_s, fetch_every_s=1.0)
        outcome.results, outcome.assignments = follower.snapshot()
        outcome.outcomes = follower.outcome_snapshot()
    states = query_states(session, timeout_s)
    outcome.lost = {uav for uav in targets.team if uav not in states}
    for uav, state in states.items():
        if uav in outcome.team:
            outcome.phases[uav] = str(state.phase)
            if state.reason:
                outcome.reasons[uav] = state.reason
    return outcome
