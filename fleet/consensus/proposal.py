"""Proposed plans, verified: any party may propose; every UAV re-scores and chooses.

`plan_queues` is the deterministic baseline every UAV computes. A party with the CPU
and a better solver (the ground, with PyVRP: fleet/solver/pyvrp_plan.py) may publish a
`PlanProposal` for a mission: queues solved from the same digested results. Every UAV
checks it against what it holds and refuses it whole (`proposal_problem`) when

* it is for another mission, another objective, or other results (its `digest` is not
  the results digest this UAV decides on);
* a queue is a UAV's that takes no part (not among the results used);
* a target is in two places, or a target some UAV reaches is in none, or a target is
  beyond the mission;
* a UAV's queue starts with a target it has no approach time to, or flies a leg that no
  route flies (an infinite time), or holds a target it has no approach time to;

then scores every valid one with the same scorer as the baseline (`finish`: the
arrivals every UAV reports) and adopts the best of the baseline and the proposals by
(the objective's key, proposer's Piccolo ID), the baseline's ID counted as 0: a proposal
only wins when it is strictly better. Every UAV holding the same results and the same
proposals adopts the same plan; the adopted proposal's queues go into the plan's digest
(`proposal_digest`), so a UAV that did not hear it reports another digest, visibly.

Who may propose (`right_problem`): the proposers the mission names, the ground alone
when it names none (`send-targets --propose`); a UAV must also be in the mission's team
(only a team UAV holds the round it solves from). A proposal from anyone else is refused
as it arrives, whatever it holds: an unexpected proposal heard by some UAVs before their
decision and by others after it would split the team.

How long the decision waits (`awaited_proposers`): every proposer solves from every team
UAV's result, and its proposal's digest says so. A UAV that would decide without a
teammate's result (gone by its liveliness) can therefore adopt no proposal at all, and
waits for none; otherwise it waits for each named proposer entitled to propose, except
a UAV whose result says it will not (`UavResult.proposes`: not started to propose, or
without its solver). What every UAV can agree on is the results it decides from (that
word of each UAV is digested with them): two UAVs deciding on the same results wait for
the same proposers. One that sees a teammate gone decides on other
results than one that does not, with or without the wait; that split is liveliness's,
visible in the digests, as for a mission with no proposer.

Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum

from fleet.consensus.assignment import usable
from fleet.consensus.digest import sha256
from fleet.consensus.objectives import plan_digest
from fleet.consensus.queues import Legs, QueuePlan, Times, finish, leg_count, queue_arrivals
from fleet.mission.messages import MISSION_MANAGER, AssignmentReport, PlanProposal
from fleet.mission.objective import Objective

__all__ = [
    "Adoption",
    "ProposalRefused",
    "Verdict",
    "adoption",
    "awaited_proposers",
    "choose",
    "plan_key",
    "proposal_digest",
    "proposal_problem",
    "right_problem",
]

#: The proposer ID the baseline is ranked by: below every Piccolo ID.
BASELINE = 0


class ProposalRefused(StrEnum):
    """Why a UAV refused a proposal: counted with the bus messages it refused (a UAV's
    state's link drops, `bus_{reason}`)."""

    NO_RIGHT = "proposal_no_right"  #: from a proposer the mission does not entitle
    INVALID = "proposal_invalid"  #: not a plan of the round's inputs (`proposal_problem`)
    #: not for the mission the UAV holds: an older one's (superseded), or a later one's
    #: pushed out of the few kept until it arrives (onboard.early_proposals)
    NO_MISSION = "proposal_no_mission"
    #: for the mission held, entitled, but heard after this UAV's decision: it changes
    #: nothing (the window closed, or every awaited plan was in)
    LATE = "proposal_late"


def right_problem(proposer: int, named: Collection[int], team: Collection[int]) -> str | None:
    """Why `proposer` may not propose for a mission naming `named` with `team`; None if
    it may."""
    if not named:
        if proposer == MISSION_MANAGER:
            return None
        return f"{proposer} is not the ground, the only proposer of a mission naming none"
    if proposer not in named:
        return f"{proposer} is not among the mission's proposers ({_ids(named)})"
    if proposer != MISSION_MANAGER and proposer not in team:
        return f"UAV {proposer} is not in the mission's team ({_ids(team)})"
    return None


def awaited_proposers(
    named: Collection[int],
    team: Collection[int],
    gone: Collection[int],
    silent: Collection[int] = (),
) -> frozenset[int] | None:
    """The proposers whose valid proposals a decision waits for while the team UAVs
    `gone` are out of it (their results left out): an empty set, none (no proposal can
    be valid without every team UAV's result); None: any one valid proposal (a mission
    naming no proposer: the ground's). The UAVs `silent` said in their results that they
    will not propose (UavResult.proposes): never waited for either."""
    if gone:
        return frozenset()
    if not named:
        return None
    return frozenset(p for p in named if p not in silent and right_problem(p, named, team) is None)


def _ids(uavs: Iterable[int]) -> str:
    return ", ".join(map(str, sorted(uavs))) or "none"


def proposal_problem(
    proposal: PlanProposal,
    mission: int,
    objective: Objective,
    results_digest: str,
    times: Times,
    legs: Legs,
) -> str | None:
    """Why `proposal` cannot be this round's plan; None if it is a valid one."""
    if proposal.mission != mission:
        return f"for mission {proposal.mission}, not {mission}"
    if proposal.objective is not objective:
        return f"for {proposal.objective.value}, not {objective.value}"
    if proposal.digest != results_digest:
        return f"solved from other results ({proposal.digest}, not {results_digest})"
    count = leg_count(legs)
    seen: set[int] = set()
    for uav, queue in proposal.queues.items():
        if uav not in times:
            return f"a queue for UAV {uav}, which takes no part"
        row = times[uav]
        for target in queue:
            if not 0 <= target < count:
                return f"target {target} of {count}"
            if target in seen:
                return f"target {target} twice"
            seen.add(target)
            if not usable(row[target]):
                return f"UAV {uav} has no approach time to target {target}"
        if queue and not all(math.isfinite(t) for t in queue_arrivals(times, legs, uav, queue)):
            return f"UAV {uav}'s queue flies a leg no route flies"
    missing = [
        t for t in range(count) if t not in seen and any(usable(r[t]) for r in times.values())
    ]
    if missing:
        return f"target {missing[0]} in no queue, although a UAV reaches it"
    return None


def plan_key(plan: QueuePlan, objective: Objective) -> tuple[float, float]:
    """What the objective minimises: (last arrival, total) for min-max, else (total,
    last arrival)."""
    if objective is Objective.MIN_MAX:
        return plan.makespan(), plan.total()
    return plan.total(), plan.makespan()


def choose(
    baseline: QueuePlan,
    proposals: Iterable[PlanProposal],
    objective: Objective,
    times: Times,
    legs: Legs,
) -> tuple[QueuePlan, PlanProposal | None]:
    """The best of the baseline and the (valid) `proposals` by (key, proposer), and the
    proposal adopted (None: the baseline)."""
    best = (plan_key(baseline, objective), BASELINE)
    chosen: tuple[QueuePlan, PlanProposal | None] = (baseline, None)
    for proposal in sorted(proposals, key=lambda p: p.proposer):
        queues = {uav: list(proposal.queues.get(uav, ())) for uav in times}
        plan = finish(queues, times, legs)
        rank = (plan_key(plan, objective), proposal.proposer)
        if rank < best:
            best, chosen = rank, (plan, proposal)
    return chosen


_PROPOSAL_VERSION = b"fleet.queues.proposal/v1\x00"


def proposal_digest(plan_digest: str, proposal: PlanProposal) -> str:
    """The digest of a plan adopted from `proposal`: the baseline's digest (results and
    objective) hashed with the proposer and every queue, in increasing Piccolo ID."""
    h = sha256(_PROPOSAL_VERSION)
    h.update(plan_digest.encode("ascii", "replace") + b"\x00")
    h.update(proposal.proposer.to_bytes(2, "little"))
    for uav in sorted(proposal.queues):
        queue: Sequence[int] = proposal.queues[uav]
        h.update(uav.to_bytes(2, "little") + len(queue).to_bytes(2, "little"))
        h.update(b"".join(t.to_bytes(2, "little") for t in queue))
    return h.hexdigest()[:16]


class Verdict(StrEnum):
    """What the team's decisions say of a proposal."""

    WAITING = "waiting"  #: no decision heard yet
    ADOPTED = "adopted"  #: every decision heard adopted it
    BASELINE = "baseline"  #: every decision heard kept the baseline
    OTHER = "other"  #: every decision heard took another plan (a proposal, other results)
    MIXED = "mixed"  #: the decisions heard differ


@dataclass(frozen=True)
class Adoption:
    """What the UAVs' decisions say of a proposal, from the digests they reported.

    A UAV that adopted the proposal reports `adopted_digest`; one that kept the
    baseline (the proposal invalid, not better, late, or not heard) reports
    `baseline_digest`; one that decided from other results reports another."""

    adopted_digest: str
    baseline_digest: str
    adopted_by: tuple[int, ...]
    baseline_by: tuple[int, ...]
    other_by: tuple[int, ...]

    def to_json(self) -> dict[str, object]:
        return {
            "verdict": str(self.verdict),
            "adopted_digest": self.adopted_digest,
            "baseline_digest": self.baseline_digest,
            "adopted_by": list(self.adopted_by),
            "baseline_by": list(self.baseline_by),
            "other_by": list(self.other_by),
        }

    def summary(self) -> str:
        """One line: who adopted it, who did not."""

        def ids(uavs: tuple[int, ...]) -> str:
            return ", ".join(map(str, uavs)) or "none"

        verdict = self.verdict
        if verdict is Verdict.WAITING:
            return "no decision heard yet"
        if verdict is Verdict.ADOPTED:
            return f"adopted by {ids(self.adopted_by)} (digest {self.adopted_digest})"
        if verdict is Verdict.BASELINE:
            return (
                f"not adopted: {ids(self.baseline_by)} kept the baseline "
                f"(digest {self.baseline_digest})"
            )
        if verdict is Verdict.OTHER:
            return f"not adopted: {ids(self.other_by)} took another plan"
        return (
            f"adopted by {ids(self.adopted_by)}, the baseline by {ids(self.baseline_by)}, "
            f"other plans by {ids(self.other_by)}"
        )

    @property
    def verdict(self) -> Verdict:
        if not (self.adopted_by or self.baseline_by or self.other_by):
            return Verdict.WAITING
        if not (self.baseline_by or self.other_by):
            return Verdict.ADOPTED
        if not (self.adopted_by or self.other_by):
            return Verdict.BASELINE
        if not (self.adopted_by or self.baseline_by):
            return Verdict.OTHER
        return Verdict.MIXED


def adoption(proposal: PlanProposal, decisions: Iterable[AssignmentReport]) -> Adoption:
    """Which of `decisions` (the UAVs' first plans of the mission: epoch 0, revision 0)
    adopted `proposal`, kept the baseline, or decided on other results."""
    baseline = plan_digest(proposal.digest, proposal.objective)
    adopted = proposal_digest(baseline, proposal)
    by: dict[str, list[int]] = {adopted: [], baseline: []}
    other: list[int] = []
    for report in sorted(decisions, key=lambda r: r.uav):
        if report.mission != proposal.mission or report.epoch or report.revision:
            continue
        by.get(report.digest, other).append(report.uav)
    return Adoption(adopted, baseline, tuple(by[adopted]), tuple(by[baseline]), tuple(other))
