"""Following one mission on the bus: its results, assignments (every epoch), outcomes,
the team's liveliness, and any later mission that supersedes it.

Every UAV publishes its UavResult and, once the consensus has run, its AssignmentReport
(again at each re-plan epoch) and a TargetOutcome when it reaches its target or drops
out; all are collected by subscription and, every second and at the end, by a query of
what the UAVs serve, so a sample lost in transit is still counted.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from fleet.mission import claims
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    PlanProposal,
    TargetOutcome,
    UavResult,
)
from fleet.transport.bus import Bus, BusSample, decode_sample
from ground.declarations import Declarations, Enter

log = logging.getLogger(__name__)


Listener = Callable[[str, UavResult | AssignmentReport | TargetOutcome], None]


class MissionFollower(Declarations):
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
        bus: Bus,
        space: KeySpace,
        mission: int,
        listener: Listener | None = None,
        team: Iterable[int] = (),
        on_revision: Callable[[MissionTargets], object] | None = None,
        on_proposal: Callable[[PlanProposal], object] | None = None,
    ) -> None:
        self._bus = bus
        self._space = space
        self.mission = mission
        self._listener = listener
        self._team = frozenset(team)
        self._on_revision = on_revision
        self._on_proposal = on_proposal
        self._changed = threading.Condition()
        self.results: dict[int, UavResult] = {}
        self.assignments: dict[int, AssignmentReport] = {}
        self.outcomes: dict[int, TargetOutcome] = {}
        #: The proposals for this mission heard, by proposer: the ground's and each UAV's
        #: (each on its own key, signed by it: the bus checks both). Put, never served:
        #: only those put while this follower listens.
        self.proposals: dict[int, PlanProposal] = {}
        self.lost: set[int] = set()  #: UAVs whose liveliness token went away
        self.superseded_by: int | None = None  #: the highest later mission of the team
        super().__init__()

    def _declare(self, enter: Enter) -> None:
        bus, space, mission = self._bus, self._space, self.mission
        enter(bus.subscribe(space.mission_results(mission), self._on_result_sample))
        enter(bus.subscribe(space.mission_assignments(mission), self._on_assignment_sample))
        enter(bus.subscribe(space.mission_outcomes(mission), self._on_outcome_sample))
        enter(bus.subscribe(space.mission_proposal(mission), self._on_proposal_sample))
        enter(bus.subscribe(space.mission_proposals(mission), self._on_proposal_sample))
        # The tokens present now are reported too: each is a UAV not lost, a no-op.
        enter(bus.subscribe_presence(space.all_alive, self._on_alive))
        enter(bus.subscribe(space.all_mission_targets, self._on_targets_sample))

    def _on_alive(self, key: str, alive: bool) -> None:
        try:
            uav = uav_id_of(key)
        except (ValueError, IndexError):
            return
        with self._changed:
            if alive:
                self.lost.discard(uav)
            else:
                self.lost.add(uav)
            self._changed.notify_all()

    def _on_targets_sample(self, sample: BusSample) -> None:
        targets = decode_sample(sample, MissionTargets)
        if targets is not None:
            self.note_targets(targets)

    def note_targets(self, targets: MissionTargets) -> None:
        """A mission sent to some team: a later one for any of ours supersedes this one;
        this one again (a revision, changed in flight) goes to `on_revision`."""
        if targets.mission == self.mission and self._on_revision is not None:
            self._on_revision(targets)
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

    def _on_result_sample(self, sample: BusSample) -> None:
        result = decode_sample(sample, UavResult)
        if result is not None:
            self.add_result(result)

    def _on_assignment_sample(self, sample: BusSample) -> None:
        report = decode_sample(sample, AssignmentReport)
        if report is not None:
            self.add_assignment(report)

    def _on_proposal_sample(self, sample: BusSample) -> None:
        proposal = decode_sample(sample, PlanProposal)
        if proposal is not None:
            self.add_proposal(proposal)

    def add_proposal(self, proposal: PlanProposal) -> None:
        """Keep a proposal for this mission (the latest of each proposer, as a UAV does
        until its decision); `on_proposal` hears it."""
        if proposal.mission != self.mission:
            return
        with self._changed:
            if self.proposals.get(proposal.proposer) == proposal:
                return
            self.proposals[proposal.proposer] = proposal
            self._changed.notify_all()
        if self._on_proposal is not None:
            self._on_proposal(proposal)

    def _on_outcome_sample(self, sample: BusSample) -> None:
        outcome = decode_sample(sample, TargetOutcome)
        if outcome is not None:
            self.add_outcome(outcome)

    def add_outcome(self, outcome: TargetOutcome) -> None:
        """A UAV's own outcome (its signature checked by the bus): a copy that claims less
        than the one held is an older one, relayed by a teammate that missed the latest."""
        with self._changed:
            if not claims.newer(self.outcomes.get(outcome.uav), outcome):
                return
        self._add("outcome", self.outcomes, outcome)

    def add_result(self, result: UavResult) -> None:
        if result.basis is not None:
            return  # a standing for a re-plan (fleet.consensus.resolve), not the result
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
        for _, result in self._bus.query_messages(
            self._space.mission_results(self.mission), UavResult, timeout_s
        ):
            self.add_result(result)
        for _, report in self._bus.query_messages(
            self._space.mission_assignments(self.mission), AssignmentReport, timeout_s
        ):
            self.add_assignment(report)
        for _, outcome in self._bus.query_messages(
            self._space.mission_outcomes(self.mission), TargetOutcome, timeout_s
        ):
            self.add_outcome(outcome)
        # A teammate's word that a UAV reached a target is a hint: ask, by name, for
        # that UAV's own outcome, which its teammates relay with its signature (it may be
        # gone).
        for uav in sorted(claims.unconfirmed(self.outcome_snapshot().values())):
            for _, outcome in self._bus.query_messages(
                self._space.mission_outcome(self.mission, uav), TargetOutcome, timeout_s
            ):
                self.add_outcome(outcome)
        # The UAVs serve their current mission's targets: a later one supersedes ours.
        for _, targets in self._bus.query_messages(
            self._space.all_mission_targets, MissionTargets, timeout_s
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

    def proposal_snapshot(self) -> dict[int, PlanProposal]:
        with self._changed:
            return dict(self.proposals)

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

    def wait_superseded(self, timeout_s: float, fetch_every_s: float) -> int | None:
        """Wait up to `timeout_s` for a later mission of the team; its id, or None.

        Queries every `fetch_every_s` as well: a later mission put before this follower
        subscribed is still what the team's UAVs (and its ground) serve.
        """
        self.wait_until(lambda: False, timeout_s, fetch_every_s)
        return self.superseded_by
