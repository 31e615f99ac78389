"""Proposals heard, checked as every UAV checks them: the ground's reckoning of each.

The ground (`send-targets --wait`, the page) hears the proposals put for a mission (the
ground's and each named UAV's, each signed by its author and checked by the bus) and
holds the team's results. From them it computes what every UAV computes at its decision
(`MissionRound`: the legs in each UAV's air, the results digest) and checks each
proposal with the UAVs' own functions: the proposer's right (`right_problem`), the
plan's validity (`proposal_problem`) and its score (`finish`, then `plan_key`'s two
figures). This says what a proposal is worth, never what the team did with it: whether
a UAV adopted it is read from the digest it reported (`adoption`).

A proposal is checked only against every team UAV's result, as it was solved from
them; one the ground has not heard yet leaves it unchecked, as does a mission changed
in flight (the proposals are for the mission as first sent).

Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import StrEnum

from fleet.consensus.mission_round import MissionRound
from fleet.consensus.proposal import proposal_problem, right_problem
from fleet.consensus.queues import finish
from fleet.mission.messages import AssignmentReport, MissionTargets, PlanProposal, UavResult

__all__ = ["Check", "ProposalReview", "Score", "review_proposals"]


class Check(StrEnum):
    """What the UAVs' own checks say of a proposal, run on the ground."""

    VALID = "valid"  #: a plan of the team's results: every UAV holding them scores it
    REFUSED = "refused"  #: every UAV refuses it (no right, or not a plan of these results)
    UNCHECKED = "unchecked"  #: the ground does not hold what checking it takes


@dataclass(frozen=True)
class Score:
    """A plan's two figures (s): its last arrival (min-max's objective) and the sum of
    its arrivals (min-sum's); the objective ranks by its own first."""

    makespan_s: float
    total_s: float

    @classmethod
    def of_report(cls, report: AssignmentReport) -> Score:
        """The score of the plan a UAV reported: its arrivals are the plan's own."""
        rows = [row for row in report.arrivals.values() if row]
        last = max((row[-1] for row in rows), default=0.0)
        return cls(last, math.fsum(t for row in rows for t in row))

    def to_json(self) -> dict[str, float]:
        return {"makespan_s": round(self.makespan_s, 1), "total_s": round(self.total_s, 1)}

    def __str__(self) -> str:
        return f"last arrival {self.makespan_s:.1f} s, arrivals summed {self.total_s:.1f} s"


@dataclass(frozen=True)
class ProposalReview:
    """One proposal as the UAVs' checks see it."""

    proposer: int
    check: Check
    problem: str | None = None  #: why it is refused, or left unchecked
    score: Score | None = None  #: its score, when valid

    def summary(self) -> str:
        if self.check is Check.VALID:
            assert self.score is not None
            return f"valid: {self.score}"
        return f"{self.check}: {self.problem}"

    def to_json(self) -> dict[str, object]:
        return {
            "check": str(self.check),
            "problem": self.problem,
            "score": self.score.to_json() if self.score is not None else None,
        }


def review_proposals(
    targets: MissionTargets,
    results: Mapping[int, UavResult],
    proposals: Iterable[PlanProposal],
) -> dict[int, ProposalReview]:
    """Each of `proposals` (for `targets`' mission as first sent) checked against the
    team's `results`, by proposer."""
    proposals = sorted(proposals, key=lambda p: p.proposer)
    reviews: dict[int, ProposalReview] = {}
    missing = sorted(set(targets.team) - results.keys())
    unchecked = None
    if targets.revision:
        unchecked = f"the mission was changed in flight (revision {targets.revision} held)"
    elif missing:
        unchecked = f"no result heard yet from UAV {', '.join(map(str, missing))}"
    mission_round = None
    if unchecked is None:
        mission_round = MissionRound(targets=targets, own_id=targets.team[0], started=0.0)
        for uav in targets.team:
            mission_round.add_result(results[uav])
    for proposal in proposals:
        proposer = proposal.proposer
        why = right_problem(proposer, targets.proposers, targets.team)
        if why is not None:
            reviews[proposer] = ProposalReview(proposer, Check.REFUSED, why)
        elif mission_round is None:
            reviews[proposer] = ProposalReview(proposer, Check.UNCHECKED, unchecked)
        else:
            reviews[proposer] = _checked(mission_round, proposal)
    return reviews


def _checked(mission_round: MissionRound, proposal: PlanProposal) -> ProposalReview:
    """`proposal` checked and scored as `MissionRound.decide` does, on every team
    UAV's result."""
    used = {uav: result.times for uav, result in sorted(mission_round.results.items())}
    legs = mission_round.air_legs(used)
    objective = mission_round.targets.objective
    inputs = mission_round.results_digest(used)
    problem = proposal_problem(proposal, mission_round.mission, objective, inputs, used, legs)
    if problem is not None:
        return ProposalReview(proposal.proposer, Check.REFUSED, problem)
    plan = finish({uav: list(proposal.queues.get(uav, ())) for uav in used}, used, legs)
    return ProposalReview(
        proposal.proposer, Check.VALID, score=Score(plan.makespan(), plan.total())
    )
