"""What the ground concludes about a mission: agreement, who took part, each target's state.

Agreement: every team UAV runs the same deterministic greedy on the same results, so
every report must carry the same `digest` (of the results used) and the same `pairs`.
When they do not, the largest group of identical reports is taken as the reference
(ties: the group holding the lowest Piccolo ID) and everyone else is named as having
disagreed.

Taking part: a UAV whose liveliness token went away while the ground waited is *lost*;
one that published a result with no time at all *declined* (module off, link lost, no
GPS). Neither is waited for nor counted as agreeing; `agreed` is about the UAVs that
took part, and every target gets a state: `reached` (by whom), `assigned` (to whom, at
the latest re-plan epoch), `preempted`, `failed` or `aborted` (its holder's part ended
there without reaching it: which UAV, why) or `unserved` (why). A target whose holder's
part ended short of it is not a success: the mission says so until someone reaches it.

Pure: no I/O.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import msgspec

from fleet.consensus.membership import own_asked
from fleet.mission.claims import flown_by, reached_by
from fleet.mission.messages import (
    AssignmentReport,
    NoFlyZone,
    Target,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase
from ground.proposals_heard import HeardProposal

log = logging.getLogger(__name__)

#: A holder's phases that end its claim on its target short of reaching it: the target
#: shows the phase, and the mission is no success while such a target is not reached.
ENDED_SHORT = frozenset({Phase.PREEMPTED, Phase.FAILED, Phase.ABORTED})


def _report_identity(report: AssignmentReport) -> tuple[str, tuple[tuple[int, int], ...]]:
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
    groups: dict[tuple[str, tuple[tuple[int, int], ...]], list[int]] = {}
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
    #: The mission each UAV's phase is about: a phase of a later mission says nothing
    #: about this mission's targets.
    phase_missions: dict[int, int] = field(default_factory=dict)
    #: A higher mission that reached the team while the ground followed this one
    superseded_by: int | None = None
    #: The mission's no-fly zones.
    zones: tuple[NoFlyZone, ...] = ()
    #: Targets taken off the mission in flight: never flown from then on.
    removed: frozenset[int] = frozenset()
    #: The ground's proposal (send-targets --propose), checked as the UAVs check it, and
    #: what their first plans say of it.
    proposal: HeardProposal | None = None
    #: The same of each UAV's proposal heard (send-targets --proposers), by proposer.
    uav_proposals: dict[int, HeardProposal] = field(default_factory=dict)

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

    @property
    def revision(self) -> int:
        """The latest revision of the mission any UAV planned (changed in flight)."""
        return max((report.revision for report in self.assignments.values()), default=0)

    def flown_twice(self) -> dict[int, list[int]]:
        """Target -> the UAVs that each reached it, by their own outcomes, for every target
        reached by more than one."""
        return {t: uavs for t, uavs in flown_by(self.outcomes.values()).items() if len(uavs) > 1}

    def membership(self) -> list[dict[str, Any]]:
        """Who left the mission after its commitment and who came back, at the latest
        epoch (fleet.consensus.membership): each such UAV's counts, whether it is out now,
        and why it left where its own outcome says (failed, link lost), else that it was
        counted in to a plan built without it, else its liveliness went."""
        report = self.latest()
        if report is None:
            return []
        left = dict(report.left) or {uav: 1 for uav in report.released}
        back = dict(report.back)
        rows = []
        for uav in sorted(left.keys() | back.keys()):
            outcome = self.outcomes.get(uav)
            dropped = outcome is not None and outcome.phase in (Phase.FAILED, Phase.LINK_LOST)
            if dropped and outcome:
                why = outcome.reason or str(outcome.phase)
            elif uav not in report.team:
                # Counted out once and back once by the rule that counts in a UAV the
                # epoch-0 plan was built without (fleet.consensus.membership `join`).
                why = "counted in: the first plan was built without it"
            else:
                why = "liveliness lost"
            rows.append(
                {
                    "uav": uav,
                    "left": left.get(uav, 0),
                    "back": back.get(uav, 0),
                    "out": left.get(uav, 0) > back.get(uav, 0),
                    "why": why,
                }
            )
        return rows

    def asked(self) -> dict[int, int]:
        """Re-plans in changed air each team UAV asked for, by its own latest report
        (fleet.consensus.membership `asked`, docs/lifecycle.md): an ask is believed from
        the asker's own word alone, as the UAVs believe it, not from a teammate's report
        that says another UAV asked."""
        counted: dict[int, int] = {}
        for uav, report in sorted(self.assignments.items()):
            if uav in self.team and report.uav == uav:
                counted.update(own_asked(uav, report.asked))
        return counted

    def reached_by(self) -> dict[int, int]:
        """Target index -> the UAV whose telemetry put it inside the acceptance radius, as
        that UAV's own outcome says (a teammate's word for it is a hint, not a fact)."""
        return reached_by(self.outcomes.values())

    @property
    def agreement(self) -> Agreement:
        return check_agreement(self.taking_part, self.assignments)

    @property
    def committed(self) -> bool:
        return bool(self.taking_part) and all(uav in self.assignments for uav in self.taking_part)

    def note_state(self, state: UavState) -> None:
        """A team UAV's phase (and reason) as its own state query answered it."""
        mission = state.mission.mission if state.mission is not None else None
        self.note_phase(state.uav, str(state.phase), state.reason, mission)

    def note_phase(self, uav: int, phase: str, reason: str | None, mission: int | None) -> None:
        """A team UAV's phase (and reason), reported while in `mission`."""
        self.phases[uav] = phase
        if reason:
            self.reasons[uav] = reason
        if mission is not None:
            self.phase_missions[uav] = mission

    def ended_short(self, uav: int, target: int) -> tuple[Phase, str] | None:
        """How `uav`'s part in `target` ended short of reaching it (preempted, failed,
        aborted) and why; None while it still holds the target. Its own TargetOutcome
        for the target says it first; else the phase it reports in this mission."""
        outcome = self.outcomes.get(uav)
        if outcome is not None and outcome.phase in ENDED_SHORT and outcome.target == target:
            return outcome.phase, outcome.reason or f"UAV {uav} {outcome.phase}"
        phase = self.phases.get(uav)
        if phase in ENDED_SHORT and self.phase_missions.get(uav) == self.mission:
            return Phase(phase), self.reasons.get(uav) or f"UAV {uav} {phase}"
        return None

    def latest(self) -> AssignmentReport | None:
        """A report of the latest epoch from a team UAV (the lowest ID's)."""
        latest = self.epoch
        for uav, report in sorted(self.assignments.items()):
            if uav in self.team and report.epoch == latest:
                return report
        return None

    def holders(self) -> dict[int, int]:
        """Target index -> the UAV holding it at the latest epoch: a UAV still showing an
        earlier epoch (dead, or not yet re-planned) holds nothing here. With queues, each
        queued target's holder is the UAV whose queue it is in."""
        latest = self.epoch
        report = self.latest()
        if report is not None and report.queues:
            return {t: uav for uav, queue in report.queues.items() for t in queue}
        return {
            report.target: uav
            for uav, report in sorted(self.assignments.items())
            if uav in self.team and report.epoch == latest and report.target is not None
        }

    def queues_json(self) -> dict[str, list[int]]:
        """Each UAV's queue at the latest epoch, keyed by Piccolo ID as a string."""
        latest = self.latest()
        queues = latest.queues if latest is not None else {}
        return {str(uav): list(queue) for uav, queue in queues.items()}

    def place(self, target: int) -> tuple[int, float | None] | None:
        """(1-based place in its holder's queue, predicted arrival in s) at the latest
        epoch; None for a target in no queue."""
        report = self.latest()
        if report is None:
            return None
        for uav, queue in report.queues.items():
            if target in queue:
                index = queue.index(target)
                arrivals = report.arrivals.get(uav, ())
                return index + 1, arrivals[index] if index < len(arrivals) else None
        return None

    def target_states(self) -> list[dict[str, Any]]:
        """Each target's state: reached (by whom), assigned (to whom), preempted, failed
        or aborted (its holder's part ended short of it: who, why) or unserved (why;
        every target not reached is unserved once a later mission superseded this one)."""
        taking_part = set(self.taking_part)
        holders = {t: uav for t, uav in self.holders().items() if uav in taking_part}
        idle = [uav for uav in self.taking_part if self.target_of(uav) is None]
        reached = self.reached_by()
        states: list[dict[str, Any]] = []
        latest = self.latest()
        unserved = latest.unserved if latest is not None else {}
        for index in range(len(self.targets)):
            state = self._target_state(index, reached, holders, idle, unserved)
            place = self.place(index)
            if place is not None:
                state["place"], state["eta_s"] = place
            states.append(state)
        return states

    def _target_state(
        self,
        index: int,
        reached: dict[int, int],
        holders: dict[int, int],
        idle: list[int],
        unserved: dict[int, str],
    ) -> dict[str, Any]:
        if index in reached:
            return {"index": index, "state": "reached", "uav": reached[index]}
        if index in self.removed:
            return {"index": index, "state": "removed", "uav": None}
        if self.superseded_by is not None:
            why = f"mission {self.superseded_by} superseded this one"
            return {"index": index, "state": "unserved", "uav": None, "reason": why}
        holder = holders.get(index)
        if holder is not None:
            ended = self.ended_short(holder, index)
            if ended is None:
                return {"index": index, "state": "assigned", "uav": holder}
            phase, why = ended
            return {"index": index, "state": str(phase), "uav": holder, "reason": why}
        if not self.committed:
            why = "the team did not commit"
        elif self._no_route(index, set(self.taking_part)):
            why = "no route around the no-fly zones reaches it"
        elif index in unserved:
            why = unserved[index]
        elif idle:
            why = f"not assigned although UAV {idle[0]} had no target"
        else:
            why = "more targets than UAVs taking part"
        return {"index": index, "state": "unserved", "uav": None, "reason": why}

    def _no_route(self, index: int, taking_part: set[int]) -> bool:
        """Every UAV taking part answered, with no time to target `index`, while it had
        times for others: no route of theirs keeps out of the mission's no-fly zones."""
        rows = [self.results[uav].times for uav in taking_part if uav in self.results]
        return bool(rows) and all(
            index < len(row) and row[index] is None and any(t is not None for t in row)
            for row in rows
        )

    @property
    def succeeded(self) -> bool:
        """The truth behind the exit code: the team agreed, no target was left unserved
        while a UAV taking part had none, no target's holder ended short of it (preempted,
        failed, aborted) without someone else reaching it, and no later mission
        superseded it."""
        if self.superseded_by is not None:
            return False
        if not self.committed or not self.agreement.agreed:
            return False
        return not any(
            (s["state"] == "unserved" and "had no target" in s["reason"])
            or s["state"] in ENDED_SHORT
            for s in self.target_states()
        )

    def target_of(self, uav: int) -> int | None:
        report = self.assignments.get(uav)
        return report.target if report is not None else None

    def unassigned(self) -> list[int]:
        """Targets no UAV holds: in no queue at the latest epoch (reports without queues:
        nobody's one target)."""
        latest = self.latest()
        if latest is not None and latest.queues:
            queued = {t for queue in latest.queues.values() for t in queue}
            return [i for i in range(len(self.targets)) if i not in queued]
        taken = {self.target_of(uav) for uav in self.team}
        return [i for i in range(len(self.targets)) if i not in taken]

    def proposals_json(self) -> dict[str, Any]:
        """The proposals heard, as `send-targets --json` and the page's `/api/mission` add
        them to `to_json`: `proposal` (the ground's) and `uav_proposals` (by proposer)."""
        data: dict[str, Any] = {}
        if self.proposal is not None:
            data["proposal"] = self.proposal.to_json()
        if self.uav_proposals:
            data["uav_proposals"] = {str(u): a.to_json() for u, a in self.uav_proposals.items()}
        return data

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
            "zones": [msgspec.to_builtins(z) for z in self.zones],
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
            "revision": self.revision,
            "removed": sorted(self.removed),
            "membership": self.membership(),
            "asked": {str(uav): count for uav, count in self.asked().items()},
            "flown_twice": {str(t): uavs for t, uavs in self.flown_twice().items()},
            "outcomes": {
                str(uav): msgspec.to_builtins(outcome)
                for uav, outcome in sorted(self.outcomes.items())
            },
            "superseded_by": self.superseded_by,
            "success": self.succeeded,
            "objective": str(reference.objective) if reference is not None else None,
            "queues": self.queues_json(),
        }
